"""`constellation replay`: a small bag republished onto a live graph reaches a subscriber intact.

The subscriber lives in an isolated rclpy Context on a leased ROS_DOMAIN_ID (loopback discovery);
the replayer is the real CLI in a subprocess. We wait on a condition with a deadline, never sleep.
"""

from __future__ import annotations

import subprocess
import sys
import threading

import pytest

pytestmark = [pytest.mark.ros, pytest.mark.timeout(120)]

S = 1_000_000_000


def _make_bag(path, with_clock=True):
    from bringup.recording.bag import BagWriter
    from bringup.recording.viz_messages import write_viz
    from msgs_json.envelope import Envelope

    with BagWriter(path) as bag:
        for k in range(6):
            t = k * S
            if with_clock:
                bag.write_clock(t)
            bag.write_envelope(Envelope(t, "sat_11", k, "/sat_11/observations", f'{{"k": {k}}}'))
            bag.write_envelope(Envelope(t, "sat_11", k, "/sat_11/dtn/out", bytes([k, 0, 255])))
            if k % 2 == 0:
                write_viz(bag, ["sat_11"], [[7088.0, 0.0, 0.0]], t)
    return path


@pytest.mark.parametrize("with_clock", [True, False], ids=["recorded_clock", "synthesised_clock"])
def test_replay_delivers_every_message_and_clock(tmp_path, with_clock):
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    from bringup.engine.ros.launcher import child_env, lease_domain_id
    from bringup.recording.bag import CLOCK_TYPE, BagReader, clock_cdr

    bag = _make_bag(tmp_path / "bag", with_clock)
    with BagReader(bag) as r:
        expected: dict[str, list[bytes]] = {}
        for m in r.messages():
            expected.setdefault(m.topic, []).append(m.cdr)
        types = {t.topic: t.msgtype for t in r.topics()}
    n_recorded = sum(len(v) for v in expected.values())
    if not with_clock:  # the replayer publishes one /clock per distinct log time
        expected["/clock"] = [clock_cdr(k * S) for k in range(6)]
        types["/clock"] = CLOCK_TYPE
    assert set(expected) == {"/clock", "/sat_11/observations", "/sat_11/dtn/out", "/sat_11/fix", "/viz/constellation"}

    got: dict[str, list[bytes]] = {t: [] for t in expected}
    cond = threading.Condition()

    def done() -> bool:
        return all(len(got[t]) >= len(expected[t]) for t in expected)

    with lease_domain_id() as lease:
        ctx = Context()
        rclpy.init(context=ctx, domain_id=lease.domain_id)
        node = rclpy.create_node("replay_listener", context=ctx)
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(node)
        qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
        for topic, mt in types.items():
            pkg, kind, name = mt.split("/")
            cls = getattr(__import__(f"{pkg}.{kind}", fromlist=[name]), name)

            def cb(raw, topic=topic):
                with cond:
                    got[topic].append(bytes(raw))
                    cond.notify_all()

            node.create_subscription(cls, topic, cb, qos, raw=True)
        spin = threading.Thread(target=ex.spin, daemon=True)
        spin.start()
        try:
            proc = subprocess.run(
                [sys.executable, "-m", "bringup.cli", "replay", str(bag), "--rate", "20",
                 "--domain-id", str(lease.domain_id), "--wait-subscribers", "1", "--wait-timeout", "30"],
                env=child_env(lease.domain_id), capture_output=True, text=True, timeout=90, check=False,
            )
            assert proc.returncode == 0, proc.stderr[-2000:]
            n_topics = 5 if with_clock else 4
            assert f"replayed {n_recorded} messages on {n_topics} topics" in proc.stdout
            with cond:
                assert cond.wait_for(done, timeout=20.0), {t: (len(got[t]), len(expected[t])) for t in expected}
        finally:
            ex.shutdown()
            node.destroy_node()
            rclpy.try_shutdown(context=ctx)
            spin.join(timeout=10)
    # byte-identical, in order, per topic; DDS may pad a payload to a 4-byte multiple
    for topic, exp in expected.items():
        assert len(got[topic]) == len(exp), topic
        for g, e in zip(got[topic], exp, strict=True):
            assert g[: len(e)] == e and set(g[len(e):]) <= {0} and len(g) - len(e) < 4, topic


def test_replay_missing_bag_is_one_line_error(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "bringup.cli", "replay", str(tmp_path / "nope")],
                          capture_output=True, text=True, timeout=60, check=False)
    assert proc.returncode == 2 and "not found" in proc.stderr and proc.stderr.strip().count("\n") == 0
