"""A rogue ROS 2 node for tests/faults/test_faults_hostile_ros.py: publishes seeded junk on every
input topic of a live run until killed. Usage: python rogue_publisher.py SATS_CSV COUNT_FILE SEED.

Per message (std_msgs/String, RELIABLE, the run's data QoS): random text that is no envelope, a
mutated valid envelope, or a valid envelope from source ``rogue`` carrying random bytes or a
wrong-key BPSec bundle; on /sat_XX/dtn/in, /sat_XX/dtn/status, /sat_XX/dtn/out, /sim/step, /sim/ack.
Writes how many it sent (per topic kind) to COUNT_FILE every 50 messages and at exit.
"""

from __future__ import annotations

import json
import random
import signal
import sys
import time

import rclpy
from std_msgs.msg import String


def main() -> int:
    sats, count_file, seed = sys.argv[1].split(","), sys.argv[2], int(sys.argv[3])
    sys.path.insert(0, __file__.rsplit("/", 1)[0])
    from test_faults_hostile import _forged_bundle

    from bringup.engine.ros.host import QOS_DATA, QOS_SYNC_PUB
    from msgs_json import topics as T
    from msgs_json.envelope import Envelope
    from msgs_json.wire import encode_envelope

    rng = random.Random(seed)
    rclpy.init()
    node = rclpy.create_node("rogue")
    topics = [T.dtn_in_topic(s) for s in sats] + [T.dtn_status_topic(s) for s in sats] + \
             [T.dtn_out_topic(s) for s in sats]
    pubs = {t: node.create_publisher(String, t, QOS_DATA) for t in topics}
    pubs["/sim/step"] = node.create_publisher(String, "/sim/step", QOS_SYNC_PUB)
    pubs["/sim/ack"] = node.create_publisher(String, "/sim/ack", QOS_SYNC_PUB)
    sent = {"junk": 0, "mutated_envelope": 0, "rogue_envelope": 0, "forged_bundle": 0, "sync_junk": 0}
    stop = {"now": False}
    signal.signal(signal.SIGTERM, lambda *_: stop.update(now=True))
    seq = 0

    def dump():
        with open(count_file, "w") as fh:
            json.dump(sent, fh)

    try:
        while not stop["now"]:
            topic = rng.choice(list(pubs))
            kind = rng.random()
            if topic.startswith("/sim/"):
                text, k = "".join(chr(rng.randrange(32, 127)) for _ in range(rng.randint(0, 60))), "sync_junk"
            elif kind < 0.3:
                text, k = rng.randbytes(rng.randint(0, 80)).decode("latin-1"), "junk"
            else:
                sat = topic.split("/")[1]
                if topic.endswith("/dtn/status"):
                    body: str | bytes = '{"v":1,"sat":"%s","t_ns":%d}' % (sat, rng.randrange(10**12))
                elif kind < 0.65:
                    body = rng.randbytes(rng.randint(1, 120))
                else:
                    src = rng.choice([s for s in sats if s != sat])
                    body = _forged_bundle(sat, src, rng.randrange(100), rng.randrange(10**12), seq)
                env = Envelope(rng.randrange(10**12), "rogue", seq, topic, body)
                seq += 1
                text = encode_envelope(env)
                if kind < 0.45:
                    b = bytearray(text.encode())
                    b[rng.randrange(len(b))] = rng.randrange(32, 127)
                    text, k = b.decode("latin-1"), "mutated_envelope"
                else:
                    k = "forged_bundle" if isinstance(body, bytes) and kind >= 0.65 else "rogue_envelope"
            pubs[topic].publish(String(data=text))
            sent[k] += 1
            if sum(sent.values()) % 50 == 0:
                dump()
            time.sleep(0.005)
    finally:
        dump()
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
