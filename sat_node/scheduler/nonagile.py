"""Non-agile baseline: the satellite points at nadir all the time and observes what passes under it.

The study's comparison case (Nag et al., ICAPS SPARK 2019, section 5: "a non-agile constellation
sees 8.4 % of GPs"; docs/design.md section 1). A GP is observed when its centre comes within half the
footprint of the (geocentric) nadir ground track: for each grid interval [t_k, t_k+1] the track is
the great circle through the two satellite positions; the GP's distance to that plane [km] is its
cross-track distance and its angle along the arc gives the crossing time inside the interval. Every
GP crossed within ``footprint_km / 2`` is observed at the nearest grid step (several GPs can share a
step: one image covers them all); its value is Eq. 1 along the resulting list (repeats within
15 min are worth 0) on top of the known observations.

How we know it is right (tests/unit/test_nonagile.py): on a circular orbit whose ground track goes
exactly over a column of GPs, exactly that column (and no neighbour 8 km away) is observed, at the
times the satellite is overhead (brute-force minimum distance on a 0.01 s grid); no slews are
implied (the pointing never changes).
"""

from __future__ import annotations

import numpy as np

from sat_node.scheduler.dp import Plan, make_plan
from sat_node.scheduler.problem import SchedulingProblem

__all__ = ["nadir_pass_crossings", "solve_nonagile"]


def nadir_pass_crossings(sat_pos_km: np.ndarray, gp_ecef_km: np.ndarray, half_width_km: float):
    """(interval k, GP column, fraction f in [0, 1)) of every nadir-track crossing within half_width_km."""
    r = np.asarray(sat_pos_km, np.float64)
    gp = np.asarray(gp_ecef_km, np.float64)
    if len(r) < 2 or len(gp) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
    a = r[:-1] / np.linalg.norm(r[:-1], axis=1, keepdims=True)
    b = r[1:] / np.linalg.norm(r[1:], axis=1, keepdims=True)
    nrm = np.cross(a, b)
    sin_th = np.linalg.norm(nrm, axis=1)
    theta = np.arctan2(sin_th, np.sum(a * b, axis=1))
    n_hat = nrm / sin_th[:, None]
    cross_km = gp @ n_hat.T  # (G, K)
    ok = np.abs(cross_km) <= half_width_km
    gi, ki = np.nonzero(ok)
    if len(gi) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
    proj = gp[gi] - cross_km[gi, ki][:, None] * n_hat[ki]
    ang = np.arctan2(np.sum(np.cross(a[ki], proj) * n_hat[ki], axis=1), np.sum(a[ki] * proj, axis=1))
    f = ang / theta[ki]
    inside = (f >= 0.0) & (f < 1.0)
    return ki[inside].astype(np.int64), gi[inside].astype(np.int64), f[inside]


def solve_nonagile(p: SchedulingProblem, footprint_km: float) -> Plan:
    """Every GP of the instance crossed by the nadir footprint, in time order, valued by Eq. 1."""
    if not footprint_km > 0:
        raise ValueError(f"solve_nonagile: footprint_km must be > 0, got {footprint_km}")
    k, g, f = nadir_pass_crossings(p.sat_pos_km, p.gp_ecef_km, footprint_km / 2.0)
    steps = np.minimum(np.rint(k + f).astype(np.int64), p.n_steps - 1)
    o = np.lexsort((g, steps))
    return make_plan(p, steps[o], g[o])
