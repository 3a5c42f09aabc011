"""Onboard scheduler: the one planner, instance building, DP (numba), brute-force and MILP oracles,
non-agile baseline.

Typical call (one satellite, one replan; the satellite and the ground segment both plan this way)::

    planner = Planner(constellation, gps.ecef_km, SlewModel.from_scenario(sc),
                      PlannerSettings.from_scenario(sc), candidates=prefilter.candidate_gp_ids)
    plan = planner.plan("sat_11", t0_s, window_s,
                        Knowledge(PersistenceView(osse, t0_s), known, belief))
    plan.as_list()   # -> [(gp_id, t_s)], plan.value

or, from arrays: ``solve_dp(build_problem(t0_s=..., step_s=1.0, sat_pos_km=..., ...))``.
"""

from sat_node.scheduler.brute import BruteTooLarge, solve_brute, solve_brute_joint
from sat_node.scheduler.dp import Plan, ScheduleInvariantError, make_plan, solve_dp
from sat_node.scheduler.joint import JointResult, joint_value, solve_joint
from sat_node.scheduler.nonagile import nadir_pass_crossings, solve_nonagile
from sat_node.scheduler.planner import (
    SOLVERS,
    Knowledge,
    PersistenceView,
    Planner,
    PlannerSettings,
    ValueSource,
)
from sat_node.scheduler.problem import (
    ProblemError,
    SchedulingProblem,
    build_problem,
    evaluate_plan,
    plan_violations,
)

__all__ = [
    "SOLVERS",
    "BruteTooLarge",
    "JointResult",
    "Knowledge",
    "MilpResult",
    "PersistenceView",
    "Plan",
    "Planner",
    "PlannerSettings",
    "ProblemError",
    "ScheduleInvariantError",
    "SchedulingProblem",
    "ValueSource",
    "build_problem",
    "evaluate_plan",
    "make_plan",
    "nadir_pass_crossings",
    "plan_violations",
    "joint_value",
    "solve_brute",
    "solve_brute_joint",
    "solve_dp",
    "solve_joint",
    "solve_milp",
    "solve_milp_joint",
    "solve_nonagile",
]


def __getattr__(name):
    # The MILP reference pulls in scipy.optimize (~50 MB per process, ~0.21 s to import measured
    # with python -X importtime): import it only when asked, so the flight processes (one per
    # satellite) do not carry it.
    if name in ("MilpResult", "solve_milp", "solve_milp_joint"):
        from sat_node.scheduler import milp

        return getattr(milp, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
