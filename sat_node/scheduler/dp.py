"""Dynamic-programming scheduler for one agile satellite (wrapper around dp_kernels).

After Nag et al., ICAPS SPARK 2019, Table 1: the graph's nodes are (time step, GP in the field of
regard); an edge joins two nodes when the slew between their pointing vectors (real positions at both
times, :mod:`sat_node.acs`) fits in the time between them; each node keeps the best accumulated value
of a path reaching it and a back-pointer; the value of a node given a predecessor is Eq. 1 *along
that predecessor's path* (a GP already on the path within 15 min is worth 0; older repeats divide by
one more) on top of the known observations (:func:`sat_node.value.prior_state`), which is how other
satellites' executed and planned observations enter (implicit consensus by satellite rank: a
satellite yields to the known plans of those that outrank it, so two satellites that know each
other's plans never both keep a GP within 15 min; ties inside the DP break by step, then GP column).

Exactness (the oracle statements the tests check):
* the value is path-dependent only through repeats of a GP on a path. When no feasible path can see a
  GP twice (every GP is worth something for less than the minimum slew time, ~5.05 s), the DP is a
  longest path in a DAG and **equals the brute-force optimum** (tests/unit/test_dp.py, tiny
  instances). Otherwise it is a heuristic that keeps one path per node: its plan is always feasible
  and its value is exactly what :func:`evaluate_plan` gives, so it is **<= the optimum**;
* against the MILP optimum (pairwise slew conflicts, tests/unit/test_milp.py) on single-satellite
  instances from the paper scenario the DP must reach >= 90 % (the study's figure);
* the same results with numba compiled and with ``NUMBA_DISABLE_JIT=1`` (subprocess test).

Anytime: with ``budget_s``, steps are processed in chunks (without one, in a single kernel call); when
it runs out the best node reached so far gives a valid plan covering the steps done
(``Plan.complete`` is False and ``Plan.steps_done`` says how far).

Cost control: predecessors older than ``w_steps`` (the largest possible slew: twice the largest
off-nadir angle plus the nadir's own rotation over the gap, by the triangle inequality) are always
reachable, so they are folded into one running best; within the window each step's nodes are scanned
in decreasing value and the scan stops when no remaining node can win. A candidate's gain is read
from per-state path tables (times each GP was seen on the path, and when last) instead of walking
its path, when states x GPs fit in ``TABLE_CELLS`` - or, for windows within the revisit window, from
one bit per GP and state (``BIT_WORDS``); the plans are the same (tests/unit/test_speed_paths.py
compares the three on instances with and without repeats).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from sat_node.acs import angle_between_deg, dot3, nadir_unit
from sat_node.scheduler import dp_kernels
from sat_node.scheduler.problem import SchedulingProblem, plan_violations

__all__ = ["Plan", "ScheduleInvariantError", "slew_window_steps", "solve_dp"]


# path tables up to 8M cells (two int32 arrays: 64 MB); the paper run's largest instance needs 1.8M
TABLE_CELLS = 8_000_000
# path bitsets (windows within the revisit window) up to 8M uint64 words (64 MB)
BIT_WORDS = 8_000_000


class ScheduleInvariantError(RuntimeError):
    """A solver returned a plan that breaks the rules (a bug, never bad input)."""


@dataclass(frozen=True)
class Plan:
    """A schedule: observations in time order (global GP ids, times [s]) and its Eq. 1 value."""

    gp_ids: np.ndarray
    t_s: np.ndarray
    steps: np.ndarray
    cols: np.ndarray
    values: np.ndarray
    value: float
    complete: bool = True
    steps_done: int = 0
    solve_s: float = 0.0

    def as_list(self) -> list[tuple[int, float]]:
        """[(gp_id, t_s)] in time order."""
        return [(int(g), float(t)) for g, t in zip(self.gp_ids, self.t_s)]

    def __len__(self) -> int:
        return len(self.steps)


def plan_value(p: SchedulingProblem, steps, cols) -> tuple[float, np.ndarray]:
    """:func:`sat_node.scheduler.problem.evaluate_plan` compiled (dp_kernels.plan_values): the same
    total and per-observation values, bit for bit (tests/unit/test_speed_paths.py)."""
    steps = np.ascontiguousarray(steps, dtype=np.int64)
    cols = np.ascontiguousarray(cols, dtype=np.int64)
    vals = dp_kernels.plan_values(p.in_for, p.prior_recent, p.absval, p.prior_count, steps, cols,
                                  float(p.step_s), float(p.revisit_zero_s))
    return float(vals.sum()), vals


def make_plan(p: SchedulingProblem, steps, cols, *, complete=True, steps_done=None, solve_s=0.0,
              values: tuple[float, np.ndarray] | None = None) -> Plan:
    """The plan of these looks on ``p``; ``values``: :func:`plan_value` of exactly these looks on
    ``p`` when the caller has it (computed otherwise)."""
    steps = np.asarray(steps, dtype=np.int64)
    cols = np.asarray(cols, dtype=np.int64)
    total, vals = plan_value(p, steps, cols) if values is None else values
    return Plan(gp_ids=p.gp_ids[cols], t_s=p.t0_s + p.step_s * steps, steps=steps, cols=cols, values=vals,
                value=total, complete=complete, steps_done=p.n_steps if steps_done is None else steps_done,
                solve_s=solve_s)


def slew_window_steps(p: SchedulingProblem, max_off_nadir_deg: float, nad: np.ndarray | None = None) -> int:
    """Smallest gap (steps) after which any slew between FOR targets fits (triangle inequality);
    ``nad``: the instance's nadir unit vectors per step, if the caller has them."""
    rate = _nadir_rate(p, nad)
    key = (p.slew, p.step_s, max_off_nadir_deg, rate)
    got = _W_STEPS.get(key)
    if got is not None:
        return got
    w = max(1, math.ceil(p.slew.min_time_s / p.step_s))
    while True:
        ang = min(180.0, 2.0 * max_off_nadir_deg + rate * w * p.step_s)
        if p.slew.time_s(ang) <= w * p.step_s:
            break
        w += 1
    if len(_W_STEPS) > 4096:
        _W_STEPS.clear()
    _W_STEPS[key] = w
    return w


# (slew model, step, largest off-nadir angle, nadir rate) -> slew_window_steps (a function of them)
_W_STEPS: dict = {}


def _nadir_rate(p: SchedulingProblem, nad: np.ndarray | None) -> float:
    """The largest rotation of nadir over one step [deg/s]; remembered in the instance, and taken
    from the parent of one derived by forbidding GPs (the same positions)."""
    rate = p._cache.get("nadir_rate")
    if rate is None:
        derived = p._cache.get("forbidden_of")
        if derived is not None:
            rate = _nadir_rate(derived[0], nad)
        else:
            nad = nadir_unit(p.sat_pos_km) if nad is None else nad
            rate = float(np.max(angle_between_deg(nad[:-1], nad[1:]))) / p.step_s if p.n_steps > 1 else 0.0
        p._cache["nadir_rate"] = rate
    return rate


_MAX_ANGLES: dict = {}


def _max_angles(slew, step_s: float, w_steps: int) -> np.ndarray:
    """``slew.max_angle_deg`` of 0..w_steps steps, remembered (a satellite's replans share them)."""
    return _slew_limits(slew, step_s, w_steps)[0]


def _slew_limits(slew, step_s: float, w_steps: int) -> tuple[np.ndarray, np.ndarray]:
    """(:func:`_max_angles`, the kernel's cosine thresholds of them), remembered together."""
    key = (slew, step_s, w_steps)
    got = _MAX_ANGLES.get(key)
    if got is None:
        if len(_MAX_ANGLES) > 64:
            _MAX_ANGLES.clear()
        a = slew.max_angle_deg(step_s * np.arange(w_steps + 1))
        # tiny safety margin so the compiled test never accepts what time_s would refuse
        cos_thr = np.where(a < 0, 2.0, np.cos(np.radians(np.maximum(a - 1e-9, 0.0))))
        a.setflags(write=False)
        cos_thr.setflags(write=False)
        got = _MAX_ANGLES[key] = (a, cos_thr)
    return got


def _states(p: SchedulingProblem):
    """The DP's states from the instance's arrays in numpy (the reference of dp_kernels.dp_states)."""
    vf = p.v_first
    ks, gs = np.nonzero(vf > 0.0)  # row-major: sorted by step then GP column
    T = p.n_steps
    t_off = np.zeros(T + 1, dtype=np.int64)
    np.cumsum(np.bincount(ks, minlength=T), out=t_off[1:])
    u = p.pointing(ks, gs) if len(ks) else np.zeros((0, 3))
    return ks.astype(np.int64), gs.astype(np.int64), np.ascontiguousarray(u), vf[ks, gs], t_off


def _prepared(p: SchedulingProblem):
    """The DP's per-state inputs of ``p`` - states (step, column) with a positive first-visit value
    in row-major order (one compiled pass, :func:`dp_kernels.dp_states`), their pointing vectors,
    values, prior counts + 1, whether the initial attitude reaches them, their off-nadir angles, and
    the nadir vectors per step - remembered in the instance.

    An instance derived from another by making some GP columns worth nothing
    (:func:`sat_node.scheduler.joint.with_forbidden`, ``_cache["forbidden_of"] = (parent, columns)``:
    the joint planner's branches) has exactly the parent's states without those columns, each with
    the same numbers: they are copied from the parent's (:func:`dp_kernels.states_without`) instead
    of being computed again (tests/unit/test_speed_paths.py compares the two). The step offsets
    are dp_states' own (the same as counting the states' steps)."""
    got = p._cache.get("dp_states")
    if got is not None:
        return got
    derived = p._cache.get("forbidden_of")
    if derived is not None:
        parent, cols = derived
        st_k, st_g, st_u, st_vf, st_n1, root_ok, off_deg, nad_t, _ = _prepared(parent)
        gone = np.zeros(p.n_gp, dtype=bool)
        gone[cols] = True
        # the kept states' numbers copied in one compiled pass (dp_kernels.states_without: what take
        # by the kept indices and bincount + cumsum of their steps give)
        st_k, st_g, st_u, st_vf, st_n1, root_ok, off_deg, t_off = dp_kernels.states_without(
            gone, p.n_steps, st_k, st_g, st_u, st_vf, st_n1, root_ok, off_deg)
    else:
        st_k, st_g, st_u, st_vf, t_off, zero = dp_kernels.dp_states(p.in_for, p.prior_recent, p.absval,
                                                                    p.prior_count, p.sat_pos_km, p.gp_ecef_km)
        if zero:
            raise ValueError("unit_vectors: zero-length vector (satellite on its target?)")
        st_n1 = (p.prior_count[st_k, st_g] + 1.0).astype(np.float64)
        t_s = p.t0_s + p.step_s * st_k
        a0 = angle_between_deg(p.init_unit[None, :], st_u)
        root_ok = p.slew.time_s(a0) <= (t_s - p.ready_t_s) + 1e-9
        nad_t = nadir_unit(p.sat_pos_km)  # per step, then per state (the same numbers, T instead of S rows)
        # np.sum(nad * st_u, axis=1) added in order (sat_node/acs.py dot3, the same numbers)
        off_deg = np.degrees(np.arccos(np.clip(dot3(nad_t[st_k], st_u), -1, 1)))
    got = p._cache["dp_states"] = (np.ascontiguousarray(st_k), np.ascontiguousarray(st_g),
                                   np.ascontiguousarray(st_u), np.ascontiguousarray(st_vf),
                                   np.ascontiguousarray(st_n1), np.ascontiguousarray(root_ok), off_deg, nad_t, t_off)
    return got


def _forward(T, budget_s, t_start, t_off, st_k, st_g, st_u, st_vf, st_n1, root_ok, cos_thr, w_steps,
             revisit_steps, V, bp, order, pref, seen_n, seen_k, seen_b, *, chunk_steps=64) -> int:
    """Run the kernel over steps 0..T-1 (in chunks of chunk_steps, checking budget_s after each; in
    one call without a budget); returns the number of steps done."""
    k = 0
    while k < T:
        k_hi = T if budget_s is None else min(T, k + chunk_steps)
        dp_kernels.dp_forward(k, k_hi, t_off, st_k, st_g, st_u, st_vf, st_n1, root_ok, cos_thr,
                              w_steps, revisit_steps, V, bp, order, pref, seen_n, seen_k, seen_b)
        k = k_hi
        if budget_s is not None and time.perf_counter() - t_start > budget_s:
            break
    return k


def solve_dp(p: SchedulingProblem, *, budget_s: float | None = None, chunk_steps: int = 64,
             check: bool = True, table_cells: int = TABLE_CELLS, bit_words: int = BIT_WORDS) -> Plan:
    """Best plan the DP finds; anytime with budget_s [s of wall time]; check: verify invariants.

    table_cells: largest states x GPs for the kernel's path tables; bit_words: largest states x
    words for its path bitsets, used when the window lies within the revisit window (beyond both: it
    walks the paths; the same plan every way)."""
    t_start = time.perf_counter()
    st_k, st_g, st_u, st_vf, st_n1, root_ok, off_deg, nad_t, t_off = _prepared(p)
    S = len(st_k)
    if S == 0:
        return make_plan(p, [], [], solve_s=time.perf_counter() - t_start)
    max_off = float(np.max(off_deg))
    w_steps = slew_window_steps(p, max_off, nad_t)
    _amax, cos_thr = _slew_limits(p.slew, p.step_s, w_steps)
    revisit_steps = p.revisit_zero_s / p.step_s
    V = np.full(S, -np.inf)
    bp = np.full(S, -2, dtype=np.int64)
    order = np.arange(S, dtype=np.int64)
    pref = np.array([-1, 0], dtype=np.int64)
    # path tables (dp_kernels): one row of G counts and G latest steps per state, when they fit
    words = (p.n_gp + 63) // 64
    within = (p.n_steps - 1) * p.step_s < p.revisit_zero_s
    bshape = (S, words) if within and S * words <= bit_words else (0, 0)
    shape = (S, p.n_gp) if bshape[0] == 0 and S * p.n_gp <= table_cells else (0, 0)
    seen_n = np.zeros(shape, dtype=np.int32)
    seen_k = np.zeros(shape, dtype=np.int32)
    seen_b = np.zeros(bshape, dtype=np.uint64)
    T = p.n_steps
    k = _forward(T, budget_s, t_start, t_off, st_k, st_g, st_u, st_vf, st_n1, root_ok, cos_thr, w_steps,
                 revisit_steps, V, bp, order, pref, seen_n, seen_k, seen_b, chunk_steps=chunk_steps)
    done = int(t_off[k])
    steps, cols = [], []
    if done > 0 and np.isfinite(V[:done]).any():
        s = int(np.argmax(V[:done]))
        best_v = float(V[s])
        while s >= 0:
            steps.append(int(st_k[s]))
            cols.append(int(st_g[s]))
            s = int(bp[s])
        steps.reverse()
        cols.reverse()
    else:
        best_v = 0.0
    values = plan_value(p, steps, cols)  # (the same numbers for the same looks: kept while no look is dropped)
    if check:
        v_dp = values[0]
        if not math.isclose(v_dp, best_v, rel_tol=1e-9, abs_tol=1e-9):
            raise ScheduleInvariantError(f"DP value {best_v} != evaluated plan value {v_dp}")
    n_looks = len(steps)
    steps, cols = drop_worthless(p, steps, cols, values[1])
    plan = make_plan(p, steps, cols, complete=k >= T, steps_done=k, solve_s=time.perf_counter() - t_start,
                     values=values if len(steps) == n_looks else None)
    if check:
        bad = plan_violations(p, plan.steps, plan.cols, rule="sequential")
        if bad:
            raise ScheduleInvariantError(f"DP plan breaks the rules: {bad[:3]}")
        if plan.value < best_v - 1e-9 * max(1.0, abs(best_v)):
            raise ScheduleInvariantError(f"DP value {best_v} > plan value {plan.value} after dropping repeats")
    return plan


def drop_worthless(p: SchedulingProblem, steps: list[int], cols: list[int],
                   vals: np.ndarray | None = None) -> tuple[list[int], list[int]]:
    """Remove observations worth 0 (repeats the DP passed through) while the plan stays feasible.

    Removing a look never lowers the later values (fewer 'times seen', an older 'last seen').
    A zero-value look is kept only when the plan needs it as a slew waypoint (the slew fit is not
    sub-additive for large angles). ``vals``: :func:`plan_value`'s per-look values of these looks
    when the caller has them.
    """
    steps, cols = list(steps), list(cols)
    changed = True
    while changed:
        changed = False
        if vals is None:
            _, vals = plan_value(p, steps, cols)
        for i in np.flatnonzero(vals <= 0.0):
            s2, c2 = steps[:i] + steps[i + 1:], cols[:i] + cols[i + 1:]
            if not plan_violations(p, s2, c2, rule="sequential"):
                steps, cols, changed, vals = s2, c2, True, None
                break
    return steps, cols
