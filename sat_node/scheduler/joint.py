"""Joint planning of satellites whose fields of regard overlap (Nag et al., ICAPS SPARK 2019, Table 1,
lines 9-20: the DP considers the satellites with overlapping FOR, ``satsWoverlappingFOR``, together).

A group is one :class:`~sat_node.scheduler.problem.SchedulingProblem` per satellite, built from the
same knowledge (the planner that plans the group predicts the others with what it knows); members'
windows may start at different times. When the group's windows span no more than
``revisit_zero_s`` a GP is worth something once for the whole group - at its first look; any later
look within 15 min is worth 0 - so the joint problem is: one feasible path per satellite, no GP on
two paths, maximum total value. It is solved by branch and bound over who
takes a contested GP:

* a node forbids some GPs to some satellites (their value is 0 there) and solves each satellite's
  DP (:func:`~sat_node.scheduler.dp.solve_dp`) alone; the sum of the values bounds every plan below
  the node (each satellite's DP is the best it can do with those GPs, when the DP is exact);
* if no GP is on two plans, the plans are a joint plan of exactly that value (the incumbent);
* else the contested GP worth most is given, in one child per satellite that can see it, to that
  satellite alone (every complete assignment lies below one of the children);
* nodes are taken best bound first, pruned when their bound does not beat the incumbent; a greedy
  dive first (every contested GP to the satellite that looks at it first, until nothing is
  contested) gives the incumbent the search must beat, and the plans when the budget of DP solves
  runs out.

For longer spans (the ground's plans reach to the next pass) a GP can be worth something twice,
15 min apart: there the dive alone runs, for at most ``DIVE_ROUNDS_LONG`` rounds, and a contested
look becomes a claim (the winner's look as a plan that outranks, :func:`sat_node.value.prior_state`)
that zeroes the GP only within 15 min of it; looks still contested after the last round are worth
0 in the joint value (the plans stay feasible).

Exactness (the oracle statements the tests check, tests/unit/test_joint.py): when every satellite's
DP is exact (no satellite can see a GP twice in the window, as in dp.py) and the budget is not
exhausted, the result equals the exhaustive optimum of every pair of feasible plans
(:func:`sat_node.scheduler.brute.solve_brute_joint`); on two-satellite instances cut from the paper
scenario it reaches >= 90 % of the joint MILP (:func:`sat_node.scheduler.milp.solve_milp_joint`);
its reported value always equals :func:`joint_value` of its plans.
"""

from __future__ import annotations

import dataclasses
import heapq
import itertools
import math
from dataclasses import dataclass

import numpy as np

from sat_node.scheduler.dp import Plan, ScheduleInvariantError, make_plan, solve_dp
from sat_node.scheduler.joint_kernels import group_value
from sat_node.scheduler.problem import SchedulingProblem
from sat_node.value import KnownObservation, prior_state

__all__ = ["JointResult", "group_span_s", "joint_value", "solve_joint", "with_claims", "with_forbidden"]

CLAIM_SOURCE = ""  # sorts before every satellite name: a claim outranks the satellite it is put on
DIVE_ROUNDS = 16  # rounds of the greedy dive (a round re-solves the satellites that lost a contest)
DIVE_ROUNDS_LONG = 4  # for long spans (the ground's: a satellite's plan to its next pass costs ~0.2-0.5 s)


@dataclass(frozen=True)
class JointResult:
    """One plan per group member (in the group's order), their joint Eq. 1 value, whether the search
    finished (``exact``: the branch and bound closed within its budget), and DP solves spent."""

    plans: list[Plan]
    value: float
    exact: bool
    dp_solves: int


def with_forbidden(p: SchedulingProblem, gp_ids) -> SchedulingProblem:
    """``p`` with the GPs ``gp_ids`` (global ids) worth nothing."""
    cols = np.flatnonzero(np.isin(p.gp_ids, np.asarray(list(gp_ids), np.int64)))
    if len(cols) == 0:
        return p
    a = p.absval.copy()
    a[:, cols] = 0.0
    # the DP takes this instance's states from p's (sat_node/scheduler/dp.py _prepared)
    return dataclasses.replace(p, absval=a, _cache={"forbidden_of": (p, cols)})


def with_claims(p: SchedulingProblem, claims) -> SchedulingProblem:
    """``p`` with other satellites' looks ``claims`` [(gp_id, t_s)] as plans that outrank it: the GP
    is worth 0 within revisit_zero_s of a claim and counts as seen after it (Eq. 1)."""
    known = [KnownObservation(float(t), int(g), CLAIM_SOURCE, planned=True) for g, t in claims]
    if not known:
        return p
    count, recent = prior_state(known, p.gp_ids, p.times_s, p.sat_name or "~", p.revisit_zero_s)
    return dataclasses.replace(p, prior_count=p.prior_count + count, prior_recent=p.prior_recent | recent, _cache={})


def group_span_s(problems: list[SchedulingProblem]) -> float:
    """From the first member's window start to the last member's window end [s]."""
    return max(p.t0_s + p.horizon_s for p in problems) - min(p.t0_s for p in problems)


def joint_value(problems: list[SchedulingProblem], plans: list[Plan]) -> float:
    """Eq. 1 over every look of every plan in time order (ties: group order), each valued with its
    own satellite's instance: 0 within revisit_zero_s of an earlier look of the group (or of a known
    recent one), else absval / (known before + group looks before + 1). Summed on arrays
    (sat_node/scheduler/joint_kernels.py ``group_value``: the same float as the loop over the looks)."""
    return group_value(problems, plans)


def _contested(problems, plans) -> dict[int, list[tuple[float, int]]]:
    """GP id -> [(look time, member)] for GPs on two plans within revisit_zero_s of each other."""
    looks: dict[int, list[tuple[float, int]]] = {}
    for i, (p, pl) in enumerate(zip(problems, plans)):
        for g, t in zip(pl.gp_ids, pl.t_s):
            looks.setdefault(int(g), []).append((float(t), i))
    r = problems[0].revisit_zero_s
    out = {}
    for g, ls in looks.items():
        if len({i for _, i in ls}) < 2:
            continue
        ls.sort()
        if any(b[1] != a[1] and b[0] - a[0] < r for a, b in itertools.pairwise(ls)):
            out[g] = ls
    return out


class _Solver:
    def __init__(self, problems: list[SchedulingProblem], budget: int):
        self.problems = problems
        self.budget = budget
        self.solves = 0
        self._memo: dict[tuple[int, frozenset], Plan] = {}

    def dp(self, i: int, forbidden: frozenset) -> Plan:
        key = (i, forbidden)
        pl = self._memo.get(key)
        if pl is None:
            self.solves += 1
            pl = self._memo[key] = solve_dp(with_forbidden(self.problems[i], forbidden), check=True)
        return pl

    def node(self, forb: tuple[frozenset, ...]) -> list[Plan]:
        return [self.dp(i, f) for i, f in enumerate(forb)]


def _visible(p: SchedulingProblem) -> set[int]:
    return {int(g) for g in p.gp_ids[np.flatnonzero((p.v_first > 0).any(axis=0))]}


def solve_joint(problems: list[SchedulingProblem], *, budget_solves: int = 64, check: bool = True) -> JointResult:
    """The group's plans (module docstring); ``budget_solves``: most DP solves spent searching."""
    if not problems:
        return JointResult([], 0.0, True, 0)
    if len(problems) == 1:
        pl = solve_dp(problems[0], check=check)
        return JointResult([pl], pl.value, True, 1)
    short = group_span_s(problems) <= problems[0].revisit_zero_s + 1e-9
    if not short:
        plans, solves = _dive_claims(problems, check)
        return _result(problems, plans, False, solves, check)
    s = _Solver(problems, budget_solves)
    visible: list[set[int]] = []  # (made when the search first branches)
    # the greedy dive: contested GPs to the first look, until nothing is contested
    forb = tuple(frozenset() for _ in problems)
    for _ in range(DIVE_ROUNDS):
        plans = s.node(forb)
        cont = _contested(problems, plans)
        if not cont:
            break
        f = [set(x) for x in forb]
        for g, ls in cont.items():
            winner = ls[0][1]
            for i in range(len(problems)):
                if i != winner:
                    f[i].add(g)
        forb = tuple(frozenset(x) for x in f)
    best_plans = plans  # (after 16 rounds still contested: the later looks are worth 0, the plans stand)
    best = joint_value(problems, plans)
    # best-first branch and bound from the root
    root = tuple(frozenset() for _ in problems)
    heap = [(-sum(pl.value for pl in s.node(root)), 0, root)]
    seq = 1
    exact = True
    seen = {root}
    while heap:
        neg_ub, _, f = heapq.heappop(heap)
        if -neg_ub <= best + 1e-9:
            break
        if s.solves >= budget_solves:
            exact = False
            break
        plans = s.node(f)
        ub = sum(pl.value for pl in plans)
        if ub <= best + 1e-9:
            continue
        cont = _contested(problems, plans)
        if not cont:
            best, best_plans = ub, plans  # conflict-free: its value is the sum
            continue
        g = max(cont, key=lambda x: max(plans[i].values[list(plans[i].gp_ids).index(x)] for _, i in cont[x]))
        visible = visible or [_visible(p) for p in problems]
        for m in range(len(problems)):
            if g not in visible[m]:
                continue
            child = tuple(fi | {g} if i != m else fi for i, fi in enumerate(f))
            if child in seen:
                continue
            seen.add(child)
            cub = sum(pl.value for pl in s.node(child)) if s.solves < budget_solves else ub
            if cub > best + 1e-9:
                heapq.heappush(heap, (-cub, seq, child))
                seq += 1
    return _result(problems, best_plans, exact, s.solves, check)


def _dive_claims(problems, check: bool) -> tuple[list[Plan], int]:
    """Longer windows: contested looks become claims of the first look on the others, until none."""
    claims: list[list[tuple[int, float]]] = [[] for _ in problems]
    plans = [solve_dp(p, check=check) for p in problems]
    solves = len(problems)
    for _ in range(DIVE_ROUNDS_LONG):
        cont = _contested(problems, plans)
        if not cont:
            break
        changed = set()
        for g, ls in cont.items():
            t_win, winner = ls[0]
            for _t, i in ls[1:]:
                if i != winner and (g, t_win) not in claims[i]:
                    claims[i].append((g, t_win))
                    changed.add(i)
        if not changed:
            break
        for i in changed:
            plans[i] = solve_dp(with_claims(problems[i], claims[i]), check=check)
            solves += 1
    return plans, solves


def _result(problems, plans, exact: bool, solves: int, check: bool) -> JointResult:
    # each plan re-made on its satellite's own instance (values as that satellite believes them)
    out = [make_plan(p, pl.steps, pl.cols, solve_s=pl.solve_s) for p, pl in zip(problems, plans)]
    value = joint_value(problems, out)
    if check and not math.isfinite(value):
        raise ScheduleInvariantError(f"joint value {value} is not finite")
    return JointResult(out, value, exact, solves)
