"""A live 6-satellite ROS run seen from outside, as RViz or Foxglove would see it.

``constellation run --engine ros`` on a leased ROS_DOMAIN_ID, with one satellite's namespace
remapped (``--ros-args -r sat_12:__ns:=/moved/sat_12``) while it shares an OS process with sat_11 and
sat_21 (``--sats-per-process 3``: the remap names one node, not the process); an rclpy node of the test on the same domain:

* receives NavSatFix fixes (``/sat_11/fix`` and the moved ``/moved/sat_12/fix``) whose bytes equal
  the bag's fix of the same instant (same stamp; DDS only pads them), the constellation MarkerArray, ``/tf`` (earth ->
  sat_11, ...) and ``/diagnostics`` with a status per satellite (its DTN counters);
* reads a satellite's run settings through its parameter services (ListParameters, GetParameters)
  and finds them as given (mode, replan period, UTC epoch);
* sees the moved satellite's topics under ``/moved/sat_12`` and none of its topics at ``/sat_12``,
  also in the bag.

Oracles: the bag of the same run (recorded by the clock, not by the hosts that publish live), the
scenario file's values, and the remap rule's expected names.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time

import pytest

from tests.conftest import REPO

pytestmark = [pytest.mark.ros, pytest.mark.system, pytest.mark.timeout(900)]

EPOCH_S = 946727968  # 2000-01-01T11:59:28Z, the paper scenario's epoch


def test_live_topics_parameters_and_a_remapped_satellite(tmp_path):
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rcl_interfaces.srv import GetParameters, ListParameters
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import QoSProfile
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import NavSatFix
    from tf2_msgs.msg import TFMessage
    from visualization_msgs.msg import MarkerArray

    from bringup.engine.ros.launcher import lease_domain_id
    from bringup.recording.bag import BagReader

    out = tmp_path / "run"
    with lease_domain_id() as lease:
        env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", PYTHONUNBUFFERED="1")
        cmd = [sys.executable, "-m", "bringup.cli", "run", "--scenario", "paper", "--engine", "ros", "--sats", "6",
               "--hours", "0.5", "--viz-period-s", "60", "--real-time-factor", "30", "--no-plots", "--no-progress",
               "--out", str(out), "--domain-id", str(lease.domain_id), "--sats-per-process", "3",
               "--ros-args", "-r", "sat_12:__ns:=/moved/sat_12"]
        proc = subprocess.Popen(cmd, cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        ctx = Context()
        rclpy.init(context=ctx, domain_id=lease.domain_id)
        got: dict[str, list] = {"fix11": [], "fix12": [], "markers": [], "tf": [], "diag": []}
        params: dict[str, object] = {}
        graph: set[str] = set()
        old_pubs: set[str] = set()
        try:
            node = rclpy.create_node("live_observer", context=ctx)
            q = QoSProfile(depth=100)
            node.create_subscription(NavSatFix, "/sat_11/fix", lambda m: got["fix11"].append(m), q, raw=True)
            node.create_subscription(NavSatFix, "/moved/sat_12/fix", lambda m: got["fix12"].append(m), q, raw=True)
            node.create_subscription(MarkerArray, "/viz/constellation", lambda m: got["markers"].append(m), q)
            node.create_subscription(TFMessage, "/tf", lambda m: got["tf"].append(m), q)
            node.create_subscription(DiagnosticArray, "/diagnostics", lambda m: got["diag"].append(m), q)
            ex = SingleThreadedExecutor(context=ctx)
            ex.add_node(node)
            pending = []
            deadline = time.monotonic() + 600
            while proc.poll() is None and time.monotonic() < deadline:
                ex.spin_once(timeout_sec=0.1)
                now = {t for t, _ in node.get_topic_names_and_types()}
                graph |= now
                # who publishes at the old place (the graph also lists topics that only have subscribers,
                # e.g. the router's subscription to /sat_12/dtn/out)
                old_pubs |= {t for t in now if t.startswith("/sat_12/") and node.count_publishers(t) > 0}
                if not pending and got["fix11"]:  # the satellites' nodes are up: ask for their parameters
                    for fqn in ("/sat_11/sat_11", "/moved/sat_12/sat_12"):
                        lc = node.create_client(ListParameters, f"{fqn}/list_parameters")
                        gc = node.create_client(GetParameters, f"{fqn}/get_parameters")
                        pending.append((fqn, lc, gc, None, None))
                for i, (fqn, lc, gc, lf, gf) in enumerate(pending):
                    if lf is None and lc.service_is_ready() and gc.service_is_ready():
                        lf = lc.call_async(ListParameters.Request())
                        gf = gc.call_async(GetParameters.Request(
                            names=["run.mode", "scheduler.replan_period_s", "run.epoch_utc", "run.role", "run.process"]))
                        pending[i] = (fqn, lc, gc, lf, gf)
                    if lf is not None and lf.done() and gf.done() and fqn not in params:
                        params[fqn] = (lf.result().result.names, gf.result().values)
            assert proc.wait(timeout=120) == 0, proc.stdout.read()
        finally:
            if proc.poll() is None:
                proc.kill()
            rclpy.try_shutdown(context=ctx)

    # parameters, through the parameter services of a satellite and of the moved one
    assert set(params) == {"/sat_11/sat_11", "/moved/sat_12/sat_12"}, params
    names, values = params["/sat_11/sat_11"]
    assert {"run.mode", "run.seed", "scheduler.replan_period_s", "isl.rate_bps", "viz.period_s"} <= set(names)
    assert values[0].string_value == "distributed"
    assert values[1].double_value == 600.0
    assert values[2].string_value == "2000-01-01T11:59:28Z"
    assert values[3].string_value == "sat_11"
    assert params["/moved/sat_12/sat_12"][1][3].string_value == "sat_12"
    # sat_11 and sat_12 share one OS process (--sats-per-process 3): the node-qualified remap moved only sat_12
    assert values[4].string_value == params["/moved/sat_12/sat_12"][1][4].string_value == "sats_1"

    # live visualisation: fixes (both satellites), markers in metres, the TF tree, diagnostics
    assert len(got["fix11"]) >= 5 and got["fix12"], {k: len(v) for k, v in got.items()}
    ma = got["markers"][-1]
    sats = next(m for m in ma.markers if m.ns == "satellites")
    assert len(sats.points) == 6 and 6.9e6 < (sats.points[0].x ** 2 + sats.points[0].y ** 2
                                             + sats.points[0].z ** 2) ** 0.5 < 7.3e6
    tf = got["tf"][-1]
    assert [t.child_frame_id for t in tf.transforms] == ["sat_11", "sat_12", "sat_21", "sat_22", "sat_31", "sat_32"]
    assert tf.transforms[0].header.frame_id == "earth" and tf.transforms[0].header.stamp.sec >= EPOCH_S
    statuses = {s.name: s for d in got["diag"] for s in d.status}
    s11 = statuses["/sat_11/sat_11"]
    assert s11.hardware_id == "sat_11"
    keys = {kv.key for kv in s11.values}
    assert {"observations.own", "plan.version", "dtn.held", "rejected_messages"} <= keys
    assert "/moved/sat_12/sat_12" in statuses and "/dtn_router" in statuses

    # the remap moved sat_12's topics, and only sat_12's
    assert "/moved/sat_12/schedule" in graph and "/moved/sat_12/fix" in graph
    assert old_pubs == set(), sorted(old_pubs)
    assert "/sat_11/schedule" in graph
    with BagReader(out / "bag") as bag:
        topics = {t.topic for t in bag.topics()}
        assert "/moved/sat_12/schedule" in topics and "/sat_12/schedule" not in topics
        assert "/sat_11/schedule" in topics
        bag_fix = {deserialize_message(m.cdr, NavSatFix).header.stamp.sec: bytes(m.cdr)
                   for m in bag.messages(["/sat_11/fix"])}
    # live fixes are the bag's bytes for the same instant
    live = {deserialize_message(c, NavSatFix).header.stamp.sec: bytes(c) for c in got["fix11"]}
    common = set(live) & set(bag_fix)
    assert len(common) >= 5
    # the same message; on the wire DDS pads the payload to 4 bytes (its encapsulation options say how
    # much), so the bytes are the bag's after the 4-byte CDR header, plus the padding
    for sec in common:
        assert deserialize_message(live[sec], NavSatFix) == deserialize_message(bag_fix[sec], NavSatFix)
        assert live[sec][4:len(bag_fix[sec])] == bag_fix[sec][4:]
