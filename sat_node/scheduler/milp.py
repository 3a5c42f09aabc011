"""Exact reference optimum for small single-satellite instances: a time-indexed MILP (HiGHS).

Formulation (the classic time-indexed agile-EOS model, e.g. Lemaitre et al. 2002):
binary ``x[k, g]`` for every candidate observation (step k, GP g) with positive first-visit value
reachable from the initial attitude; maximize ``sum v_first[k, g] x[k, g]`` subject to

* one observation per step: ``sum_g x[k, g] <= 1``;
* each GP counted once: ``sum_k x[k, g] <= 1`` (exact Eq. 1 when the window is no longer than
  ``revisit_zero_s``, since any repeat is then worth 0; longer windows raise NotImplementedError);
* pairwise slew conflicts: for (k, g) and (k', g') with ``0 < k' - k`` and the gap shorter than the
  slew between them, ``x[k, g] + x[k', g'] <= 1``. Because at most one observation is taken per
  step, all conflicts of (k, g) with step k' are aggregated into one valid row
  ``x[k, g] + sum_{g' in C} x[k', g'] <= 1`` (same integer set, tighter LP).

Solved with ``scipy.optimize.milp`` (HiGHS branch and cut). Pairwise feasibility is slightly
stricter than the sequential rule the satellite executes (the slew fit is not sub-additive above
~35 deg + 35 deg), so the DP may occasionally exceed this "optimum"; see problem.py.

:func:`solve_milp_joint` is the same for a group of satellites planned together (one row per GP
over the group; tests/unit/test_joint.py: equal to the exhaustive joint optimum on tiny groups).

How we know it is right (tests/unit/test_milp.py): equal to the exhaustive
``solve_brute(rule="pairwise")`` on tiny instances; its plan passes ``plan_violations(rule="pairwise")``
and its objective equals :func:`evaluate_plan` of its plan.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.optimize import Bounds, LinearConstraint, milp

from sat_node.acs import angle_between_deg, nadir_unit
from sat_node.scheduler.dp import Plan, ScheduleInvariantError, make_plan, slew_window_steps
from sat_node.scheduler.problem import SchedulingProblem, plan_violations

__all__ = ["MilpResult", "solve_milp", "solve_milp_joint"]


@dataclass(frozen=True)
class MilpResult:
    plan: Plan
    optimal: bool
    objective: float
    dual_bound: float
    n_vars: int
    n_rows: int
    solve_s: float
    message: str


def _conflict_rows(p: SchedulingProblem, ks: np.ndarray, u: np.ndarray) -> list[np.ndarray]:
    """Aggregated pairwise slew conflicts of the candidates (steps ``ks``, pointing ``u``): each row
    is one candidate and every candidate of one later step it cannot reach (columns into ``ks``)."""
    out = []
    nad = nadir_unit(p.sat_pos_km[ks])
    max_off = float(np.max(np.degrees(np.arccos(np.clip(np.sum(nad * u, axis=1), -1, 1)))))
    w = slew_window_steps(p, max_off)
    starts = {int(k): np.nonzero(ks == k)[0] for k in np.unique(ks)}
    for k, idx in starts.items():
        for dk in range(1, w):
            idx2 = starts.get(k + dk)
            if idx2 is None:
                continue
            need = p.slew.time_s(angle_between_deg(u[idx][:, None, :], u[idx2][None, :, :]))
            conf = need > dk * p.step_s + 1e-9
            for a in np.nonzero(conf.any(axis=1))[0]:
                out.append(np.concatenate([[idx[a]], idx2[conf[a]]]))
    return out


def solve_milp_joint(problems: list[SchedulingProblem], *, time_limit_s: float | None = 60.0) -> tuple[list[Plan], float, bool]:
    """The joint optimum of a group of satellites (sat_node/scheduler/joint.py) as one MILP: each
    satellite's variables and rows as :func:`solve_milp`, and one row per GP over every satellite
    (the GP counts once for the group within revisit_zero_s). Returns (plans, objective, optimal)."""
    span = max(p.t0_s + p.horizon_s for p in problems) - min(p.t0_s for p in problems)
    if span > problems[0].revisit_zero_s + 1e-9:
        raise NotImplementedError("solve_milp_joint: groups spanning more than revisit_zero_s are not modelled")
    blocks = []
    off = 0
    for p in problems:
        vf = p.v_first
        ks, gs = np.nonzero(vf > 0.0)
        u = p.pointing(ks, gs) if len(ks) else np.zeros((0, 3))
        t = p.t0_s + p.step_s * ks
        if len(ks):
            root = p.slew.time_s(angle_between_deg(p.init_unit[None, :], u)) <= t - p.ready_t_s + 1e-9
            ks, gs, u = ks[root], gs[root], u[root]
        blocks.append((p, ks, gs, u, off))
        off += len(ks)
    n = off
    if n == 0:
        return [make_plan(p, [], []) for p in problems], 0.0, True
    c = np.concatenate([-b[0].v_first[b[1], b[2]] for b in blocks])
    rows, cols = [], []
    r = 0
    by_gp: dict[int, list[int]] = {}
    for p, ks, gs, u, o in blocks:
        for k in np.unique(ks):
            idx = np.nonzero(ks == k)[0] + o
            rows.append(np.full(len(idx), r))
            cols.append(idx)
            r += 1
        for j, g in enumerate(p.gp_ids[gs]):
            by_gp.setdefault(int(g), []).append(o + j)
        if len(ks):
            for cs in _conflict_rows(p, ks, u):
                rows.append(np.full(len(cs), r))
                cols.append(cs + o)
                r += 1
    for idx in by_gp.values():
        if len(idx) > 1:
            rows.append(np.full(len(idx), r))
            cols.append(np.asarray(idx))
            r += 1
    A = sparse.csr_array((np.ones(sum(len(x) for x in rows)), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(r, n))
    opts = {"disp": False}
    if time_limit_s is not None:
        opts["time_limit"] = float(time_limit_s)
    res = milp(c, constraints=LinearConstraint(A, -np.inf, 1.0), integrality=np.ones(n), bounds=Bounds(0, 1),
               options=opts)
    if res.x is None:
        raise ScheduleInvariantError(f"solve_milp_joint: HiGHS returned no solution ({res.message})")
    plans = []
    for p, ks, gs, _u, o in blocks:
        sel = np.nonzero(res.x[o:o + len(ks)] > 0.5)[0]
        sel = sel[np.argsort(ks[sel], kind="stable")]
        plans.append(make_plan(p, ks[sel], gs[sel]))
    return plans, float(-res.fun), res.status == 0


def solve_milp(p: SchedulingProblem, *, time_limit_s: float | None = 60.0, check: bool = True) -> MilpResult:
    """Solve the time-indexed MILP; ``optimal`` False when the time limit stopped HiGHS."""
    t_start = time.perf_counter()
    if p.horizon_s > p.revisit_zero_s + 1e-9:
        raise NotImplementedError(
            f"solve_milp: window {p.horizon_s} s longer than revisit_zero_s {p.revisit_zero_s} s "
            "(path-dependent repeat values are not modelled)")
    vf = p.v_first
    ks, gs = np.nonzero(vf > 0.0)
    u = p.pointing(ks, gs) if len(ks) else np.zeros((0, 3))
    t = p.t0_s + p.step_s * ks
    root = p.slew.time_s(angle_between_deg(p.init_unit[None, :], u)) <= t - p.ready_t_s + 1e-9 \
        if len(ks) else np.zeros(0, bool)
    ks, gs, u = ks[root], gs[root], u[root]
    n = len(ks)
    if n == 0:
        return MilpResult(make_plan(p, [], []), True, 0.0, 0.0, 0, 0, time.perf_counter() - t_start, "empty")
    c = -vf[ks, gs]
    rows, cols = [], []
    r = 0
    # one per step
    for k in np.unique(ks):
        idx = np.nonzero(ks == k)[0]
        rows.append(np.full(len(idx), r))
        cols.append(idx)
        r += 1
    for g in np.unique(gs):
        idx = np.nonzero(gs == g)[0]
        if len(idx) > 1:
            rows.append(np.full(len(idx), r))
            cols.append(idx)
            r += 1
    # aggregated pairwise conflicts
    for cs in _conflict_rows(p, ks, u):
        rows.append(np.full(len(cs), r))
        cols.append(cs)
        r += 1
    rr = np.concatenate(rows)
    cc = np.concatenate(cols)
    A = sparse.csr_array((np.ones(len(rr)), (rr, cc)), shape=(r, n))
    opts = {"disp": False}
    if time_limit_s is not None:
        opts["time_limit"] = float(time_limit_s)
    res = milp(c, constraints=LinearConstraint(A, -np.inf, 1.0), integrality=np.ones(n),
               bounds=Bounds(0, 1), options=opts)
    if res.x is None:
        raise ScheduleInvariantError(f"solve_milp: HiGHS returned no solution ({res.message})")
    sel = np.nonzero(res.x > 0.5)[0]
    order = np.argsort(ks[sel], kind="stable")
    sel = sel[order]
    plan = make_plan(p, ks[sel], gs[sel], solve_s=time.perf_counter() - t_start)
    obj = float(-res.fun)
    bound = float(-getattr(res, "mip_dual_bound", res.fun)) if getattr(res, "mip_dual_bound", None) is not None \
        else obj
    if check:
        bad = plan_violations(p, plan.steps, plan.cols, rule="pairwise")
        if bad:
            raise ScheduleInvariantError(f"MILP plan breaks the rules: {bad[:3]}")
        if abs(plan.value - obj) > 1e-6 * max(1.0, abs(obj)):
            raise ScheduleInvariantError(f"MILP objective {obj} != evaluated plan value {plan.value}")
    return MilpResult(plan=plan, optimal=res.status == 0, objective=obj, dual_bound=bound, n_vars=n,
                      n_rows=r, solve_s=time.perf_counter() - t_start, message=str(res.message))
