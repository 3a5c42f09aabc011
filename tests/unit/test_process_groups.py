"""Satellites grouped into the ROS engine's processes (bringup/scenario/participants.py
process_groups, `constellation run --sats-per-process`) and the factory that builds a group.

Oracle: every participant role is hosted exactly once, satellites in their order, the others alone;
one process per role with K = 1 (the spec the launcher wrote before groups existed)."""

from __future__ import annotations

import argparse

import pytest

from bringup.cli.run import sats_per_process
from bringup.engine.ros.factory import build, prepare
from bringup.engine.ros.run_spec import RunSpec
from bringup.errors import UserError
from bringup.scenario.participants import process_groups, roles_for, sats_per_process_auto
from msgs_json.names import sat_names


@pytest.mark.parametrize("n,k", [(24, 1), (24, 5), (96, 12), (96, 4), (240, 24), (7, 3), (3, 10)])
def test_groups_host_every_role_once_in_order(n, k):
    sats = sat_names(3, n // 3) if n % 3 == 0 else sat_names(1, n)
    roles = roles_for(sats, "distributed")
    groups = process_groups(roles, sats, k)
    hosted = [r for g in groups.values() for r in g]
    assert sorted(hosted) == sorted(roles) and len(hosted) == len(roles)
    sat_groups = [g for g in groups.values() if g[0] in sats]
    assert [s for g in sat_groups for s in g] == sats
    assert all(len(g) == k for g in sat_groups[:-1]) and 1 <= len(sat_groups[-1]) <= k
    assert groups["router"] == ["router"] and groups["contacts"] == ["contacts"]
    if k == 1:
        assert groups == {r: [r] for r in roles}
    else:
        assert list(groups)[: len(sat_groups)] == [f"sats_{i + 1:0{len(str(len(sat_groups)))}d}"
                                                   for i in range(len(sat_groups))]


def test_auto_keeps_small_runs_one_per_process():
    assert [sats_per_process_auto(n) for n in (1, 24, 25, 48, 96, 240, 1000)] == [1, 1, 2, 2, 4, 10, 42]
    ns = lambda **kw: argparse.Namespace(**{"sats_per_process": "auto", "restart": 0, **kw})  # noqa: E731
    assert sats_per_process(ns(), 24) == 1 and sats_per_process(ns(), 96) == 4
    assert sats_per_process(ns(restart=2), 96) == 1 and sats_per_process(ns(sats_per_process="12"), 96) == 12
    for bad in ({"sats_per_process": "0"}, {"sats_per_process": "x"}, {"sats_per_process": "4", "restart": 1}):
        with pytest.raises(UserError) as e:
            sats_per_process(ns(**bad), 96)
        assert "\n" not in str(e.value) and "--" in str(e.value)


def test_run_spec_groups_checked_and_built(tmp_path, paper_scenario):
    from bringup.engine.keys import RunKeys
    from bringup.scenario.world import World
    from tests.keys import TEST_BPSEC_KEY

    world = World.build(paper_scenario.with_overrides(sats=6, hours=0.5))
    path = world.save(tmp_path / "world.pkl")
    keys = RunKeys(b"r" * 32, TEST_BPSEC_KEY).write(tmp_path / "run.keys")
    groups = process_groups(roles_for(world, "distributed"), world.sat_names, 4)
    spec = RunSpec(factory="bringup.engine.ros.factory:build", roles=list(groups),
                   groups={g: m for g, m in groups.items() if m != [g]}, keys_file=str(keys),
                   extra={"world": str(path), "world_key": world.key})
    spec.check()
    deferred = build(spec, "sats_1")  # built when their nodes are configured (bringup/engine/lifecycle.py)
    assert [d.name for d in deferred] == world.sat_names[:4]
    parts = [d.build() for d in deferred]
    assert [p.name for p in parts] == world.sat_names[:4]
    assert parts[0].agent.graph is parts[3].agent.graph  # one contact graph per process
    assert all(p.agent.config.key == TEST_BPSEC_KEY for p in parts)  # the run's BPSec key
    assert [d.name for d in build(spec, "router")] == [d.build().name for d in build(spec, "router")] == ["dtn_router"]
    assert [d.name for d in build(spec, "contacts")] == [d.build().name for d in build(spec, "contacts")]
    assert set(prepare(spec, "contacts")) == set()
    for bad in ({"nope": ["sat_11"]}, {"sats_1": ["sat_11"], "sats_2": ["sat_11"]}, {"sats_1": []}):
        with pytest.raises(UserError):
            RunSpec(factory="a:b", roles=["sats_1", "sats_2"], groups=bad).check()
