"""Onboard scheduler: instance building, DP (numba), brute-force and MILP oracles, non-agile baseline.

Typical call (one satellite, one replan)::

    p = build_problem(t0_s=..., step_s=1.0, sat_pos_km=..., gp_ecef_km=..., in_for=...,
                      absval=..., slew=SlewModel.from_scenario(sc), revisit_zero_s=900.0,
                      prior_count=..., prior_recent=..., init_target_km=...)
    plan = solve_dp(p, budget_s=1.0)   # plan.as_list() -> [(gp_id, t_s)], plan.value
"""

from sat_node.scheduler.brute import BruteTooLarge, solve_brute
from sat_node.scheduler.dp import Plan, ScheduleInvariantError, make_plan, solve_dp
from sat_node.scheduler.milp import MilpResult, solve_milp
from sat_node.scheduler.nonagile import nadir_pass_crossings, solve_nonagile
from sat_node.scheduler.problem import (
    ProblemError,
    SchedulingProblem,
    build_problem,
    circular_walker_ecef_km,
    evaluate_plan,
    for_mask,
    plan_violations,
    square_region_gp_ecef_km,
)

__all__ = [
    "BruteTooLarge", "solve_brute", "Plan", "ScheduleInvariantError", "make_plan", "solve_dp",
    "MilpResult", "solve_milp", "nadir_pass_crossings", "solve_nonagile", "ProblemError",
    "SchedulingProblem", "build_problem", "circular_walker_ecef_km", "evaluate_plan", "for_mask",
    "plan_violations", "square_region_gp_ecef_km",
]
