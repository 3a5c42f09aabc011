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



class _Intervals:
    """A satellite of the assignment search reduced to candidate intervals (no slew)."""

    def __init__(self, rows):                      # rows: (task, start, end)
        self.task = np.array([r[0] for r in rows])
        self.start = np.array([r[1] for r in rows])
        self.end = np.array([r[2] for r in rows])


def _interval_dp(cand, gain):
    """Weighted interval scheduling by brute force over subsets (the search's per-satellite oracle)."""
    n, best, arg = len(cand.task), 0.0, []
    for r in range(1, n + 1):
        for sub in itertools.combinations(range(n), r):
            seq = sorted(sub, key=lambda i: cand.start[i])
            if len({cand.task[i] for i in seq}) < r or any(gain[i] <= 0 for i in seq):
                continue
            if all(cand.end[j] <= cand.start[i] for j, i in itertools.pairwise(seq)):
                v = float(sum(gain[i] for i in seq))
                if v > best + 1e-12:
                    best, arg = v, seq
    return arg


def _assignment_optimum(cands, w):
    order, best = sorted(cands), 0.0
    for who in itertools.product(range(-1, len(order)), repeat=len(w)):
        ok = True
        for q, sid in enumerate(order):
            mine = {k for k, h in enumerate(who) if h == q}
            c = cands[sid]
            path = _interval_dp(c, np.where(np.isin(c.task, list(mine)), 1.0, 0.0)) if mine else []
            ok = ok and {int(c.task[i]) for i in path} == mine
        if ok:
            best = max(best, float(sum(w[k] for k, h in enumerate(who) if h >= 0)))
    return best


def test_joint_search_moves_a_task_to_free_a_satellite():
    """Sequential planning gives X to s0 and leaves s1 idle; the optimum is s0: Y, s1: X."""
    import time

    from bringup.benchmarks.aeossp.search import assign

    cands = {"s0": _Intervals([(0, 0, 10), (1, 0, 10)]), "s1": _Intervals([(0, 0, 10)])}
    w = np.array([3.0, 2.0])
    start = np.array([0, -1])                      # what s0 alone, then s1 without X, would do
    got = assign(cands, w, start, _interval_dp, time.monotonic() + 30.0)
    assert list(got) == [1, 0] and w[got >= 0].sum() == _assignment_optimum(cands, w) == 5.0


def test_joint_search_on_random_instances_is_consistent_and_never_worse():
    import time

    from bringup.benchmarks.aeossp.search import assign

    rng = np.random.default_rng(7)
    hits = 0
    for _ in range(12):
        w = rng.integers(1, 5, 5).astype(float)
        cands = {}
        for s in ("s0", "s1", "s2"):
            rows = [(k, t0, t0 + 10) for k in range(5) for t0 in rng.choice([0, 5, 10, 15], 1)
                    if rng.random() < 0.6]
            cands[s] = _Intervals(rows or [(0, 0, 10)])
        start = np.full(5, -1)
        got = assign(cands, w, start, _interval_dp, time.monotonic() + 30.0)
        for q, sid in enumerate(sorted(cands)):   # each satellite can really do what it holds
            c, mine = cands[sid], set(np.flatnonzero(got == q).tolist())
            path = _interval_dp(c, np.where(np.isin(c.task, list(mine)), 1.0, 0.0)) if mine else []
            assert {int(c.task[i]) for i in path} == mine
        opt = _assignment_optimum(cands, w)
        assert w[got >= 0].sum() <= opt + 1e-9
        hits += w[got >= 0].sum() == opt
    assert hits >= 10                               # a heuristic, but near the optimum on small cases


def _joint_optimum(c, cands, w):
    """Brute force over the tasks sat_a keeps (all of them must fit), sat_c the best of the rest."""
    ca, cc = cands["sat_a"], cands["sat_c"]
    best = 0.0
    for r in range(len(w) + 1):
        for sub in itertools.combinations(range(len(w)), r):
            keep = np.isin(ca.task, sub)
            va = float(w[np.unique(ca.task[P.dp_gain(ca, np.where(keep, ca.weight, 0.0))])].sum()) if r else 0.0
            if va < float(w[list(sub)].sum()) - 1e-9:
                continue                               # sat_a cannot do all of them
            rest = ~np.isin(cc.task, sub)
            vc = float(w[np.unique(cc.task[P.dp_gain(cc, np.where(rest, cc.weight, 0.0))])].sum())
            best = max(best, va + vc)
    return best


def test_joint_search_reaches_the_brute_force_optimum(tmp_path, monkeypatch):
    import time

    from bringup.benchmarks.aeossp.search import assign

    monkeypatch.setattr(P, "MAX_STARTS", 2)
    c = _crowded(tmp_path / "k")
    orbits = Orbits(c.satellites, c.mission.start)
    cands = {s.sat_id: P.Candidates(c, orbits, s.sat_id) for s in c.satellites}
    w = np.array([t.weight for t in c.tasks])
    start = np.full(len(w), -1)
    start[np.unique(cands["sat_a"].task[P.dp(cands["sat_a"], np.ones(len(cands["sat_a"]), bool), 0.0)])] = 0
    got = assign(cands, w, start, P.dp_gain, time.monotonic() + 30.0)
    for q, sid in enumerate(sorted(cands)):       # each satellite can really do what it holds
        cd = cands[sid]
        mine = np.flatnonzero(got == q)
        path = P.dp_gain(cd, np.where(np.isin(cd.task, mine), cd.weight, 0.0))
        assert set(cd.task[path].tolist()) == set(mine.tolist())
    assert w[got >= 0].sum() >= w[start >= 0].sum()
    assert w[got >= 0].sum() == pytest.approx(_joint_optimum(c, cands, w))
