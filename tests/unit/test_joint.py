"""Joint planning of satellites with overlapping fields of regard (sat_node/scheduler/joint.py).

Oracles: the exhaustive joint optimum over every pair of feasible plans (brute.solve_brute_joint) on
tiny two-satellite instances where each satellite's DP is exact (no GP visible to one satellite for
as long as the shortest slew); the joint MILP (HiGHS); a hand-worked two-GP case; on two-satellite
instances cut from the paper scenario's overlapping passes, >= 90 % of the joint MILP.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from dp_instances import PAPER_SLEW, gp_ecef, track

from orbit_clock.access import for_mask
from sat_node.scheduler import (
    joint_value,
    solve_brute_joint,
    solve_dp,
    solve_joint,
    solve_milp_joint,
)
from sat_node.scheduler.joint import with_claims, with_forbidden
from sat_node.scheduler.problem import build_problem


def pair_instance(seed: int, *, n_gp: int = 4, n_steps: int = 30, max_window: int = 4, shared_value: bool = True):
    """Two satellites on neighbouring tracks over the same GPs; each GP visible to each satellite during
    one random run of <= max_window steps (< the shortest slew: each DP is exact); one value matrix."""
    rng = np.random.default_rng(seed)
    times = -15.0 + np.arange(n_steps, dtype=float)
    gp = gp_ecef(rng.uniform(-3, 3, n_gp), rng.uniform(-3, 3, n_gp))
    absval = rng.integers(1, 257, size=(n_steps, n_gp)).astype(float)
    out = []
    for name, tilt in (("sat_11", 0.0), ("sat_21", 4.0)):
        sat = track(times, tilt)
        geo = for_mask(sat, gp, 55.0)
        m = np.zeros_like(geo)
        for j in range(n_gp):
            length = int(rng.integers(1, max_window + 1))
            start = int(rng.integers(0, n_steps - length + 1))
            m[start:start + length, j] = True
        m &= geo
        a = absval if shared_value else rng.integers(1, 257, size=(n_steps, n_gp)).astype(float)
        out.append(build_problem(t0_s=times[0], step_s=1.0, sat_pos_km=sat, gp_ecef_km=gp, in_for=m, absval=a,
                                 slew=PAPER_SLEW, revisit_zero_s=900.0, gp_ids=np.arange(n_gp), sat_name=name))
    return out


@pytest.mark.parametrize("seed", range(40))
def test_joint_dp_equals_brute_force_on_tiny_pairs(seed):
    probs = pair_instance(seed, n_gp=int(3 + seed % 4))
    res = solve_joint(probs)
    best, best_v = solve_brute_joint(probs)
    assert res.exact
    assert res.value == pytest.approx(best_v, abs=1e-9)
    assert res.value == pytest.approx(joint_value(probs, res.plans), abs=1e-9)


@pytest.mark.parametrize("seed", range(12))
def test_joint_milp_is_the_optimum_on_tiny_pairs_and_the_dp_reaches_it(seed):
    probs = pair_instance(100 + seed, n_gp=5)
    plans, obj, optimal = solve_milp_joint(probs)
    _best, best_v = solve_brute_joint(probs)
    assert optimal
    # the MILP forbids slew-infeasible pairs pairwise (stricter than the sequential rule, milp.py)
    assert obj <= best_v + 1e-6
    assert joint_value(probs, plans) == pytest.approx(obj, abs=1e-6)
    assert solve_joint(probs).value >= obj - 1e-6


def test_hand_worked_two_gps_two_satellites():
    """Both satellites see GP 0 (worth 200) and GP 1 (worth 100) at the same steps and can take one
    look each. Alone, each takes GP 0 (one of the two looks is then worth nothing: 200 for the group);
    jointly, one takes each: 300."""
    times = np.arange(8.0)
    gp = gp_ecef(np.array([0.2, -0.2]), np.array([0.0, 0.0]))
    probs = []
    for name, tilt in (("sat_11", 0.0), ("sat_21", 1.0)):
        m = np.zeros((8, 2), bool)
        m[6:8, :] = True
        probs.append(build_problem(t0_s=0.0, step_s=1.0, sat_pos_km=track(times, tilt), gp_ecef_km=gp, in_for=m,
                                   absval=np.array([200.0, 100.0]), slew=PAPER_SLEW, revisit_zero_s=900.0,
                                   gp_ids=np.array([0, 1]), sat_name=name))
    alone = [solve_dp(p) for p in probs]
    assert [list(a.gp_ids) for a in alone] == [[0], [0]]
    assert joint_value(probs, alone) == pytest.approx(200.0)
    res = solve_joint(probs)
    assert sorted(int(g) for pl in res.plans for g in pl.gp_ids) == [0, 1]
    assert res.value == pytest.approx(300.0) and res.exact


def test_forbidden_and_claims():
    p = pair_instance(5, n_gp=4)[0]
    f = with_forbidden(p, [1, 2])
    assert np.all(f.v_first[:, 1:3] == 0) and np.array_equal(f.v_first[:, [0, 3]], p.v_first[:, [0, 3]])
    c = with_claims(p, [(0, float(p.times_s[10]))])
    zero = np.abs(p.times_s - p.times_s[10]) < 900.0
    assert np.all(c.v_first[zero, 0] == 0)
    assert np.array_equal(c.v_first[:, 1:], p.v_first[:, 1:])


def test_long_windows_resolve_contests_by_claims():
    """Windows longer than revisit_zero_s: the dive gives a contested GP to the first look only
    within 15 min of it."""
    probs = pair_instance(9, n_gp=6, n_steps=30)
    probs = [dataclasses.replace(p, revisit_zero_s=10.0, _cache={}) for p in probs]
    res = solve_joint(probs)
    assert not res.exact
    looks = sorted((t, g, i) for i, pl in enumerate(res.plans) for g, t in zip(pl.gp_ids, pl.t_s))
    for a in looks:
        for b in looks:
            if a[1] == b[1] and a[2] != b[2] and a[0] < b[0]:
                assert b[0] - a[0] >= 10.0


def test_joint_dp_reaches_90_percent_of_the_milp_on_paper_instances():
    """Two satellites whose fields of regard overlap over a paper region, 60 s, 20 GPs of the overlap
    (bringup/cli/bench_scheduler.py joint_milp_comparison)."""
    from bringup.cli.bench_scheduler import joint_milp_comparison
    from bringup.scenario.config import load_scenario
    from bringup.scenario.world import OrbitContext

    ctx = OrbitContext.from_scenario(load_scenario("paper").with_overrides(hours=2.0))
    r = joint_milp_comparison(ctx, instances=4, n_gps=20, window_s=60.0, time_limit_s=60.0)
    assert r["joint_instances"] >= 2
    assert r["joint_dp_over_milp_min"] >= 0.9, r
