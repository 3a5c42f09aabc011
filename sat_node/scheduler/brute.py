"""Exhaustive oracle for tiny single-satellite instances (test-only in spirit, kept in the package).

Enumerates every plan - every increasing sequence of candidate observations (step, GP) whose
first-visit value is positive - that satisfies the feasibility rule of
:func:`sat_node.scheduler.problem.plan_violations` ("sequential": consecutive slews fit, as the
satellite executes; "pairwise": every pair fits, as the MILP models it), and returns the best by
the exact path-dependent Eq. 1 (:func:`evaluate_plan`). Depth-first with no pruning beyond
feasibility, so it is obviously right and only usable for a few dozen candidates.

:func:`solve_brute_joint` does the same for a group of satellites planned together (joint.py): every
combination of one feasible plan per satellite, valued by the group's Eq. 1
(:func:`sat_node.scheduler.joint.joint_value`).

How we know it is right: it is the definition; tests/unit/test_dp.py also checks it against a
hand-enumerated 3-candidate instance, tests/unit/test_joint.py the joint one against a hand-worked
two-satellite case.
"""

from __future__ import annotations

import numpy as np

from sat_node.acs import angle_between_deg
from sat_node.scheduler.dp import Plan, make_plan
from sat_node.scheduler.joint import joint_value
from sat_node.scheduler.problem import SchedulingProblem, evaluate_plan

__all__ = ["BruteTooLarge", "feasible_plans", "solve_brute", "solve_brute_joint"]


class BruteTooLarge(ValueError):
    """The instance has too many candidates or plans for exhaustive search."""


def solve_brute(p: SchedulingProblem, *, rule: str = "sequential", max_candidates: int = 60,
                max_nodes: int = 2_000_000) -> Plan:
    """The optimum plan by exhaustive search (ties: the fewest observations, then the first found)."""
    if rule not in ("sequential", "pairwise"):
        raise ValueError(f"solve_brute: rule must be 'sequential' or 'pairwise', got {rule!r}")
    ks, gs = np.nonzero(p.v_first > 0.0)
    n = len(ks)
    if n > max_candidates:
        raise BruteTooLarge(f"solve_brute: {n} candidates > max_candidates={max_candidates}")
    if n == 0:
        return make_plan(p, [], [])
    u = p.pointing(ks, gs)
    t = p.t0_s + p.step_s * ks
    need = p.slew.time_s(angle_between_deg(u[:, None, :], u[None, :, :]))
    ok = (t[None, :] - t[:, None] + 1e-9 >= need) & (ks[None, :] > ks[:, None])  # ok[i, j]: i then j
    root = p.slew.time_s(angle_between_deg(p.init_unit[None, :], u)) <= t - p.ready_t_s + 1e-9
    best = [-1.0, []]
    nodes = [0]

    def dfs(seq: list[int]) -> None:
        nodes[0] += 1
        if nodes[0] > max_nodes:
            raise BruteTooLarge(f"solve_brute: more than max_nodes={max_nodes} plans")
        v, _ = evaluate_plan(p, ks[seq], gs[seq])
        if v > best[0] + 1e-9 or (v > best[0] - 1e-9 and len(seq) < len(best[1])):
            best[0], best[1] = v, list(seq)
        start = seq[-1] + 1 if seq else 0
        for j in range(start, n):
            if seq:
                if rule == "sequential":
                    if not ok[seq[-1], j]:
                        continue
                elif not all(ok[i, j] for i in seq):
                    continue
            if not root[j] and (rule == "pairwise" or not seq):
                continue
            dfs(seq + [j])

    dfs([])
    seq = best[1]
    return make_plan(p, ks[seq], gs[seq])


def feasible_plans(p: SchedulingProblem, *, max_candidates: int = 30, max_plans: int = 200_000):
    """Every plan (steps, cols) feasible by the sequential rule over the candidates with a positive
    first-visit value, the empty plan first."""
    ks, gs = np.nonzero(p.v_first > 0.0)
    n = len(ks)
    if n > max_candidates:
        raise BruteTooLarge(f"feasible_plans: {n} candidates > max_candidates={max_candidates}")
    if n == 0:
        return [(np.zeros(0, np.int64), np.zeros(0, np.int64))]
    u = p.pointing(ks, gs)
    t = p.t0_s + p.step_s * ks
    need = p.slew.time_s(angle_between_deg(u[:, None, :], u[None, :, :]))
    ok = (t[None, :] - t[:, None] + 1e-9 >= need) & (ks[None, :] > ks[:, None])
    root = p.slew.time_s(angle_between_deg(p.init_unit[None, :], u)) <= t - p.ready_t_s + 1e-9
    out = []

    def dfs(seq: list[int]) -> None:
        if len(out) >= max_plans:
            raise BruteTooLarge(f"feasible_plans: more than max_plans={max_plans}")
        out.append((ks[seq], gs[seq]))
        start = seq[-1] + 1 if seq else 0
        for j in range(start, n):
            if (seq and not ok[seq[-1], j]) or (not seq and not root[j]):
                continue
            dfs(seq + [j])

    dfs([])
    return out


def solve_brute_joint(problems: list[SchedulingProblem], **kw) -> tuple[list[Plan], float]:
    """The optimum of a group by exhaustive search over one feasible plan per satellite (ties: the
    first found); returns (plans, joint value)."""
    options = [[make_plan(p, s, c) for s, c in feasible_plans(p, **kw)] for p in problems]
    best_v, best = -1.0, None

    def rec(i: int, chosen: list) -> None:
        nonlocal best_v, best
        if i == len(problems):
            v = joint_value(problems, chosen)
            if v > best_v + 1e-9:
                best_v, best = v, list(chosen)
            return
        for pl in options[i]:
            rec(i + 1, chosen + [pl])

    rec(0, [])
    return best, best_v
