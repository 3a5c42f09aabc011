"""ISL contact plans of large constellations against a brute-force line-of-sight check.

The plan search (orbit_clock/isl.py) samples only the pairs and times that can be in range (k-d tree
pruning) and refines edges by bisection. The oracle here shares none of that: at random instants
it propagates every satellite with SGP4's array path, and for every pair decides line of sight with
a segment-sphere intersection (roots of a quadratic, in the ellipsoid-to-sphere scaled frame) and
the range limit. Every pair the oracle sees in contact must have a contact open in the plan at that
instant and no other pair may, both directions, the same window each way.

Tolerances: an instant within 5 ms of one of the pair's contact edges is not judged (edges are
bisected to 1 ms); a window the 10 s search grid cannot see (shorter than one step) may be missing,
so a pair the oracle sees but the plan lacks must have a margin that stays positive for less than
10 s around that instant.
"""

from __future__ import annotations

import msgspec
import numpy as np
import pytest

from bringup.scenario.config import load_scenario
from orbit_clock import build_constellation, isl_contact_plan
from orbit_clock.frames import WGS84_A_KM, WGS84_B_KM

EDGE_S = 5e-3
STEP_S = 10.0


def _in_contact(p1: np.ndarray, p2: np.ndarray, grazing_km: float, max_range_km: float) -> np.ndarray:
    """(pairs,) line of sight by segment-sphere roots (independent of los_clearance_km) and range."""
    s = np.array([1.0, 1.0, WGS84_A_KM / WGS84_B_KM])
    a, b = p1 * s, p2 * s
    d = b - a
    R = WGS84_A_KM + grazing_km
    qa = np.einsum("ij,ij->i", d, d)
    qb = 2.0 * np.einsum("ij,ij->i", a, d)
    qc = np.einsum("ij,ij->i", a, a) - R * R
    disc = qb * qb - 4 * qa * qc
    sq = np.sqrt(np.maximum(disc, 0.0))
    r1, r2 = (-qb - sq) / (2 * qa), (-qb + sq) / (2 * qa)
    blocked = (disc >= 0) & (((r1 >= 0) & (r1 <= 1)) | ((r2 >= 0) & (r2 <= 1)))
    return ~blocked & (np.linalg.norm(p2 - p1, axis=1) <= max_range_km)


@pytest.mark.parametrize("sats,planes,pattern,inc_deg,hours", [
    (96, 3, "star", 98.5, 6.0),  # the paper's orbits, 32 per plane (what --sats 96 gives)
    (240, 12, "delta", 53.0, 3.0),  # a Walker delta 240/12/1 at 53 deg
])
def test_plan_equals_brute_force_line_of_sight(sats, planes, pattern, inc_deg, hours):
    sc = load_scenario("paper").with_overrides(sats=sats, planes=planes, hours=hours)
    sc = msgspec.structs.replace(sc, constellation=msgspec.structs.replace(
        sc.constellation, pattern=pattern, inclination_deg=inc_deg))
    c = build_constellation(sc)
    plan = isl_contact_plan(sc, c)
    isl = sc.isl
    names = c.names
    n = len(names)
    idx = {nm: k for k, nm in enumerate(names)}
    # both directions carry the same windows
    fwd = {(x.src, x.dst, x.start_s, x.end_s) for x in plan}
    assert all((b, a, s, e) in fwd for a, b, s, e in fwd)
    w = np.array([(idx[x.src], idx[x.dst], x.start_s, x.end_s) for x in plan if idx[x.src] < idx[x.dst]])
    wi, wj = w[:, 0].astype(np.int64), w[:, 1].astype(np.int64)
    wp = wi * n - wi * (wi + 1) // 2 + (wj - wi - 1)  # pair index in np.triu_indices(n, 1) order
    I, J = np.triu_indices(n, 1)
    rng = np.random.default_rng(sats)
    times = rng.uniform(0.0, sc.scenario.horizon_s, 40)
    pos = c.positions_ecef_km(times)  # (n, T, 3), SatrecArray path
    judged = seen = 0
    for k, t in enumerate(times):
        truth = _in_contact(pos[I, k], pos[J, k], isl.grazing_height_km, isl.max_range_km)
        open_ = np.zeros(I.size, bool)
        open_[wp[(w[:, 2] <= t) & (t < w[:, 3])]] = True
        near_edge = np.zeros(I.size, bool)
        near_edge[wp[(np.abs(t - w[:, 2]) < EDGE_S) | (np.abs(t - w[:, 3]) < EDGE_S)]] = True
        judged += int((~near_edge).sum())
        seen += int((open_ & truth & ~near_edge).sum())
        for p in np.flatnonzero((open_ != truth) & ~near_edge):
            assert not open_[p], f"t={t:.3f}: plan has {names[I[p]]}-{names[J[p]]} open, line of sight says no"
            # a window the 10 s grid could not see: positive for less than one step around t
            tt = t + np.linspace(-STEP_S, STEP_S, 201)
            pp = c.positions_ecef_km(tt)
            m = _in_contact(pp[I[p]], pp[J[p]], isl.grazing_height_km, isl.max_range_km)
            assert m.sum() * (2 * STEP_S / 200) < STEP_S, (
                f"t={t:.3f}: {names[I[p]]}-{names[J[p]]} in line of sight, no contact in the plan")
    assert judged > 0.99 * len(times) * I.size and seen > 0.1 * len(times) * I.size
