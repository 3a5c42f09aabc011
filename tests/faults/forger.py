"""A hostile ROS 2 process for tests/faults/test_faults_hostile_ros.py: forges and replays messages on a
live run's domain, a fixed corpus with known counts. Usage: python forger.py SAT OTHER_SAT OUT_JSON.

It joins the run's domain (ROS_DOMAIN_ID from its environment), waits until each of its
publishers has matched the run's subscriptions, then publishes once:

* 20 Observation envelopes on /SAT/observations that look like the satellite's own (the attack
  that turned value 7219 into 107217), and 5 more with a MAC under another run's key;
* on /sim/step: a step message (k 5) and a stop message (each once ended every host or changed
  the observations), plus 2 junk texts;
* on /sim/ack: a hello and an error ack from SAT (they crashed the clock and failed the run),
  plus 3 junk texts;
* on /SAT/dtn/in: 10 envelopes posing as the DTN router, carrying bundles for SAT signed with
  the BPSec key the agent used to hold in its source (they crashed the satellite), and 5 junk texts;
* a genuine envelope of the run captured on /SAT/schedule: republished 3 times as it is (a replay:
  a duplicate every receiver drops), once with one byte changed in it, once on /OTHER_SAT/schedule.

Writes OUT_JSON: per topic, how many messages of each expected rejection reason it published and
how many subscriptions each publisher had matched when it did (every one of them should count a
rejection), plus the replays.
"""

from __future__ import annotations

import json
import os
import sys
import time

import rclpy
from std_msgs.msg import String

OLD_SOURCE_KEY = b"constellation-shared-key-0000000"
WAIT_S = 240.0


def _bundle(target: str, src: str, i: int) -> bytes:
    from orbit_clock.contact_plan import node_number
    from sat_node.dtn.bpsec import add_bib
    from sat_node.dtn.bpv7 import Bundle, encode_bundle, ipn
    from sat_node.dtn.routing_blocks import set_routing
    from sat_node.inference import Inference, encode_inference

    b = Bundle(dest=ipn(node_number(target), 1), src=ipn(node_number(src), 1), creation_ms=946_728_000_000 + i,
               seq=50_000 + i, lifetime_ms=900_000,
               payload=encode_inference(Inference(src, 7, 1_000_000_000, 99.0, 0)))
    to = node_number(target)
    set_routing(b, [(to, 1, 900_000)], {to: (to,)})
    b.hop_count = (32, 0)
    add_bib(b, OLD_SOURCE_KEY, ipn(node_number(src), 0))
    return encode_bundle(b)


def main() -> int:
    sat, other, out_path = sys.argv[1], sys.argv[2], sys.argv[3]
    from bringup.engine.lockstep import AckMsg, StepMsg, encode_msg
    from bringup.engine.ros.host import QOS_DATA, QOS_SYNC_PUB
    from msgs_json import codec
    from msgs_json import schemas as S
    from msgs_json import topics as T
    from msgs_json.auth import RunAuth
    from msgs_json.envelope import Envelope
    from msgs_json.wire import encode_envelope

    rclpy.init()
    node = rclpy.create_node("forger")
    captured: list[str] = []
    sched = T.schedule_topic(sat)
    cap = node.create_subscription(String, sched, lambda m: captured.append(m.data), QOS_DATA)
    obs_t, in_t, other_sched = T.observations_topic(sat), T.dtn_in_topic(sat), T.schedule_topic(other)
    pubs = {t: node.create_publisher(String, t, QOS_DATA) for t in (obs_t, in_t, sched, other_sched)}
    pubs["/sim/step"] = node.create_publisher(String, "/sim/step", QOS_SYNC_PUB)
    pubs["/sim/ack"] = node.create_publisher(String, "/sim/ack", QOS_SYNC_PUB)
    # who must have matched before we publish: the recorder on data topics, every host on /sim/step
    need = {obs_t: 1, in_t: 2, sched: 2, other_sched: 1, "/sim/step": int(os.environ["FORGER_HOSTS"]), "/sim/ack": 1}
    deadline = time.monotonic() + WAIT_S
    while any(pubs[t].get_subscription_count() < n for t, n in need.items()):
        if time.monotonic() > deadline:
            got = {t: pubs[t].get_subscription_count() for t in need}
            print(f"forger: publishers not matched after {WAIT_S:g} s: {got}, need {need}", file=sys.stderr)
            os._exit(3)
        rclpy.spin_once(node, timeout_sec=0.05)
    sent: dict[str, dict] = {}

    def pub(topic: str, text: str, reason: str | None) -> None:
        pubs[topic].publish(String(data=text))
        rec = sent.setdefault(topic, {"reasons": {}, "matched": pubs[topic].get_subscription_count(), "replays": 0})
        if reason is None:
            rec["replays"] += 1
        else:
            rec["reasons"][reason] = rec["reasons"].get(reason, 0) + 1

    other_run = RunAuth(b"another run's key, 32 bytes long")
    for i in range(25):
        o = S.Observation(sat=sat, gp=(37 * i) % 500, t_ns=60_000_000_000 + i, recorded_value=5000.0,
                          assumed_value=5000.0)
        env = Envelope(o.t_ns, sat, 100_000 + i, obs_t, codec.encode(o))
        if i < 20:
            pub(obs_t, encode_envelope(env), "unauthenticated")
        else:
            pub(obs_t, encode_envelope(env, other_run.mac(env)), "bad_mac")
    pub("/sim/step", encode_msg(StepMsg(k=5, t_ns=50_000_000_000)), "unauthenticated")
    pub("/sim/step", encode_msg(StepMsg(k=0, t_ns=0, stop=True, reason="forged")), "unauthenticated")
    for junk in ("not a step", '{"k": 1}'):
        pub("/sim/step", junk, "unauthenticated")
    pub("/sim/ack", encode_msg(AckMsg(participant=sat, k=0, t_ns=0, hello=True)), "unauthenticated")
    pub("/sim/ack", encode_msg(AckMsg(participant=sat, k=3, t_ns=0, error="forged failure")), "unauthenticated")
    for junk in ("", "\x00\x01junk", '{"participant": "clock"}'):
        pub("/sim/ack", junk, "unauthenticated")
    for i in range(10):
        env = Envelope(1_000_000_000 + i, "dtn_router", i, in_t, _bundle(sat, other, i))
        pub(in_t, encode_envelope(env), "unauthenticated")
    for junk in ("{", "[]", '{"t_ns": 1}', "\ud7ff" * 3, "x" * 500):
        pub(in_t, junk, "malformed")

    # a genuine envelope of the run: replayed, tampered, moved to another topic
    while not captured:
        if time.monotonic() > deadline:
            print("forger: no schedule of the run captured", file=sys.stderr)
            os._exit(4)
        rclpy.spin_once(node, timeout_sec=0.05)
    node.destroy_subscription(cap)
    while pubs[sched].get_subscription_count() >= need[sched]:  # our own subscription is gone
        rclpy.spin_once(node, timeout_sec=0.05)
    genuine = captured[0]
    for _ in range(3):
        pub(sched, genuine, None)
    i = genuine.index('"t_ns":') + len('"t_ns":')
    tampered = genuine[:i] + ("1" if genuine[i] != "1" else "2") + genuine[i + 1:]
    pub(sched, tampered, "bad_mac")
    pub(other_sched, genuine, "bad_mac")
    for p in pubs.values():
        p.wait_for_all_acked(rclpy.duration.Duration(seconds=10.0))
    with open(out_path, "w") as fh:
        json.dump(sent, fh)
    sys.stdout.flush()
    os._exit(0)  # no DDS teardown (bringup/engine/ros/host.py exit_now says why)


if __name__ == "__main__":
    sys.exit(main())
