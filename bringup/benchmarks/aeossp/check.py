"""Our own feasibility check of an ``aeossp_standard`` solution, and its metrics WCR, CR, TAT, PC.

Written from the benchmark's public rules (its README, "Validity Rules", "Geometry, Attitude, And
Power Semantics", "Metrics And Ranking"), not from its verifier's code; orbits, look angles, the
slew law and the Sun come from :mod:`.geometry`. A solution is valid when every action:

- *structure*: has ``start < end``, both on the action grid and inside the horizon, lies inside its
  task's ``[release, due]`` window, lasts exactly ``required_duration_s``, and its satellite carries
  the task's sensor type;
- *geometry*: keeps the target visible and within ``max_off_nadir_deg`` at its start, its end and
  every geometry-grid instant between them;
- *overlap*: does not overlap the satellite's previous observation;
- *slew*: leaves, after the previous observation (or after the horizon start, slewing from nadir),
  at least the bang-coast-bang slew time plus the settle time; that maneuver window is the
  ``required`` seconds just before the observation;
- *battery*: the battery, integrated over segments cut at the resource grid, every action and every
  maneuver window, never drops below zero. A segment's load (taken at its midpoint) is the idle
  power, plus the imaging power in an observation, plus the slew power in a maneuver window; the
  charge is the sunlit charge power when the satellite is lit (cylindrical shadow) and the battery is
  capped at its capacity after each segment.

Metrics (all zero and TAT None when invalid): CR completed tasks / tasks, WCR completed weight /
total weight, TAT mean of (earliest completing observation's end - release) [s], PC the gross
energy drawn by all satellites over the horizon [Wh] (charging not subtracted). ``slew=False`` or
``battery=False`` switch a rule off, to measure what it costs.

How we know it is right: tests/unit/test_aeossp_check.py builds a tiny case (tasks put on a
satellite's ground track), accepts a two-action schedule on it with the metrics computed by hand,
and shows each rule (grid, window, duration, sensor, visibility, off-nadir, overlap, slew gap,
battery) rejecting a copy broken in that one way; PC equals the closed-form sum of idle, imaging
and slew energy. The official verifier agreed with it on our solutions (docs/guide/aeossp.md).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bringup.benchmarks.aeossp.case import Action, Case
from bringup.benchmarks.aeossp.geometry import (
    Orbits,
    angle_deg,
    ecef_to_teme,
    off_nadir_deg,
    slew_time_s,
    sun_unit_teme,
    sunlit,
    target_ecef_km,
    visible,
)

__all__ = ["CheckResult", "Violation", "check", "metrics"]

EPS = 1e-6


@dataclass(frozen=True)
class Violation:
    kind: str          # structure | geometry | overlap | slew | battery
    action: Action | None
    text: str
    sat_id: str = ""
    t_s: float = 0.0


@dataclass
class CheckResult:
    valid: bool
    violations: list[Violation]
    metrics: dict
    maneuvers: dict = field(default_factory=dict)   # sat -> [(start_s, end_s)]


def look_teme(orbits: Orbits, sat: str, tgt_ecef: np.ndarray, t_s) -> np.ndarray:
    """Inertial (TEME) look vectors satellite -> target at the offsets [n_t, 3]."""
    r, _e, theta = orbits.at(sat, t_s)
    return ecef_to_teme(np.broadcast_to(tgt_ecef, r.shape), theta) - r


def _structure(case: Case, a: Action) -> str | None:
    m, task, sat = case.mission, case.task(a.task_id), case.sat(a.sat_id)
    if a.end_s <= a.start_s:
        return "zero or negative duration"
    if a.start_s % m.action_step_s or a.end_s % m.action_step_s:
        return f"off the {m.action_step_s}-s action grid"
    if a.start_s < 0 or a.end_s > m.horizon_s:
        return "outside the horizon"
    if a.start_s < task.release_s or a.end_s > task.due_s:
        return "outside the task window"
    if a.end_s - a.start_s != task.duration_s:
        return f"lasts {a.end_s - a.start_s} s, the task requires {task.duration_s} s"
    if sat.sensor != task.sensor:
        return f"sensor {sat.sensor} cannot serve a {task.sensor} task"
    return None


def geometry_samples(case: Case, a: Action) -> np.ndarray:
    g = case.mission.geometry_step_s
    inner = np.arange((a.start_s // g + 1) * g, a.end_s, g)
    return np.concatenate([[a.start_s], inner, [a.end_s]]).astype(float)


def _geometry(case: Case, orbits: Orbits, a: Action) -> str | None:
    sat = case.sat(a.sat_id)
    tgt = targets_ecef_km(case)[a.task_id]
    ts = geometry_samples(case, a)
    _r, e, _th = orbits.at(a.sat_id, ts)
    vis = visible(e, tgt)
    ona = off_nadir_deg(e, tgt)
    bad = np.flatnonzero(~vis | (ona > sat.max_off_nadir_deg + EPS))
    if bad.size:
        i = bad[0]
        why = "target not visible" if not vis[i] else f"off-nadir {ona[i]:.3f} deg > {sat.max_off_nadir_deg:g}"
        return f"{why} at t+{ts[i]:g} s"
    return None


def slew_need_s(case: Case, orbits: Orbits, prev: Action | None, cur: Action) -> float:
    """Slew-plus-settle seconds needed before ``cur`` (from ``prev``'s end look, or nadir)."""
    sat = case.sat(cur.sat_id)
    to = look_teme(orbits, cur.sat_id, target_ecef_km(case.task(cur.task_id)), [cur.start_s])[0]
    if prev is None:
        r, _e, _th = orbits.at(cur.sat_id, [cur.start_s])
        frm = -r[0]
    else:
        frm = look_teme(orbits, cur.sat_id, target_ecef_km(case.task(prev.task_id)), [prev.end_s])[0]
    theta = float(angle_deg(frm, to))
    return slew_time_s(theta, sat.max_rate_deg_s, sat.max_acc_deg_s2) + sat.settle_s


def targets_ecef_km(case: Case) -> dict[str, np.ndarray]:
    """Every task's target in ECEF [km], computed once per case."""
    cached = getattr(case, "_targets", None)
    if cached is None:
        xyz = target_ecef_km_many(case)
        cached = {t.task_id: xyz[k] for k, t in enumerate(case.tasks)}
        object.__setattr__(case, "_targets", cached)
    return cached


def target_ecef_km_many(case: Case) -> np.ndarray:
    from orbit_clock.frames import geodetic_to_ecef_km

    return geodetic_to_ecef_km([t.lat_deg for t in case.tasks], [t.lon_deg for t in case.tasks],
                               np.array([t.alt_m for t in case.tasks]) / 1000.0)


def satellite_sequence(case: Case, orbits: Orbits, sat_id: str, acts: list[Action], slew: bool = True):
    """Overlap and slew violations of one satellite's actions, and its maneuver windows.

    The same rule as :func:`slew_need_s`, with every look vector from one propagation."""
    out, windows, prev = [], [], None
    acts = sorted(acts, key=lambda a: (a.start_s, a.end_s))
    if not acts:
        return out, windows
    sat = case.sat(sat_id)
    tg = targets_ecef_km(case)
    n = len(acts)
    ts = np.array([a.start_s for a in acts] + [a.end_s for a in acts], dtype=float)
    r, _e, theta = orbits.at(sat_id, ts)
    tgt = np.array([tg[a.task_id] for a in acts] * 2)
    look = ecef_to_teme(tgt, theta) - r
    look0, look1, nadir0 = look[:n], look[n:], -r[:n]
    for i, a in enumerate(acts):
        if prev is not None and acts[prev].end_s > a.start_s:
            out.append(Violation("overlap", a, f"{a.sat_id} {a.task_id}: overlaps {acts[prev].task_id}", sat_id,
                                 a.start_s))
            continue
        frm = nadir0[i] if prev is None else look1[prev]
        theta_deg = float(angle_deg(frm, look0[i]))
        need = slew_time_s(theta_deg, sat.max_rate_deg_s, sat.max_acc_deg_s2) + sat.settle_s
        have = a.start_s - (acts[prev].end_s if prev is not None else 0)
        if slew and have + EPS < need:
            out.append(Violation("slew", a, f"{a.sat_id} {a.task_id}: slew+settle needs {need:.2f} s, has {have} s",
                                 sat_id, a.start_s))
            continue
        if slew and need > EPS:
            windows.append((a.start_s - need, float(a.start_s)))
        prev = i
    return out, windows


def battery(case: Case, orbits: Orbits, sat_id: str, acts: list[Action], windows: list[tuple[float, float]]):
    """(first violation or None, gross consumption Wh, minimum battery Wh) of one satellite."""
    sat, m = case.sat(sat_id), case.mission
    pts = set(np.arange(0, m.horizon_s + 1, m.resource_step_s, dtype=float).tolist())
    pts.add(float(m.horizon_s))
    for a in acts:
        pts.update((float(a.start_s), float(a.end_s)))
    for w0, w1 in windows:
        pts.update((w0, w1))
    t = np.array(sorted(pts))
    dt = np.diff(t)
    mid = t[:-1] + dt / 2.0
    keep = dt > 0
    t0, dt, mid = t[:-1][keep], dt[keep], mid[keep]
    load = np.full(mid.shape, sat.idle_w)
    img = np.zeros(mid.shape, bool)
    for a in acts:
        img |= (mid >= a.start_s) & (mid < a.end_s)
    slw = np.zeros(mid.shape, bool)
    for w0, w1 in windows:
        slw |= (mid >= w0) & (mid < w1)
    load = load + img * sat.imaging_w + slw * sat.slew_w
    r, _e, _th = orbits.at(sat_id, mid)
    charge = np.where(sunlit(r, sun_unit_teme(m.start, mid)), sat.charge_w, 0.0)
    delta = (charge - load) * dt / 3600.0
    b, lowest = sat.initial_wh, sat.initial_wh
    for i in range(len(delta)):   # the cap makes this a scan, not a cumsum
        b += delta[i]
        if b < -EPS:
            return (Violation("battery", None, f"{sat_id}: battery below zero ({b:.3f} Wh) at t+{mid[i]:.1f} s",
                              sat_id, float(t0[i])), float(np.sum(load * dt) / 3600.0), b)
        b = min(b, sat.capacity_wh)
        lowest = min(lowest, b)
    return None, float(np.sum(load * dt) / 3600.0), lowest


def metrics(case: Case, acts: list[Action], pc_wh: float) -> dict:
    first_end: dict[str, int] = {}
    for a in acts:
        first_end[a.task_id] = min(a.end_s, first_end.get(a.task_id, a.end_s))
    total_w = sum(t.weight for t in case.tasks)
    done_w = sum(case.task(k).weight for k in first_end)
    tat = [first_end[k] - case.task(k).release_s for k in first_end]
    return {"CR": len(first_end) / len(case.tasks) if case.tasks else 0.0,
            "WCR": done_w / total_w if total_w > 0 else 0.0,
            "TAT": float(np.mean(tat)) if tat else None, "PC": pc_wh}


def check(case: Case, acts: list[Action], orbits: Orbits | None = None, *, slew: bool = True,
          battery_rule: bool = True) -> CheckResult:
    """Every rule on every action; metrics zeroed (TAT None) when anything is violated."""
    orbits = orbits or Orbits(case.satellites, case.mission.start)
    vio: list[Violation] = []
    good: list[Action] = []
    for a in acts:
        why = _structure(case, a) or _geometry(case, orbits, a)
        if why:
            kind = "structure" if _structure(case, a) else "geometry"
            vio.append(Violation(kind, a, f"{a.sat_id} {a.task_id} [{a.start_s}, {a.end_s}]: {why}", a.sat_id,
                                 a.start_s))
        else:
            good.append(a)
    by_sat: dict[str, list[Action]] = {s.sat_id: [] for s in case.satellites}
    for a in good:
        by_sat[a.sat_id].append(a)
    pc, maneuvers = 0.0, {}
    for sid, sa in by_sat.items():
        v, windows = satellite_sequence(case, orbits, sid, sa, slew=slew)
        vio += v
        maneuvers[sid] = windows
        bv, used, _low = battery(case, orbits, sid, sa, windows)
        if bv is not None and battery_rule:
            vio.append(bv)
        pc += used
    valid = not vio
    m = metrics(case, acts, pc) if valid else {"CR": 0.0, "WCR": 0.0, "TAT": None, "PC": 0.0}
    return CheckResult(valid, vio, m, maneuvers)
