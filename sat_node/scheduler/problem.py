"""One satellite's scheduling instance on a time grid, and the exact evaluation of a plan.

An instance (Nag et al., ICAPS SPARK 2019, Table 1 / docs/design.md section 1) is everything one satellite
needs to choose where to point over ``[t0_s, t0_s + n_steps * step_s)``: its ECEF positions on the
grid, the GP ECEF vectors, which GP is inside the field of regard (FOR) at each step, the believed
absolute value per (step, GP), what it knows was (or will be, by other satellites) observed before
each step, and its attitude at the start. The instance is plain numpy;
:class:`sat_node.scheduler.planner.Planner` builds it from the orbits, the field of regard
(:func:`orbit_clock.access.for_mask`) and what the planner knows.

Semantics shared by every solver here (DP, brute force, MILP, non-agile), implemented once in
:func:`evaluate_plan` and :func:`plan_violations`:

* a plan is a list of observations ``(step, GP column)`` with strictly increasing steps (at most one
  observation per step, taken instantaneously at the step time);
* each observation must have its GP in the FOR at its step;
* *sequential* feasibility (what the satellite executes): the first observation is reachable from
  the initial pointing (``init_unit`` at ``ready_t_s``) and each consecutive pair leaves at least the
  slew time of the angle between the two satellite-to-GP vectors (real positions at both times);
  *pairwise* feasibility (the MILP's time-indexed formulation) asks it of every pair. The slew fit is
  not sub-additive for large angles, so pairwise is (rarely) stricter than sequential;
* value: Eq. 1 along the plan, counting the known observations (``prior_count``/``prior_recent``)
  and the plan's own earlier observations of the same GP.

How we know it is right (tests/unit/test_dp.py): the evaluation against a hand-computed three-
observation plan, and every solver's reported value equals :func:`evaluate_plan` of its plan.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from sat_node.acs import SlewModel, angle_between_deg, nadir_unit, unit_vectors

__all__ = [
    "ProblemError",
    "SchedulingProblem",
    "build_problem",
    "evaluate_plan",
    "plan_violations",
]


class ProblemError(ValueError):
    """An instance that cannot be scheduled (message names the array and what is wrong)."""


@dataclass(frozen=True, eq=False)
class SchedulingProblem:
    """A single-satellite instance; build it with :func:`build_problem` (which validates)."""

    t0_s: float
    step_s: float
    sat_pos_km: np.ndarray  # (T, 3) ECEF
    gp_ecef_km: np.ndarray  # (G, 3) ECEF
    gp_ids: np.ndarray  # (G,) global GP ids
    in_for: np.ndarray  # (T, G) bool
    absval: np.ndarray  # (T, G) believed absolute value (>= 0)
    prior_count: np.ndarray  # (T, G) known observations before each step
    prior_recent: np.ndarray  # (T, G) one of them within revisit_zero_s
    init_unit: np.ndarray  # (3,) pointing at t0 (unit, ECEF)
    ready_t_s: float
    slew: SlewModel
    revisit_zero_s: float
    sat_name: str = ""
    _cache: dict = field(default_factory=dict, repr=False)

    @property
    def n_steps(self) -> int:
        return int(self.sat_pos_km.shape[0])

    @property
    def n_gp(self) -> int:
        return int(self.gp_ecef_km.shape[0])

    @property
    def times_s(self) -> np.ndarray:
        return self.t0_s + self.step_s * np.arange(self.n_steps)

    @property
    def horizon_s(self) -> float:
        return self.n_steps * self.step_s

    @property
    def v_first(self) -> np.ndarray:
        """(T, G) value of a GP at a step if the plan has not observed it before (0 outside FOR)."""
        v = self._cache.get("v_first")
        if v is None:
            v = np.where(self.in_for & ~self.prior_recent, self.absval / (self.prior_count + 1.0), 0.0)
            self._cache["v_first"] = v
        return v

    def pointing(self, steps: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """Unit satellite-to-GP vectors (K, 3) for observations (step, column)."""
        return unit_vectors(self.gp_ecef_km[cols] - self.sat_pos_km[steps])


def build_problem(*, t0_s: float, step_s: float, sat_pos_km, gp_ecef_km, in_for, absval,
                  slew: SlewModel, revisit_zero_s: float, gp_ids=None, prior_count=None,
                  prior_recent=None, init_target_km=None, init_sat_pos_km=None,
                  ready_t_s: float | None = None, sat_name: str = "") -> SchedulingProblem:
    """Validate arrays and make an instance.

    absval may be (T, G) or (G,) (constant over the window). init_target_km: the ECEF point the
    satellite points at when the window starts (None: nadir), seen from init_sat_pos_km (default:
    its first position). ready_t_s: when the satellite can start slewing (default t0_s; e.g. the
    time of its last observation, with init_sat_pos_km its position then). prior_count/prior_recent: from :func:`sat_node.value.prior_state`
    (default: nothing known).
    """
    sat = np.ascontiguousarray(sat_pos_km, dtype=np.float64)
    gp = np.ascontiguousarray(gp_ecef_km, dtype=np.float64)
    if sat.ndim != 2 or sat.shape[1] != 3 or sat.shape[0] < 1:
        raise ProblemError(f"sat_pos_km: need shape (T>=1, 3), got {sat.shape}")
    if gp.ndim != 2 or gp.shape[1] != 3:
        raise ProblemError(f"gp_ecef_km: need shape (G, 3), got {gp.shape}")
    T, G = sat.shape[0], gp.shape[0]
    if not (np.all(np.isfinite(sat)) and np.all(np.isfinite(gp))):
        raise ProblemError("sat_pos_km/gp_ecef_km: non-finite coordinates")
    if not (step_s > 0 and math.isfinite(step_s)):
        raise ProblemError(f"step_s: must be > 0, got {step_s}")
    m = np.asarray(in_for)
    if m.shape != (T, G):
        raise ProblemError(f"in_for: need shape {(T, G)}, got {m.shape}")
    a = np.asarray(absval, dtype=np.float64)
    if a.shape == (G,):
        a = np.broadcast_to(a, (T, G))
    if a.shape != (T, G):
        raise ProblemError(f"absval: need shape {(T, G)} or {(G,)}, got {a.shape}")
    if not np.all(np.isfinite(a)) or np.any(a < 0):
        raise ProblemError("absval: values must be finite and >= 0")
    ids = np.arange(G, dtype=np.int64) if gp_ids is None else np.asarray(gp_ids, dtype=np.int64)
    if ids.shape != (G,) or not (np.all(ids[1:] > ids[:-1]) or len(np.unique(ids)) == G):
        raise ProblemError(f"gp_ids: need {G} distinct ids, got shape {ids.shape}")
    pc = np.zeros((T, G), np.int64) if prior_count is None else np.asarray(prior_count, np.int64)
    pr = np.zeros((T, G), bool) if prior_recent is None else np.asarray(prior_recent, bool)
    if pc.shape != (T, G) or pr.shape != (T, G):
        raise ProblemError(f"prior_count/prior_recent: need shape {(T, G)}, got {pc.shape}/{pr.shape}")
    if np.any(pc < 0):
        raise ProblemError("prior_count: must be >= 0")
    if init_target_km is None:
        u0 = nadir_unit(sat[0])
    else:
        tgt = np.asarray(init_target_km, np.float64)
        if tgt.shape != (3,):
            raise ProblemError(f"init_target_km: need shape (3,), got {tgt.shape}")
        origin = sat[0] if init_sat_pos_km is None else np.asarray(init_sat_pos_km, np.float64)
        if origin.shape != (3,):
            raise ProblemError(f"init_sat_pos_km: need shape (3,), got {origin.shape}")
        u0 = unit_vectors(tgt - origin)
    if revisit_zero_s < 0:
        raise ProblemError(f"revisit_zero_s: must be >= 0, got {revisit_zero_s}")
    return SchedulingProblem(
        t0_s=float(t0_s), step_s=float(step_s), sat_pos_km=sat, gp_ecef_km=gp, gp_ids=ids,
        in_for=np.ascontiguousarray(m, dtype=bool), absval=np.ascontiguousarray(a),
        prior_count=np.ascontiguousarray(pc), prior_recent=np.ascontiguousarray(pr), init_unit=u0,
        ready_t_s=float(t0_s if ready_t_s is None else ready_t_s), slew=slew,
        revisit_zero_s=float(revisit_zero_s), sat_name=sat_name)


def evaluate_plan(p: SchedulingProblem, steps, cols) -> tuple[float, np.ndarray]:
    """Exact Eq. 1 value of a plan (total, per observation); steps must be increasing."""
    steps = np.asarray(steps, dtype=np.int64)
    cols = np.asarray(cols, dtype=np.int64)
    vals = np.zeros(len(steps))
    seen: dict[int, list[int]] = {}
    for i, (k, j) in enumerate(zip(steps, cols)):
        own = seen.setdefault(int(j), [])
        if not p.in_for[k, j] or p.prior_recent[k, j] or any((k - kk) * p.step_s < p.revisit_zero_s for kk in own):
            v = 0.0
        else:
            v = p.absval[k, j] / (p.prior_count[k, j] + len(own) + 1.0)
        vals[i] = v
        own.append(int(k))
    return float(vals.sum()), vals


def plan_violations(p: SchedulingProblem, steps, cols, rule: str = "sequential",
                    tol_s: float = 1e-9) -> list[str]:
    """Human-readable violations of the plan rules (empty list: valid). rule: sequential|pairwise."""
    if rule not in ("sequential", "pairwise"):
        raise ValueError(f"plan_violations: rule must be 'sequential' or 'pairwise', got {rule!r}")
    steps = np.asarray(steps, dtype=np.int64)
    cols = np.asarray(cols, dtype=np.int64)
    out: list[str] = []
    if len(steps) == 0:
        return out
    if np.any(np.diff(steps) <= 0):
        out.append("steps not strictly increasing")
    if steps.min() < 0 or steps.max() >= p.n_steps or cols.min() < 0 or cols.max() >= p.n_gp:
        return out + ["index out of range"]
    for k, j in zip(steps[~p.in_for[steps, cols]], cols[~p.in_for[steps, cols]]):
        out.append(f"GP {p.gp_ids[j]} outside the FOR at step {k}")
    u = p.pointing(steps, cols)
    t = p.t0_s + p.step_s * steps
    a0 = angle_between_deg(p.init_unit[None, :], u)
    need0 = p.slew.time_s(a0)
    first = range(len(steps)) if rule == "pairwise" else [0]
    for i in first:
        if t[i] - p.ready_t_s + tol_s < need0[i]:
            out.append(f"obs {i}: {t[i] - p.ready_t_s:.3f} s from the initial attitude < slew {need0[i]:.3f} s")
    # each observation against the later ones (pairwise) or the next one (sequential), one array per i
    # (the same per-pair arithmetic as one pair at a time)
    last = len(steps) - 1
    if rule == "sequential" and last > 0:
        need = p.slew.time_s(angle_between_deg(u[:-1], u[1:]))
        dt = t[1:] - t[:-1]
        for i in np.flatnonzero(dt + tol_s < need):
            out.append(f"obs {i}->{i + 1}: {dt[i]:.3f} s < slew {need[i]:.3f} s")
    elif rule == "pairwise":
        for i in range(last):
            need = p.slew.time_s(angle_between_deg(u[i][None, :], u[i + 1:]))
            dt = t[i + 1:] - t[i]
            for jx in np.flatnonzero(dt + tol_s < need):
                out.append(f"obs {i}->{i + 1 + jx}: {dt[jx]:.3f} s < slew {need[jx]:.3f} s")
    return out
