"""The operations logic inside one satellite (sat_node/satellite.py + sat_node/operations/), stepped
by hand without an engine.

Oracles: the rules of sat_node/operations/modes.py applied to one satellite whose faults are known;
the planner's ``partners`` argument seen by a spy (a satellite leaves out of its joint plans exactly
the neighbours whose notice reached it - a neighbour in SAFE whose notice did not arrive is still
counted on: no peeking at another satellite's state).
"""

from __future__ import annotations

import msgspec
import pytest

from bringup.scenario.config import _validate
from bringup.scenario.world import World
from msgs_json import codec
from sat_node.operations.notice import ModeNotice
from sat_node.satellite import SatelliteLogic
from tests.keys import TEST_BPSEC_KEY

_NS = 1_000_000_000
SAT = "sat_24"


def _world(paper_scenario, faults):
    raw = msgspec.to_builtins(paper_scenario.with_overrides(sats=12, hours=0.5))
    raw.pop("source_path", None)
    raw["faults"] = faults
    return World.build(_validate(raw, "<test>"))


@pytest.fixture(scope="module")
def world(paper_scenario):
    return _world(paper_scenario, [{"sat": SAT, "kind": "acs_stuck", "at_s": 400.0, "until_s": 900.0},
                                   {"sat": "sat_23", "kind": "store_full", "at_s": 0.0}])


def _modes(emits):
    return [codec.decode(e.topic, e.data) for e in emits if e.topic.endswith("/ops/mode")]


def test_acs_fault_safe_in_its_step_then_recovers(world):
    s = SatelliteLogic(world, SAT, "distributed", bpsec_key=TEST_BPSEC_KEY)
    r = s.start(0)
    assert r.next_wakeup_ns <= 400 * _NS  # the fault's start is a wake-up
    t = 0
    while t < 400 * _NS:
        t = min(r.next_wakeup_ns or 400 * _NS, t + 10 * _NS, 400 * _NS)
        r = s.step(t, [])
        if t < 400 * _NS:
            assert s.ops.mode == "NOMINAL"
    ch = _modes(r.emits)
    assert [(m.t_ns, m.mode, m.reason) for m in ch] == [(400 * _NS, "SAFE", "acs_fault")]
    assert s.plan == [] and s.target_km is None  # no plan, safe attitude (nadir)
    assert not [e for e in r.emits if e.topic.endswith("/observations")]
    assert r.next_wakeup_ns == 900 * _NS  # the fault's end; no replan wakes it while SAFE
    r = s.step(900 * _NS, [])
    assert [(m.mode, m.previous) for m in _modes(r.emits)] == [("NOMINAL", "SAFE")]
    assert any(e.topic.endswith("/schedule") for e in r.emits)  # replans at once
    tim = s.ops.time_in_mode_s(1800 * _NS)
    assert tim == {"NOMINAL": 1300.0, "DEGRADED": 0.0, "SAFE": 500.0}


def test_a_full_store_images_but_stores_no_bundle(world):
    s = SatelliteLogic(world, "sat_23", "distributed", bpsec_key=TEST_BPSEC_KEY)
    r, t, looks = s.start(0), 0, 0
    assert s.ops.mode == "NOMINAL"  # the rules run from the first step on
    while t < 1800 * _NS:
        t = min(t + 10 * _NS, 1800 * _NS)
        r = s.step(t, [])
        looks += sum(1 for e in r.emits if e.topic.endswith("/observations"))
        assert s.ops.mode == "DEGRADED" and s.ops.reason == "store_full"
    assert looks > 0 and s.ops.bundles_not_stored == looks
    assert s.agent.held_count() == 0


def test_partners_leave_out_exactly_the_notified_neighbours(world, monkeypatch):
    s = SatelliteLogic(world, "sat_23", "distributed", bpsec_key=TEST_BPSEC_KEY)
    seen = []
    real = world.planner.plan

    def spy(*a, **kw):
        seen.append(kw.get("partners"))
        return real(*a, **kw)

    monkeypatch.setattr(world.planner, "plan", spy)
    s.start(0)
    # sat_24 is in SAFE from 400 s (its own fault) but nothing told sat_23: still counted on
    s.step(600 * _NS, [])
    assert seen[-1] is None
    s._on_notice(ModeNotice(SAT, "SAFE", False, 400 * _NS))
    assert s._news_conflict  # replans at its next step
    s.step(610 * _NS, [])
    names = [n for n, _free in seen[-1]]
    assert SAT not in names and sorted(names) == sorted(n for n in world.sat_names if n not in (SAT, "sat_23"))
    s._on_notice(ModeNotice(SAT, "NOMINAL", True, 900 * _NS))
    s.step(910 * _NS, [])
    assert seen[-1] is None
    with pytest.raises(ValueError, match="not another satellite"):
        s._on_notice(ModeNotice("sat_23", "SAFE", False, 1))
