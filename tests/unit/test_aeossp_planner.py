"""The aeossp planner (bringup/benchmarks/aeossp/planner.py) and command (bringup/cli/aeossp.py) on
tiny cases of our own: the DP's value equals a brute force over every subset of a satellite's
candidates; every mode's plan passes our check with no task twice; onboard planning does not peek (a
higher-ranked satellite's plan is the same with or without its lower-ranked neighbour, and the
neighbour never takes a task the higher one announced); the battery price makes a poor satellite's
plan feasible; the command writes a solution our check accepts and refuses a bad folder in one line."""

from __future__ import annotations

import itertools
import json
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest

from bringup.benchmarks.aeossp import planner as P
from bringup.benchmarks.aeossp.case import read_case
from bringup.benchmarks.aeossp.check import check
from bringup.benchmarks.aeossp.geometry import Orbits
from tests.unit.aeossp_cases import sat_entry, standard, subsat, task_entry, tle, write_case


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    return read_case(standard(tmp_path_factory.mktemp("c") / "c")[0])


def _crowded(folder, with_c=True):
    """sat_a and sat_c (same plane, 2 deg behind) over eight tasks near sat_a's track."""
    a, c = tle(10.0, 0.0, 90001), tle(10.0, 358.0, 90003)
    tasks = []
    for i, (ts, dlon) in enumerate([(560, 0.0), (580, 0.8), (600, -0.6), (620, 0.3), (640, 1.0), (660, -1.0),
                                    (690, 0.0), (720, 0.5)]):
        lat, lon = subsat(*a, ts)
        tasks.append(task_entry(f"k{i}", lat, lon + dlon, ts - 200, ts + 400, w=1.0 + (i % 3)))
    sats = [sat_entry("sat_a", *a)] + ([sat_entry("sat_c", *c)] if with_c else [])
    return read_case(write_case(folder, sats, tasks))


def _brute(cand: P.Candidates) -> float:
    n, best = len(cand), 0.0
    for r in range(1, n + 1):
        for sub in itertools.combinations(range(n), r):
            seq = sorted(sub, key=lambda i: cand.start[i])
            if len({cand.task[i] for i in seq}) < len(seq):
                continue
            i0 = seq[0]
            ok = cand.start[i0] >= cand.need_s(P._angles_rows(cand.nadir0[[i0]], cand.u0[[i0]])[0])
            for j, i in itertools.pairwise(seq):
                ok = ok and cand.end[j] <= cand.start[i] and \
                    cand.start[i] - cand.end[j] >= cand.need_s(P._angles(cand.u1[j], cand.u0[i]))
            if ok:
                best = max(best, float(sum(cand.weight[i] for i in seq)))
    return best


def test_dp_equals_brute_force(tmp_path, monkeypatch):
    monkeypatch.setattr(P, "MAX_STARTS", 2)
    c = _crowded(tmp_path / "k", with_c=False)
    cand = P.Candidates(c, Orbits(c.satellites, c.mission.start), "sat_a")
    assert 8 <= len(cand) <= 18
    path = P.dp(cand, np.ones(len(cand), bool), 0.0)
    got = float(sum(cand.weight[i] for i in path))
    assert got == pytest.approx(_brute(cand))
    assert 0 < len(path) < 8                      # the slew law really binds: not every task fits


@pytest.mark.parametrize("mode", ["onboard", "central", "greedy"])
def test_every_plan_passes_the_check(case, mode):
    acts = P.plan(case, mode, 60.0)
    r = check(case, acts)
    assert r.valid and len({a.task_id for a in acts}) == len(acts)
    assert {"t1", "t2"} <= {a.task_id for a in acts}      # the two weighty tasks on the track are easy


def test_onboard_does_not_peek(tmp_path):
    both = _crowded(tmp_path / "both")
    alone = _crowded(tmp_path / "alone", with_c=False)
    pb, pa = P.plan(both, "onboard", 60.0), P.plan(alone, "onboard", 60.0)
    a_both = [x for x in pb if x.sat_id == "sat_a"]
    assert a_both == [x for x in pa if x.sat_id == "sat_a"]       # sat_a knows nothing of sat_c
    c_tasks = {x.task_id for x in pb if x.sat_id == "sat_c"}
    assert c_tasks and not c_tasks & {x.task_id for x in a_both}  # sat_c defers to sat_a's announcement
    central = P.plan(both, "central", 60.0)
    assert check(both, central).valid and len({x.task_id for x in central}) == len(central)


def test_battery_price_makes_a_poor_satellite_feasible(tmp_path):
    c = _crowded(tmp_path / "k", with_c=False)
    poor = replace(c, satellites=(replace(c.satellites[0], initial_wh=12.0, idle_w=0.0, charge_w=0.0),))
    rich_acts = P.plan(c, "onboard", 60.0)
    poor_acts = P.plan(poor, "onboard", 60.0)
    assert check(poor, poor_acts).valid
    assert not check(poor, rich_acts).valid                     # the unconstrained plan would deplete it
    assert 0 < len(poor_acts) < len(rich_acts)


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "bringup.cli", "aeossp", *args], check=False, capture_output=True,
                          text=True, timeout=300)


def test_command_solves_and_checks(tmp_path):
    d, _ = standard(tmp_path / "c")
    out = tmp_path / "sol.json"
    r = _cli("solve", str(d), "--out", str(out), "--planning", "onboard", "--time-limit", "30")
    assert r.returncode == 0, r.stderr
    line = json.loads(r.stdout)
    assert line["WCR"] > 0 and json.loads(out.read_text())["actions"]
    r = _cli("check", str(d), str(out))
    assert r.returncode == 0 and json.loads(r.stdout)["valid"] and json.loads(r.stdout)["WCR"] == line["WCR"]
    doc = json.loads(out.read_text())
    doc["actions"][0]["start_time"] = doc["actions"][0]["start_time"][:-3] + "02Z"   # off the grid
    out.write_text(json.dumps(doc))
    r = _cli("check", str(d), str(out))
    assert r.returncode == 1 and "grid" in r.stderr
    (d / "tasks.yaml").write_text("tasks: 7\n")
    r = _cli("solve", str(d), "--out", str(out))
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "tasks.yaml" in r.stderr
