"""The study's ground network and look cadence in the paper scenario.

* Passes: :func:`orbit_clock.ground_passes.pass_figures` on a hand-made plan; the paper scenario's
  stations give the study's "twice an orbit" (2 +- 0.3 passes per satellite and orbit).
* Uplinks: a centralized local-engine run of the paper scenario (three satellites, one per plane,
  the full 6 h) uplinks 2 +- 0.3 times per satellite and orbit (report.json ground.uplinks_per_orbit),
  as many as it has passes.
* Cadence: that run's in-pass look intervals (report.json looks.in_pass_interval_s) have the mode of
  the study's own traffic files, read here with the csv module (independent of the project's
  readers): 9 s.
"""

from __future__ import annotations

import csv
from collections import Counter, defaultdict
from itertools import pairwise

import pytest

from bringup.analysis.cadence import IN_PASS_GAP_S, cadence_figures
from bringup.analysis.report import RunMeta, build_report
from bringup.engine.local import run_local
from bringup.scenario.participants import all_participants
from bringup.scenario.world import World
from orbit_clock.contact_plan import Contact, ContactPlan
from orbit_clock.ground_passes import ground_contact_plan, orbit_period_s, pass_figures
from tests.keys import TEST_BPSEC_KEY


def test_pass_figures_of_a_hand_made_plan():
    c = [Contact(100.0, 400.0, "sat_11", "gs_a", 1e6, 0.01), Contact(300.0, 500.0, "sat_11", "gs_b", 1e6, 0.01),
         Contact(100.0, 400.0, "gs_a", "sat_11", 1e6, 0.01),  # the uplink direction is not a second pass
         Contact(900.0, 1000.0, "sat_11", "gs_a", 1e6, 0.01), Contact(50.0, 60.0, "sat_12", "gs_b", 1e6, 0.01),
         Contact(70.0, 80.0, "sat_99", "gs_b", 1e6, 0.01)]  # not one of the satellites asked about
    got = pass_figures(ContactPlan(c), ["sat_11", "sat_12"], horizon_s=3000.0, period_s=1000.0)
    # sat_11: [100, 500] (two stations overlapping: one pass) and [900, 1000]; sat_12: one
    assert got == {"passes": 3, "orbit_period_s": 1000.0, "passes_per_orbit": 3 / (2 * 3.0)}


def test_orbit_period_is_keplers():
    # 710 km: 98.98 min (a = 7088.137 km, mu = 398600.5 km^3/s^2)
    assert orbit_period_s(710.0) == pytest.approx(5938.94, abs=0.01)


def test_the_paper_stations_give_two_passes_an_orbit(paper_scenario):
    sc = paper_scenario
    got = pass_figures(ground_contact_plan(sc), sc.sat_names, sc.scenario.horizon_s,
                       orbit_period_s(sc.constellation.altitude_km))
    assert got["passes_per_orbit"] == pytest.approx(2.0, abs=0.3), got


@pytest.fixture(scope="module")
def centralized(paper_scenario):
    world = World.build(paper_scenario.with_overrides(sats=3))
    sc = world.scenario
    assert sc.constellation.planes == 3 and sc.scenario.horizon_s == 21600.0
    res = run_local(all_participants(world, "centralized", bpsec_key=TEST_BPSEC_KEY), horizon_ns=sc.horizon_ns,
                    max_step_ns=int(sc.scenario.lockstep_max_step_s * 1e9))
    return build_report(res.envelopes, RunMeta.for_world(world, "centralized", "local"))


def test_the_paper_scenario_uplinks_twice_an_orbit(centralized):
    g = centralized["ground"]
    assert g["stations"] == ["svalbard", "mcmurdo"]
    assert g["uplinks_per_orbit"] == pytest.approx(2.0, abs=0.3), g
    assert g["uplinks"] == g["passes"]  # one uplink a pass: the two stations never see a satellite at once


def _study_intervals(path) -> Counter:
    with open(path, newline="") as fh:
        times = defaultdict(set)
        for row in csv.DictReader(fh):
            times[row["source"]].add(float(row["time_s"]))
    out = Counter()
    for ts in times.values():
        ts = sorted(ts)
        out.update(b - a for a, b in pairwise(ts) if b - a < IN_PASS_GAP_S)
    return out


def test_in_pass_cadence_is_the_studys(centralized, paper_inputs):
    study = _study_intervals(paper_inputs / "traffic_case1.csv")
    mode_s, n = study.most_common(1)[0]
    assert mode_s == 9.0 and n / sum(study.values()) > 0.99  # 7792 of 7795
    ours = centralized["looks"]["in_pass_interval_s"]
    assert ours["count"] > 100
    assert ours["mode_s"] == mode_s
    assert ours["mode_share"] > 0.9, ours["hist"]


def test_cadence_figures_of_hand_made_looks():
    got = cadence_figures({"a": [0.0, 9.0, 18.0, 27.5, 200.0, 209.0], "b": [5.0, 11.0], "c": [1.0]})
    # a: 9, 9, 9.5, (172.5: a gap), 9; b: 6
    assert got["count"] == 5 and got["hist"] == {"6": 1, "9": 4}
    assert got["mode_s"] == 9 and got["mode_share"] == 0.8 and got["median_s"] == 9.0
    assert cadence_figures({})["mode_s"] is None
