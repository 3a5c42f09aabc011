"""Plan an ``aeossp_standard`` case: the project's DP per satellite, onboard or central, and a greedy baseline.

Candidates. For each satellite and each task of its sensor type, every start on the action grid
whose observation keeps the target visible and within ``max_off_nadir_deg - MARGIN_DEG`` at every
geometry sample (the same samples as :mod:`.check`), inside the task window; at most
``MAX_STARTS`` starts per run of feasible starts (evenly spread, the earliest always kept). Each
candidate carries its inertial look directions at start and end.

DP (the idea of sat_node/scheduler/dp.py, compiled in :mod:`.dp_kernel`: a longest path over the
satellite's time-ordered choices, each transition feasible under the slew law). Over the satellite's candidates sorted by
start, ``V[i] = w_i - lambda E_i + max(0, max_j V[j])`` over predecessors ``j`` that end early
enough for the bang-coast-bang slew plus settle (+ ``MARGIN_S``) from ``j``'s end look to ``i``'s
start look, and observe another task; a predecessor ending more than the longest possible slew
earlier is always feasible and is taken from a running maximum. The first observation slews from
nadir. The battery is a resource by a Lagrangian price: ``E_i`` is the candidate's imaging and
(nominal) slew energy [Wh]; ``lambda`` rises through ``LAMBDAS`` until :func:`.check.battery`
holds for the plan (with ``BATTERY_RESERVE_WH`` kept); a plan that does not hold is repaired (the
lightest action before the depletion dropped, again and again) and the best plan by weight is kept.

Planning:
- ``onboard``: satellites plan one after another in rank order (the project's rank rule: a plan
  announced by a higher-ranked satellite outranks, so a satellite drops the tasks its higher-ranked
  neighbours announced); each knows only its own candidates and those announcements.
- ``central``: one planner with the whole picture: the onboard pass as a start, then the joint
  assignment search of :mod:`.search` (steal and insert moves between satellites, each
  satellite's part an exact DP, until no move gains or the time limit), then every satellite's
  battery-priced DP over the tasks it was assigned, and a last pass in which any satellite may
  take up a task the battery let go.
- ``greedy`` (the baseline): tasks by weight (then earliest due), each inserted at the first
  candidate whose slew gaps to the neighbours on its satellite's timeline hold; battery repair last.

Every plan is repaired until :func:`.check.check` finds it valid (the command asserts it).

How we know it is right: tests/unit/test_aeossp_planner.py (every mode's plan passes the check
with no task twice; the DP's value equals a brute force over all subsets of a small satellite's
candidates; the joint search moves a task to free a satellite and is near the brute-force
optimum of the assignment on small instances; onboard does not peek: a higher-ranked satellite's
plan is the same with or without its lower-ranked neighbour, who never takes a task the higher one announced; the battery price makes a
poor satellite's plan feasible where the unpriced plan would deplete it).
"""

from __future__ import annotations

import time

import numpy as np

from bringup.benchmarks.aeossp.case import Action, Case
from bringup.benchmarks.aeossp.check import battery, check, satellite_sequence, target_ecef_km_many
from bringup.benchmarks.aeossp.dp_kernel import longest_path
from bringup.benchmarks.aeossp.geometry import (
    Orbits,
    ecef_to_teme,
    off_nadir_deg,
    slew_time_s,
    visible,
)
from bringup.benchmarks.aeossp.search import assign

__all__ = ["Candidates", "plan"]

MARGIN_DEG = 0.02       # off-nadir margin against our frames vs the verifier's (GMST vs full IAU)
MARGIN_S = 0.1          # slew-gap margin [s]
MAX_STARTS = 64
DUP_RETRIES = 3
BATTERY_RESERVE_WH = 2.0
LAMBDAS = (0.0, 0.003, 0.01, 0.03, 0.1, 0.3, 1.0)


class Candidates:
    """One satellite's candidate observations as arrays sorted by start."""

    def __init__(self, case: Case, orbits: Orbits, sat_id: str, slew: bool = True):
        sat = case.sat(sat_id)
        self.slew = slew
        m = case.mission
        step = m.action_step_s
        grid = np.arange(0, m.horizon_s + 1, step)
        r, e, theta = orbits.at(sat_id, grid.astype(float))
        tg = target_ecef_km_many(case) if getattr(case, "_targets", None) is None else \
            np.array([case._targets[t.task_id] for t in case.tasks])
        rows = []
        ks = [k for k, t in enumerate(case.tasks) if t.sensor == sat.sensor]
        lo = np.array([case.tasks[k].release_s // step for k in ks], dtype=int)
        hi = np.array([case.tasks[k].due_s // step for k in ks], dtype=int)
        # every (task, window sample) at once: the geometry of all windows in one vector pass
        lens = hi - lo + 1
        off = np.concatenate([[0], np.cumsum(lens)])
        flat_t = np.repeat(np.arange(len(ks)), lens)
        flat_i = np.arange(off[-1]) - np.repeat(off[:-1], lens) + np.repeat(lo, lens)
        ee, tt = e[flat_i], tg[np.asarray(ks, dtype=int)][flat_t] if ks else np.zeros((0, 3))
        ok_all = visible(ee, tt) & (off_nadir_deg(ee, tt) <= sat.max_off_nadir_deg - MARGIN_DEG)
        for q, k in enumerate(ks):
            task = case.tasks[k]
            i0 = int(lo[q])
            ok = ok_all[off[q]:off[q + 1]]
            n = task.duration_s // step       # samples per observation: n + 1
            if not ok.any() or len(ok) < n + 1:
                continue
            c = np.concatenate([[0], np.cumsum(ok)])
            full = (c[n + 1:] - c[:-(n + 1)]) == n + 1          # start index s: samples s..s+n all ok
            starts = np.flatnonzero(full)
            if not starts.size:
                continue
            runs = np.split(starts, np.flatnonzero(np.diff(starts) > 1) + 1)
            for run in runs:
                pick = run if len(run) <= MAX_STARTS else run[np.unique(np.linspace(0, len(run) - 1,
                                                                                   MAX_STARTS).astype(int))]
                for s in pick:
                    rows.append((k, (i0 + s) * step, (i0 + s + n) * step, i0 + s, i0 + s + n))
        rows.sort(key=lambda x: (x[1], x[2], x[0]))
        self.sat_id = sat_id
        self.task = np.array([x[0] for x in rows], dtype=int)
        self.start = np.array([x[1] for x in rows], dtype=int)
        self.end = np.array([x[2] for x in rows], dtype=int)
        w = np.array([t.weight for t in case.tasks])
        self.weight = w[self.task] if rows else np.zeros(0)
        si = np.array([x[3] for x in rows], dtype=int)
        ei = np.array([x[4] for x in rows], dtype=int)
        if rows:
            self.u0 = self._unit(ecef_to_teme(tg[self.task], theta[si]) - r[si])
            self.u1 = self._unit(ecef_to_teme(tg[self.task], theta[ei]) - r[ei])
            self.nadir0 = self._unit(-r[si])
        else:
            self.u0 = self.u1 = self.nadir0 = np.zeros((0, 3))
        self.energy = (sat.imaging_w * (self.end - self.start) + sat.slew_w * (sat.settle_s + 10.0)) / 3600.0
        self.sat = sat
        self.by_end = np.argsort(self.end, kind="stable")
        self.startf, self.endf = self.start.astype(np.float64), self.end.astype(np.float64)
        if slew and rows:
            self.t_far = float(self.need_s(180.0))
            self.first_ok = self.start >= self.need_s(_angles_rows(self.nadir0, self.u0))
        else:
            self.t_far, self.first_ok = 0.0, np.ones(len(rows), bool)

    @staticmethod
    def _unit(v):
        return v / np.linalg.norm(v, axis=-1, keepdims=True)

    def __len__(self):
        return len(self.task)

    def need_s(self, theta_deg):
        if not self.slew:                      # the slew rule switched off: only overlap remains
            return 0.0 * np.asarray(theta_deg, dtype=float)
        return slew_time_s(theta_deg, self.sat.max_rate_deg_s, self.sat.max_acc_deg_s2) + self.sat.settle_s + MARGIN_S


def _angles(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.degrees(np.arccos(np.clip(a @ b, -1.0, 1.0)))


def dp(cand: Candidates, allowed: np.ndarray, lam: float) -> list[int]:
    """The best path (indices into ``cand``) over allowed candidates; value w - lam * energy."""
    return dp_gain(cand, np.where(allowed, cand.weight - lam * cand.energy, 0.0))


def dp_gain(cand: Candidates, gain: np.ndarray) -> list[int]:
    """The best path (indices into ``cand``) by candidate gains (a gain <= 0 is never used).

    The DP only keeps a task from following itself; when a path still visits a task twice, the
    later visits' candidates are struck and the DP runs again (``DUP_RETRIES`` times at most)."""
    if not len(cand):
        return []
    gain = np.asarray(gain, dtype=float)
    for _ in range(DUP_RETRIES + 1):
        path = _dp_path(cand, gain)
        tasks = cand.task[path]
        if len(np.unique(tasks)) == len(path):
            return path
        seen: dict[int, int] = {}
        strike = np.zeros(len(cand), bool)
        for i, k in zip(path, tasks.tolist(), strict=True):
            if k in seen:
                strike |= (cand.task == k)
                strike[seen[k]] = False
            else:
                seen[k] = i
        gain = np.where(strike, 0.0, gain)
    return path


def _dp_path(cand: Candidates, gain: np.ndarray) -> list[int]:
    s = cand.sat
    V, P = longest_path(cand.startf, cand.endf, cand.task, cand.u0, cand.u1, gain, cand.first_ok, cand.by_end,
                        s.max_rate_deg_s, s.max_acc_deg_s2, s.settle_s, MARGIN_S, cand.t_far, cand.slew)
    i = int(np.argmax(V))
    if not np.isfinite(V[i]) or V[i] <= 0:
        return []
    path = []
    while i >= 0:
        path.append(i)
        i = int(P[i])
    return path[::-1]


def _angles_rows(a, b):
    return np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", a, b), -1.0, 1.0)))


def _actions(case: Case, cand: Candidates, path) -> list[Action]:
    seen, out = set(), []
    for i in path:
        tid = case.tasks[cand.task[i]].task_id
        if tid in seen:
            continue
        seen.add(tid)
        out.append(Action(cand.sat_id, tid, int(cand.start[i]), int(cand.end[i])))
    return out


def repair(case: Case, orbits: Orbits, sat_id: str, acts: list[Action], rules=(True, True)) -> list[Action]:
    """Drop actions until the satellite's sequence and battery hold (the reserve kept).

    ``rules`` = (slew, battery): either switched off to measure what it costs."""
    acts = sorted(acts, key=lambda a: a.start_s)
    while True:
        vio, windows = satellite_sequence(case, orbits, sat_id, acts, slew=rules[0])
        if vio:
            bad = {v.action for v in vio}
            acts = [a for a in acts if a not in bad]
            continue
        if not rules[1]:
            return acts
        bv, _used, low = battery(case, orbits, sat_id, acts, windows)
        if bv is None and low >= BATTERY_RESERVE_WH:
            return acts
        t = bv.t_s if bv is not None else None
        if t is None:   # above zero but inside the reserve: find where the minimum is by dropping late
            pool = acts
        else:
            pool = [a for a in acts if a.start_s <= t] or acts
        worst = min(pool, key=lambda a: (case.task(a.task_id).weight, -a.start_s))
        acts = [a for a in acts if a is not worst]


def plan_satellite(case: Case, orbits: Orbits, cand: Candidates, allowed: np.ndarray,
                   rules=(True, True)) -> list[Action]:
    """DP with rising battery prices: the first plan the battery holds, or the best repaired one."""
    best: list[Action] = []
    for lam in LAMBDAS if rules[1] else (0.0,):
        acts = _actions(case, cand, dp(cand, allowed, lam))
        _v, windows = satellite_sequence(case, orbits, cand.sat_id, acts, slew=rules[0])
        bv, _u, low = battery(case, orbits, cand.sat_id, acts, windows)
        held = not rules[1] or (bv is None and low >= BATTERY_RESERVE_WH)
        if not held:
            acts = repair(case, orbits, cand.sat_id, acts, rules)
        if _weight(case, acts) > _weight(case, best):
            best = acts
        if held:
            break
    return repair(case, orbits, cand.sat_id, best, rules)


def _weight(case: Case, acts: list[Action]) -> float:
    return sum(case.task(a.task_id).weight for a in acts)


def _onboard(case, orbits, cands, deadline, rules):
    taken: set[int] = set()
    plans = {}
    for sid in sorted(cands):                 # rank order: a higher-ranked announced plan outranks
        c = cands[sid]
        allowed = ~np.isin(c.task, list(taken)) if taken else np.ones(len(c), bool)
        plans[sid] = plan_satellite(case, orbits, c, allowed, rules)
        taken |= {_tindex(case)[a.task_id] for a in plans[sid]}
    return plans


_TIDX: dict[int, dict[str, int]] = {}


def _tindex(case):
    key = id(case)
    if key not in _TIDX:
        _TIDX[key] = {t.task_id: k for k, t in enumerate(case.tasks)}
    return _TIDX[key]


def _central(case, orbits, cands, deadline, rules):
    """The onboard pass, the joint assignment search, then each satellite's priced DP over its tasks."""
    ti = _tindex(case)
    plans = _onboard(case, orbits, cands, deadline, rules)
    w = np.array([t.weight for t in case.tasks], dtype=float)
    order = sorted(cands)
    holder = np.full(len(case.tasks), -1)
    for q, sid in enumerate(order):
        for a in plans[sid]:
            holder[ti[a.task_id]] = q
    holder = assign(cands, w, holder, dp_gain, deadline)
    new = {}
    for q, sid in enumerate(order):
        c = cands[sid]
        new[sid] = plan_satellite(case, orbits, c, holder[c.task] == q, rules)
        holder[holder == q] = -1
        holder[[ti[a.task_id] for a in new[sid]]] = q
    for q, sid in enumerate(order):       # tasks the battery let go: anyone may take them up
        c = cands[sid]
        acts = plan_satellite(case, orbits, c, (holder[c.task] < 0) | (holder[c.task] == q), rules)
        if _weight(case, acts) > _weight(case, new[sid]):
            holder[holder == q] = -1
            holder[[ti[a.task_id] for a in acts]] = q
            new[sid] = acts
    return new


def _greedy(case, orbits, cands, deadline, rules):
    by_task: dict[int, list[tuple[int, str, int]]] = {}
    for sid, c in cands.items():
        for i in range(len(c)):
            by_task.setdefault(int(c.task[i]), []).append((int(c.start[i]), sid, i))
    timeline: dict[str, list[int]] = {sid: [] for sid in cands}   # candidate indices sorted by start
    order = sorted(by_task, key=lambda k: (-case.tasks[k].weight, case.tasks[k].due_s))
    for k in order:
        if time.monotonic() > deadline:
            break
        for _s, sid, i in sorted(by_task[k]):
            c, tl = cands[sid], timeline[sid]
            pos = int(np.searchsorted(c.start[tl], c.start[i])) if tl else 0
            if pos > 0:
                j = tl[pos - 1]
                if c.start[i] - c.end[j] < c.need_s(_angles(c.u1[j][None], c.u0[i])[0]):
                    continue
            elif c.start[i] < c.need_s(_angles(c.nadir0[i][None], c.u0[i])[0]):
                continue
            if pos < len(tl):
                j = tl[pos]
                if c.start[j] - c.end[i] < c.need_s(_angles(c.u1[i][None], c.u0[j])[0]):
                    continue
            tl.insert(pos, i)
            break
    return {sid: repair(case, orbits, sid, [Action(sid, case.tasks[cands[sid].task[i]].task_id,
                                                   int(cands[sid].start[i]), int(cands[sid].end[i])) for i in tl],
                          rules)
            for sid, tl in timeline.items()}


def plan(case: Case, planning: str = "central", time_limit_s: float = 300.0,
         orbits: Orbits | None = None, *, slew: bool = True, battery_rule: bool = True) -> list[Action]:
    """A valid plan (asserted with :func:`.check.check`) by ``onboard``, ``central`` or ``greedy``.

    ``slew=False`` / ``battery_rule=False`` plan and check with that rule switched off (what the
    rule costs is the WCR difference); such a plan is not a valid benchmark solution."""
    t0 = time.monotonic()
    deadline = t0 + time_limit_s
    orbits = orbits or Orbits(case.satellites, case.mission.start)
    cands = {s.sat_id: Candidates(case, orbits, s.sat_id, slew) for s in case.satellites}
    fn = {"onboard": _onboard, "central": _central, "greedy": _greedy}.get(planning)
    if fn is None:
        raise ValueError(f"planning must be onboard, central or greedy, not {planning!r}")
    plans = fn(case, orbits, cands, deadline, (slew, battery_rule))
    acts = [a for sid in sorted(plans) for a in plans[sid]]
    res = check(case, acts, orbits, slew=slew, battery_rule=battery_rule)
    if not res.valid:
        raise AssertionError(f"the {planning} plan fails our own check: {res.violations[0].text}")
    return acts
