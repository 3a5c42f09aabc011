"""Our aeossp feasibility check (bringup/benchmarks/aeossp/check.py) on a tiny hand-made case: a
valid two-action schedule passes with the metrics computed by hand; each rule (grid, window,
duration, horizon, sensor, visibility, off-nadir, overlap, slew gap, battery) rejects a copy broken
in that one way; switching the slew or battery rule off lets the broken copy through; the energy
PC equals the closed-form sum."""

from __future__ import annotations

from dataclasses import replace

import pytest

from bringup.benchmarks.aeossp.case import Action, read_case
from bringup.benchmarks.aeossp.check import check, metrics, slew_need_s
from bringup.benchmarks.aeossp.geometry import Orbits
from tests.unit.aeossp_cases import standard

GOOD = [Action("sat_a", "t1", 590, 610), Action("sat_a", "t2", 650, 670)]


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    return read_case(standard(tmp_path_factory.mktemp("c") / "c")[0])


def test_valid_schedule_and_its_metrics(case):
    r = check(case, GOOD)
    assert r.valid, [v.text for v in r.violations]
    w = sum(t.weight for t in case.tasks)
    assert r.metrics["WCR"] == pytest.approx(5.0 / w) and r.metrics["CR"] == pytest.approx(2 / 5)
    assert r.metrics["TAT"] == pytest.approx(((610 - 300) + (670 - 340)) / 2)
    # a later duplicate earns nothing more and the earliest completion sets TAT
    dup = metrics(case, GOOD + [Action("sat_b", "t1", 700, 720)], 0.0)
    assert (dup["WCR"], dup["CR"], dup["TAT"]) == (r.metrics["WCR"], r.metrics["CR"], r.metrics["TAT"])


@pytest.mark.parametrize("broken, kind, words", [
    (Action("sat_a", "t1", 592, 612), "structure", "off the 5-s action grid"),
    (Action("sat_a", "t1", 200, 220), "structure", "outside the task window"),
    (Action("sat_a", "t1", 590, 615), "structure", "requires 20 s"),
    (Action("sat_a", "t4", 890, 910), "structure", "sensor visible cannot serve a infrared task"),
    (Action("sat_a", "t5", 590, 610), "geometry", "target not visible"),
    (Action("sat_a", "t1", 300, 320), "geometry", "off-nadir"),
])
def test_each_action_rule_rejects(case, broken, kind, words):
    r = check(case, [GOOD[1], broken])
    assert not r.valid and r.metrics == {"CR": 0.0, "WCR": 0.0, "TAT": None, "PC": 0.0}
    assert [v.kind for v in r.violations] == [kind] and words in r.violations[0].text


def test_overlap_rejected(case):
    r = check(case, [GOOD[0], Action("sat_a", "t1", 600, 620)])
    assert [v.kind for v in r.violations] == ["overlap"]


def test_slew_gap_rejected_and_switchable(case):
    orbits = Orbits(case.satellites, case.mission.start)
    tight = [GOOD[0], Action("sat_a", "t2", 630, 650)]   # looking ~9 deg back, then ~9 deg ahead: 20 s is short
    need = slew_need_s(case, orbits, GOOD[0], tight[1])
    assert need > 3.0                                    # more than the settle time alone
    r = check(case, tight, orbits)
    assert [v.kind for v in r.violations] == ["slew"]
    assert check(case, tight, orbits, slew=False).valid


def test_battery_rejected_and_switchable(case):
    poor = replace(case, satellites=(replace(case.satellites[0], initial_wh=1.0, idle_w=0.0, charge_w=0.0,
                                             slew_w=0.0), case.satellites[1]))
    assert check(poor, []).valid                          # idle costs nothing: never below zero
    r = check(poor, [GOOD[0]])                            # 480 W for 20 s = 2.67 Wh > 1 Wh
    assert [v.kind for v in r.violations] == ["battery"] and "below zero" in r.violations[0].text
    assert check(poor, [GOOD[0]], battery_rule=False).valid


def test_pc_closed_form(case):
    a, b = case.satellites
    orbits = Orbits(case.satellites, case.mission.start)
    r = check(case, GOOD, orbits)
    need = [slew_need_s(case, orbits, None, GOOD[0]), slew_need_s(case, orbits, GOOD[0], GOOD[1])]
    idle = (a.idle_w + b.idle_w) * 3600 / 3600.0
    expect = idle + a.imaging_w * 40 / 3600.0 + a.slew_w * sum(need) / 3600.0
    assert r.metrics["PC"] == pytest.approx(expect, rel=1e-9)
