"""Onboard scheduler: instance building, DP (numba), brute-force and MILP oracles, non-agile baseline.

Typical call (one satellite, one replan)::

    p = build_problem(t0_s=..., step_s=1.0, sat_pos_km=..., gp_ecef_km=..., in_for=...,
                      absval=..., slew=SlewModel.from_scenario(sc), revisit_zero_s=900.0,
                      prior_count=..., prior_recent=..., init_target_km=...)
    plan = solve_dp(p, budget_s=1.0)   # plan.as_list() -> [(gp_id, t_s)], plan.value
"""

from sat_node.scheduler.brute import BruteTooLarge, solve_brute
from sat_node.scheduler.dp import Plan, ScheduleInvariantError, make_plan, solve_dp
from sat_node.scheduler.nonagile import nadir_pass_crossings, solve_nonagile
from sat_node.scheduler.problem import (
    OrbitContext,
    ProblemError,
    SchedulingProblem,
    build_problem,
    evaluate_plan,
    instance_from_orbit,
    pass_starts_s,
    plan_violations,
)

__all__ = [
    "BruteTooLarge",
    "MilpResult",
    "OrbitContext",
    "Plan",
    "ProblemError",
    "ScheduleInvariantError",
    "SchedulingProblem",
    "build_problem",
    "evaluate_plan",
    "instance_from_orbit",
    "make_plan",
    "nadir_pass_crossings",
    "pass_starts_s",
    "plan_violations",
    "solve_brute",
    "solve_dp",
    "solve_milp",
    "solve_nonagile",
]


def __getattr__(name):
    # The MILP reference pulls in scipy.optimize (~50 MB per process): import it only when asked,
    # so the flight processes (one per satellite) do not carry it.
    if name in ("MilpResult", "solve_milp"):
        from sat_node.scheduler import milp

        return getattr(milp, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
