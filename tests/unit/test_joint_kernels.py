"""The joint group's value on arrays (sat_node/scheduler/joint_kernels.py) equals the loop's.

Oracle: ``joint_value`` of sat_node/scheduler/joint.py as first written (the loop over every look,
kept in the module as ``value_loop``, the path for small groups), against both paths of ``group_value`` (arrays and compiled sum; the loop for small
groups) and ``joint_value`` itself, on random groups (2-4 members, windows starting at the same or
different times, shared and own GPs, repeats inside and beyond the revisit window, known prior
looks, tied times) and on the DP plans of two-satellite instances: the value's bits.
"""

from __future__ import annotations

import numpy as np
import pytest
from dp_instances import PAPER_SLEW, gp_ecef, track

from sat_node.scheduler import solve_dp
from sat_node.scheduler.dp import make_plan
from sat_node.scheduler.joint import joint_value
from sat_node.scheduler.joint_kernels import ARRAY_LOOKS, group_value, value_loop
from sat_node.scheduler.problem import build_problem


def _random_group(seed: int):
    rng = np.random.default_rng(seed)
    n_sats = int(rng.integers(2, 5))
    n_all = int(rng.integers(3, 12))
    gps = gp_ecef(rng.uniform(-3, 3, n_all), rng.uniform(-3, 3, n_all))
    rz = float(rng.choice([5.0, 12.0, 900.0]))
    problems, plans = [], []
    for s in range(n_sats):
        n_steps = int(rng.integers(5, 40))
        ids = np.sort(rng.choice(n_all, int(rng.integers(1, n_all + 1)), replace=False))
        t0 = float(rng.choice([0.0, 2.0, 3.5])) if seed % 2 else 0.0  # same starts: tied times
        times = t0 + np.arange(n_steps, dtype=float)
        p = build_problem(t0_s=t0, step_s=1.0, sat_pos_km=track(times, 2.0 * s), gp_ecef_km=gps[ids],
                          in_for=rng.random((n_steps, len(ids))) < 0.8,
                          absval=rng.integers(0, 257, (n_steps, len(ids))).astype(float),
                          prior_count=rng.integers(0, 3, (n_steps, len(ids))),
                          prior_recent=rng.random((n_steps, len(ids))) < 0.1, slew=PAPER_SLEW,
                          revisit_zero_s=rz, gp_ids=ids, sat_name=f"sat_{s}")
        n_looks = int(rng.integers(0, min(n_steps, 12) + 1))
        steps = np.sort(rng.choice(n_steps, n_looks, replace=False))
        cols = rng.integers(0, len(ids), n_looks)
        problems.append(p)
        plans.append(make_plan(p, steps, cols))
    return problems, plans


@pytest.mark.parametrize("seed", range(300))
def test_value_equals_the_loop_on_random_groups(seed):
    problems, plans = _random_group(seed)
    _assert_same_value(problems, plans)


def _assert_same_value(problems, plans):
    want = np.float64(value_loop(problems, plans)).tobytes()
    for got in (joint_value(problems, plans), group_value(problems, plans, array_looks=0),
                group_value(problems, plans, array_looks=10 ** 9)):
        assert np.float64(got).tobytes() == want


def test_value_equals_the_loop_on_dp_plans():
    """Two satellites on neighbouring tracks over the same GPs, each solved alone by the DP (the
    joint planner's first dive round)."""
    big = 0
    for seed in range(30):
        rng = np.random.default_rng(seed)
        n_gp, n_steps = 30, 120
        times = -60.0 + np.arange(n_steps, dtype=float)
        gp = gp_ecef(rng.uniform(-3, 3, n_gp), rng.uniform(-3, 3, n_gp))
        absval = rng.integers(1, 257, size=(n_steps, n_gp)).astype(float)
        problems = [build_problem(t0_s=times[0], step_s=1.0, sat_pos_km=track(times, tilt), gp_ecef_km=gp,
                                  in_for=np.ones((n_steps, n_gp), bool), absval=absval, slew=PAPER_SLEW,
                                  revisit_zero_s=900.0, gp_ids=np.arange(n_gp), sat_name=name)
                    for name, tilt in (("sat_11", 0.0), ("sat_21", 4.0))]
        plans = [solve_dp(p) for p in problems]
        _assert_same_value(problems, plans)
        big += sum(len(pl) for pl in plans) >= ARRAY_LOOKS
    assert big >= 10  # groups past ARRAY_LOOKS: joint_value took the array path too
