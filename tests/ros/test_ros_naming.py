"""Names of a run's nodes and topics (bringup/engine/ros/naming.py) resolved by rclpy itself.

Oracles: docs/design.md section 4's names (what every topic resolves to by default), rclpy's own name
resolution and remapping (rcl) for the namespaces, relative names and remap rules we give it, and
the invariant that both ends of every per-satellite link resolve to one name under a push.
"""

from __future__ import annotations

import pytest

from bringup.engine.ros.naming import check_namespace, node_name_and_namespace, ros_topic_name
from tests.keys import TEST_BPSEC_KEY

pytestmark = [pytest.mark.ros, pytest.mark.timeout(120)]


def _topics(paper_scenario):
    from bringup.scenario.participants import all_participants
    from bringup.scenario.world import World

    world = World.build(paper_scenario.with_overrides(sats=4, hours=0.1))
    parts = all_participants(world, "distributed", bpsec_key=TEST_BPSEC_KEY)
    out = {}
    for p in parts:
        topics = set(p.subscriptions())
        r = p.start(0)
        topics |= {e.topic for e in r.emits}
        if p.name == "router":  # what it publishes: each satellite's dtn/in, dtn/overheard and dtn/status
            from msgs_json import topics as T
            topics |= {T.dtn_in_topic(s) for s in world.sat_names} | {T.dtn_status_topic(s) for s in world.sat_names}
            topics |= {T.dtn_overheard_topic(s) for s in world.sat_names}
        if p.name in world.sat_names:
            from msgs_json import topics as T
            topics |= {T.dtn_out_topic(p.name), T.schedule_topic(p.name), T.observations_topic(p.name),
                       T.acs_state_topic(p.name), T.GROUND_DOWNLINK}
        out[p.name] = sorted(topics)
    return out


def _resolve(ctx, participant, topics, push="", extra_args=()):
    import rclpy

    name, ns = node_name_and_namespace(participant, push)
    node = rclpy.create_node(name, namespace=ns, context=ctx, start_parameter_services=False,
                             enable_rosout=False, cli_args=["--ros-args", *extra_args] if extra_args else None)
    try:
        return node.get_fully_qualified_name(), {t: node.resolve_topic_name(ros_topic_name(t, participant))
                                                  for t in topics}
    finally:
        node.destroy_node()


def test_default_names_are_designs_and_a_push_moves_both_ends(paper_scenario):
    import rclpy
    from rclpy.context import Context

    from bringup.engine.ros.launcher import lease_domain_id

    topics = _topics(paper_scenario)
    with lease_domain_id() as lease:
        ctx = Context()
        rclpy.init(context=ctx, domain_id=lease.domain_id)
        try:
            seen = {}
            for p, ts in topics.items():
                fqn, res = _resolve(ctx, p, ts)
                assert fqn == (f"/{p}/{p}" if p.startswith("sat_") else f"/{p}")
                assert res == {t: t for t in ts}, p  # by default every name is docs/design.md's
                for t in ts:
                    if t.startswith("/sat_"):
                        assert not ros_topic_name(t, p).startswith("/"), (p, t)  # relative
                seen[p] = ts
            pushed = {p: _resolve(ctx, p, ts, push="/fleet/a")[1] for p, ts in seen.items()}
            for p, res in pushed.items():
                for t, r in res.items():
                    if t.startswith("/sat_"):
                        assert r == "/fleet/a" + t, (p, t, r)  # every end of a satellite's link moves
                    else:
                        assert r == t  # global topics stay
            # a node-qualified namespace remap moves one satellite's own topics only
            fqn, res = _resolve(ctx, "sat_12", seen["sat_12"], extra_args=["-r", "sat_12:__ns:=/moved/sat_12"])
            assert fqn == "/moved/sat_12/sat_12"
            assert res["/sat_12/dtn/out"] == "/moved/sat_12/dtn/out"
            assert res["/ground/downlink"] == "/ground/downlink"
            fqn, res = _resolve(ctx, "sat_11", seen["sat_11"], extra_args=["-r", "sat_12:__ns:=/moved/sat_12"])
            assert res["/sat_11/dtn/out"] == "/sat_11/dtn/out"
            # and a topic remap of a relative name works on the expanded name
            _, res = _resolve(ctx, "sat_11", seen["sat_11"], extra_args=["-r", "schedule:=plan"])
            assert res["/sat_11/schedule"] == "/sat_11/plan"
        finally:
            rclpy.try_shutdown(context=ctx)


def test_check_namespace():
    assert check_namespace("") == "" and check_namespace("/") == ""
    assert check_namespace("/fleet/a_1") == "/fleet/a_1"
    for bad in ("fleet", "/fleet/", "//x", "/1x", "/a-b"):
        with pytest.raises(ValueError, match="namespace"):
            check_namespace(bad)


def test_names_beyond_9x9_are_satellites_too():
    # msgs_json/names.py: sat_PPPP_SSSS beyond 9 planes of 9; the same rules as sat_PS
    assert node_name_and_namespace("sat_0001_0012", "/fleet") == ("sat_0001_0012", "/fleet/sat_0001_0012")
    assert ros_topic_name("/sat_0001_0012/dtn/out", "sat_0001_0012") == "dtn/out"
    assert ros_topic_name("/sat_0001_0012/dtn/in", "router") == "sat_0001_0012/dtn/in"
    assert ros_topic_name("/sat_0001_0012/dtn/in", "sat_0002_0001") == "/sat_0001_0012/dtn/in"
    assert ros_topic_name("/ground/uplink", "sat_0001_0012") == "/ground/uplink"
    assert node_name_and_namespace("router") == ("router", "/")
