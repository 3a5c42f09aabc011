"""`constellation replay`: a small bag republished onto a live graph reaches a subscriber intact,
offered with the QoS the bag recorded.

The subscriber lives in an isolated rclpy Context on a leased ROS_DOMAIN_ID (loopback discovery);
the replayer is the real CLI in a subprocess. We wait on a condition with a deadline, never sleep.
Oracle for the QoS: the bag's own metadata.yaml (offered_qos_profiles, read with PyYAML, not with
our reader) against what the graph reports for the replayer's publishers (get_publishers_info_by_topic:
reliability and durability; DDS discovery does not carry the history, which ``ros2 topic info -v``
shows as UNKNOWN too).
"""

from __future__ import annotations

import subprocess
import sys
import threading
import time

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

    def done(topics=tuple(expected)) -> bool:
        return all(len(got[t]) >= len(expected[t]) for t in topics)

    reliable = tuple(t for t in expected if t != "/clock")

    with lease_domain_id() as lease:
        ctx = Context()
        rclpy.init(context=ctx, domain_id=lease.domain_id)
        node = rclpy.create_node("replay_listener", context=ctx)
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(node)
        qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
        clock_qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.BEST_EFFORT)
        for topic, mt in types.items():
            pkg, kind, name = mt.split("/")
            cls = getattr(__import__(f"{pkg}.{kind}", fromlist=[name]), name)

            def cb(raw, topic=topic):
                with cond:
                    got[topic].append(bytes(raw))
                    cond.notify_all()

            # /clock is offered best effort (what the bag recorded): a reliable reader would not match it
            node.create_subscription(cls, topic, cb, clock_qos if topic == "/clock" else qos, raw=True)
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
                assert cond.wait_for(lambda: done(reliable), timeout=20.0), {
                    t: (len(got[t]), len(expected[t])) for t in expected}
                cond.wait_for(done, timeout=5.0)  # /clock is best effort: what arrives is checked below
        finally:
            ex.shutdown()
            node.destroy_node()
            rclpy.try_shutdown(context=ctx)
            spin.join(timeout=10)
    # byte-identical, in order, per topic; DDS may pad a payload to a 4-byte multiple. /clock goes out
    # best effort, as recorded (rclpy's TimeSource subscribes so): DDS may drop a sample on a loaded
    # machine, so what arrives must be the expected clocks in order, at least one of them
    def same(g: bytes, e: bytes) -> bool:
        return g[: len(e)] == e and set(g[len(e):]) <= {0} and len(g) - len(e) < 4

    for topic, exp in expected.items():
        if topic == "/clock":
            it = iter(exp)
            assert got[topic] and all(any(same(g, e) for e in it) for g in got[topic]), topic
            continue
        assert len(got[topic]) == len(exp), topic
        for g, e in zip(got[topic], exp, strict=True):
            assert same(g, e), topic


def test_replay_missing_bag_is_one_line_error(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "bringup.cli", "replay", str(tmp_path / "nope")],
                          capture_output=True, text=True, timeout=60, check=False)
    assert proc.returncode == 2 and "not found" in proc.stderr and proc.stderr.strip().count("\n") == 0


def test_replay_offers_the_recorded_qos(tmp_path):
    import rclpy
    import yaml
    from rclpy.context import Context
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    from bringup.engine.ros.launcher import child_env, lease_domain_id
    from bringup.recording.bag import BagWriter
    from bringup.recording.viz_frames import TF_TYPE, station_tf, tf_cdr
    from msgs_json.envelope import Envelope

    class St:
        name, lat_deg, lon_deg, alt_m = "svalbard", 78.2298, 15.4078, 500.0

    bag = tmp_path / "bag"
    with BagWriter(bag) as w:
        for k in range(4):
            w.write_clock(k * S)
            w.write_envelope(Envelope(k * S, "sat_11", k, "/sat_11/observations", "{}"))
        w.write_raw("/tf_static", TF_TYPE, tf_cdr(station_tf([St], 0)), 0)
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    recorded = {}
    for t in meta["topics_with_message_count"]:
        tm = t["topic_metadata"]
        q = tm["offered_qos_profiles"]
        recorded[tm["name"]] = (yaml.safe_load(q) if isinstance(q, str) else q)[0]
    want_rel = {"reliable": ReliabilityPolicy.RELIABLE, "best_effort": ReliabilityPolicy.BEST_EFFORT}
    want_dur = {"transient_local": DurabilityPolicy.TRANSIENT_LOCAL, "volatile": DurabilityPolicy.VOLATILE}
    assert {n: (q["reliability"], q["durability"], q["history"]) for n, q in recorded.items()} == {
        "/clock": ("best_effort", "volatile", "keep_last"), "/sat_11/observations": ("reliable", "volatile", "keep_all"),
        "/tf_static": ("reliable", "transient_local", "keep_last")}

    with lease_domain_id() as lease:
        ctx = Context()
        rclpy.init(context=ctx, domain_id=lease.domain_id)
        node = rclpy.create_node("qos_listener", context=ctx)
        proc = None
        try:
            from rosgraph_msgs.msg import Clock
            from std_msgs.msg import String
            from tf2_msgs.msg import TFMessage

            for topic, cls in (("/clock", Clock), ("/sat_11/observations", String), ("/tf_static", TFMessage)):
                node.create_subscription(cls, topic, lambda m: None,
                                         QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT))
            # a slow replay with a long wait for subscribers: the publishers stay on the graph meanwhile
            proc = subprocess.Popen(
                [sys.executable, "-m", "bringup.cli", "replay", str(bag), "--rate", "0.5",
                 "--domain-id", str(lease.domain_id), "--wait-subscribers", "1", "--wait-timeout", "60"],
                env=child_env(lease.domain_id), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            seen = {}
            deadline = time.monotonic() + 60
            while len(seen) < 3 and time.monotonic() < deadline and proc.poll() is None:
                for topic in recorded:
                    infos = [i for i in node.get_publishers_info_by_topic(topic) if i.node_name == "bag_replay"]
                    if infos:
                        seen[topic] = infos[0].qos_profile
                time.sleep(0.05)
            assert set(seen) == set(recorded), (seen, proc.poll())
            for topic, q in recorded.items():
                assert seen[topic].reliability == want_rel[q["reliability"]], topic
                assert seen[topic].durability == want_dur[q["durability"]], topic
            assert proc.wait(timeout=60) == 0, proc.stderr.read()[-2000:]
        finally:
            if proc is not None and proc.poll() is None:
                proc.kill()
            node.destroy_node()
            rclpy.try_shutdown(context=ctx)


def test_replay_qos_agreeing_offers_kept_disagreeing_fall_back(capsys):
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, ReliabilityPolicy

    from bringup.cli.replay import replay_qos
    from bringup.recording.bag import make_qos

    tl = make_qos(depth=1, transient_local=True)
    q = replay_qos("/tf_static", [tl, tl])
    assert (q.reliability, q.durability, q.history, q.depth) == (
        ReliabilityPolicy.RELIABLE, DurabilityPolicy.TRANSIENT_LOCAL, HistoryPolicy.KEEP_LAST, 1)
    assert capsys.readouterr().err == ""
    # two publishers recorded with different durability: rosbag2's default offer, and a warning naming the topic
    q = replay_qos("/x", [tl, make_qos(depth=5)])
    assert (q.reliability, q.durability, q.history, q.depth) == (
        ReliabilityPolicy.RELIABLE, DurabilityPolicy.VOLATILE, HistoryPolicy.KEEP_LAST, 10)
    assert "/x" in capsys.readouterr().err
    # nothing recorded (an older bag): the default, silently
    assert replay_qos("/y", []).depth == 10 and capsys.readouterr().err == ""
