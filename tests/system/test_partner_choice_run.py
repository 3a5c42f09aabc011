"""A whole run with the partner choice asking the region pass index equals one that asks every satellite.

96 satellites in the paper's 3 planes, 0.25 h, joint planning with at most one partner
(``scheduler.joint_max_partners = 1``), local engine in this process: once with the scenario's
planner (``Planner.group`` with ``passes``, best-first, orbit_clock/access.py ``RegionPrefilter``),
once with the same planner without the index (every partner asked one by one, every passing one
looked at and sorted). Oracle: the second run, the choice as first written - every message of the
two runs (topic, time, bytes: schedules, observations, bundles) must be the same, the CPU seconds a
schedule reports aside, and joint plans must have been made.
"""

from __future__ import annotations

import re

import pytest

from tests.keys import TEST_BPSEC_KEY

pytestmark = [pytest.mark.system]


def _run(world):
    from bringup.engine.local import run_local
    from bringup.scenario.participants import all_participants

    sc = world.scenario
    parts = all_participants(world, "distributed", bpsec_key=TEST_BPSEC_KEY)
    res = run_local(parts, horizon_ns=sc.horizon_ns, max_step_ns=round(sc.scenario.lockstep_max_step_s * 1e9))
    return [(e.topic, e.t_ns, _CPU.sub(r'"\1":0', e.data) if isinstance(e.data, str) else e.data)
            for e in res.envelopes]


_CPU = re.compile(r'"(\w*cpu\w*)":[-+0-9.eE]+')  # the planners' own CPU seconds (a schedule's solve_cpu_s)


def test_a_run_with_the_pass_index_is_the_run_without_it(paper_scenario, monkeypatch):
    from bringup.scenario.world import World
    from sat_node.scheduler import Planner

    world = World.build(paper_scenario.with_overrides(sats=96, hours=0.25, joint_max_partners=1))
    planner = world.planner
    assert planner.passes is not None and planner.settings.joint_max_partners == 1
    groups = []
    group = Planner.group

    def counted(self, *a, **kw):
        g = group(self, *a, **kw)
        groups.append(len(g))
        return g

    monkeypatch.setattr(Planner, "group", counted)
    with_index = _run(world)
    made = sum(1 for n in groups if n)
    groups.clear()
    world.__dict__["_planner"] = Planner(planner.constellation, planner.gp_ecef_km, planner.slew, planner.settings,
                                         candidates=planner.candidates, own=planner.own)
    assert world.planner.passes is None
    without = _run(world)
    assert made > 20 and made == sum(1 for n in groups if n)  # joint plans were made, as many each time
    assert len(with_index) == len(without)
    assert with_index == without
