"""The centralized mode's ground segment (ground_station.ground_segment), in a local-engine run of six
satellites over three hours: what the satellites execute is what the ground uplinked, and the ground
never sends two satellites to one GP within 15 min."""

from __future__ import annotations

from collections import defaultdict

import pytest

from bringup.engine.local import run_local
from bringup.scenario.participants import all_participants
from bringup.scenario.world import World
from msgs_json import codec
from msgs_json import schemas as S
from tests.keys import TEST_BPSEC_KEY


@pytest.fixture(scope="module")
def run(paper_scenario):
    # the footprint spacing (500 GPs): GPs are seen more than once in 3 h, so the 15-min rule is put to work
    world = World.build(paper_scenario.with_overrides(sats=6, hours=3, gp_spacing_km=8.0))
    sc = world.scenario
    res = run_local(all_participants(world, "centralized", bpsec_key=TEST_BPSEC_KEY), horizon_ns=sc.horizon_ns,
                    max_step_ns=int(sc.scenario.lockstep_max_step_s * 1e9))
    wanted = ("/ground/uplink", "/ground/downlink")
    msgs = [codec.decode(e.topic, e.data) for e in res.envelopes
            if e.topic in wanted or e.topic.endswith("/observations")]
    return world, msgs


def test_every_observation_is_an_item_of_the_last_plan_uplinked_to_its_satellite(run):
    world, msgs = run
    uplinks = [m for m in msgs if isinstance(m, S.GroundUplink)]
    obs = [m for m in msgs if isinstance(m, S.Observation)]
    assert len(uplinks) > len(world.sat_names) and len(obs) > 50  # passes happened, plans were executed
    for o in obs:
        before = [u for u in uplinks if u.sat == o.sat and u.t_ns <= o.t_ns]
        assert before, o
        last = max(before, key=lambda u: u.t_ns)
        assert o.schedule_version == last.schedule.version
        assert (o.gp, o.t_ns) in {(it.gp, it.t_ns) for it in last.schedule.items}


def test_no_gp_observed_by_two_satellites_within_revisit_zero(run):
    world, msgs = run
    zero_ns = int(world.scenario.value.revisit_zero_s * 1e9)
    by_gp = defaultdict(list)
    for o in msgs:
        if isinstance(o, S.Observation):
            by_gp[o.gp].append((o.t_ns, o.sat))
    pairs = 0
    for looks in by_gp.values():
        looks.sort()
        for (t1, s1), (t2, s2) in zip(looks, looks[1:]):
            pairs += 1
            assert s1 == s2 or t2 - t1 >= zero_ns, (s1, t1, s2, t2)
    assert pairs > 0


def test_downlinks_carry_every_observation_once(run):
    """What the ground learns: each executed observation reaches it in exactly one downlink, at the
    first pass after it."""
    _world, msgs = run
    obs = {(m.sat, m.gp, m.t_ns) for m in msgs if isinstance(m, S.Observation)}
    down = [(d.t_ns, (o.sat, o.gp, o.t_ns))
            for d in msgs if isinstance(d, S.GroundDownlink) for o in d.observations]
    keys = [k for _t, k in down]
    assert len(keys) == len(set(keys)) and set(keys) <= obs
    assert all(k[2] <= t for t, k in down)
