"""MILP reference (HiGHS) against brute force, and DP against the MILP on paper-scenario instances."""

import numpy as np
import pytest
from dp_instances import random_instance

from bringup.scenario.world import OrbitContext
from sat_node.scheduler import Knowledge, plan_violations, solve_brute, solve_dp, solve_milp


@pytest.mark.parametrize("seed", range(12))
def test_milp_equals_pairwise_brute(seed):
    p = random_instance(seed, n_gp=4, n_steps=36, max_window=12 if seed % 2 else 5, prior=seed % 3 == 0)
    m = solve_milp(p)
    b = solve_brute(p, rule="pairwise", max_candidates=80)
    assert m.optimal
    assert m.objective == pytest.approx(b.value, abs=1e-6)
    assert plan_violations(p, m.plan.steps, m.plan.cols, rule="pairwise") == []
    # pairwise is at least as strict as sequential: the sequential optimum is never below it
    assert solve_brute(p, rule="sequential", max_candidates=80).value >= b.value - 1e-9


def test_milp_refuses_windows_longer_than_revisit():
    p = random_instance(0, n_gp=2, n_steps=20, max_window=5, revisit_zero_s=10.0)
    with pytest.raises(NotImplementedError, match="revisit_zero_s"):
        solve_milp(p)


@pytest.fixture(scope="module")
def paper_ctx(paper_scenario):
    return OrbitContext.from_scenario(paper_scenario)


def test_dp_within_90_percent_of_milp_on_paper_instances(paper_ctx):
    rng = np.random.default_rng(2)
    planner, field = paper_ctx.planner(), Knowledge(paper_ctx.osse)
    starts = planner.pass_starts_s("sat_11", 0.0, 21600.0)
    assert len(starts) >= 2
    ratios = []
    for t0 in starts[:3]:
        full = planner.instance("sat_11", float(t0), field, window_s=600.0)
        ids = np.sort(rng.choice(full.gp_ids, size=min(15, len(full.gp_ids)), replace=False))
        p = planner.instance("sat_11", float(t0) + 60.0, field, window_s=45.0, gp_ids=ids)
        m = solve_milp(p, time_limit_s=60.0)
        d = solve_dp(p)
        assert m.optimal
        if m.objective > 0:
            ratios.append(d.value / m.objective)
    assert ratios and min(ratios) >= 0.9
