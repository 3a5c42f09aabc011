"""Inter-satellite link (ISL) line of sight and the ISL contact plan.

Model (Nag et al. 2019, section 4; DESIGN.md sections 1 and 5): two satellites are in contact while
(a) the segment between them clears the Earth by the grazing height (default 80 km: the atmosphere
below is taken as opaque) and (b) their range is at most the radio's maximum range (default
6000 km). The Earth is the WGS-84 ellipsoid: coordinates are scaled by a/b along z, which maps the
ellipsoid onto the sphere of radius a, and the segment must clear the sphere of radius a + h there
(the scaling stretches heights by at most a/b - 1 = 0.34 %, i.e. 0.3 km at 80 km).

Windows are found on a coarse grid (default 10 s) and each edge is refined by bisection with SGP4
to ``tol_s`` (default 1 ms, orbit_clock.windows); a window shorter than the coarse step can be missed (bench/bench_orbit.py
compares with a 1 s brute-force grid). Each window becomes two directed contacts (A->B, B->A) with
rate ``scenario.isl.rate_bps`` and ``range_light_s`` = the mean range over the window (21 samples,
evenly spaced, ends included) divided by c. CGR takes range constant over a contact, so the mean is
used; in-plane neighbours of the paper's constellation keep a near-constant 5.43e3 km, cross-plane
ranges sweep from the 6000 km limit down to a few hundred km and back.

How we know it is right (tests/unit/test_orbit_isl.py): ``los_clear`` against an independent
segment-sphere intersection (quadratic roots) on random geometry (hypothesis); windows against a 1 s
brute-force grid; symmetry (A->B and B->A identical); hand cases (antipodal satellites blocked,
in-plane neighbours of the paper constellation in contact the whole horizon).
"""

from __future__ import annotations

import numpy as np

from orbit_clock.contact_plan import Contact, ContactPlan
from orbit_clock.frames import C_KM_S, WGS84_A_KM, WGS84_B_KM
from orbit_clock.propagation import Constellation, build_constellation
from orbit_clock.windows import mean_range_km, time_grid, true_runs, windows_from_margin

__all__ = [
    "isl_contact_plan",
    "isl_windows",
    "los_clear",
    "los_clearance_km",
]

_Z_SCALE = WGS84_A_KM / WGS84_B_KM


def los_clearance_km(p1_km: np.ndarray, p2_km: np.ndarray, grazing_height_km: float = 80.0) -> np.ndarray:
    """Closest approach of the segment p1-p2 to the Earth minus (a + grazing height) [km], in the
    ellipsoid-to-sphere scaled frame; > 0 means line of sight. Broadcasts over leading axes."""
    s = np.array([1.0, 1.0, _Z_SCALE])
    a = np.asarray(p1_km, dtype=float) * s
    b = np.asarray(p2_km, dtype=float) * s
    d = b - a
    dd = np.einsum("...k,...k->...", d, d)
    u = np.clip(-np.einsum("...k,...k->...", a, d) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)
    closest = a + u[..., None] * d
    return np.linalg.norm(closest, axis=-1) - (WGS84_A_KM + grazing_height_km)


def los_clear(p1_km, p2_km, grazing_height_km: float = 80.0) -> np.ndarray:
    """True where the segment clears the Earth + grazing height."""
    return los_clearance_km(p1_km, p2_km, grazing_height_km) > 0.0


def isl_windows(constellation: Constellation, t0_s: float, t1_s: float, *, grazing_height_km: float = 80.0,
                max_range_km: float = 6000.0, step_s: float = 10.0, tol_s: float = 1e-3, refine: bool = True):
    """Undirected ISL windows: (i, j, start_s, end_s) arrays with i < j satellite indices.

    ``refine=False`` gives the bare grid (edges at the samples): the brute-force reference.
    """
    n = len(constellation)
    I, J = np.triu_indices(n, k=1)
    t = time_grid(t0_s, t1_s, step_s)
    r = constellation.positions_ecef_km(t)
    margin = np.empty((I.size, t.size))
    chunk = max(1, 4_000_000 // max(1, I.size))
    for c0 in range(0, t.size, chunk):
        a, b = r[I, c0:c0 + chunk], r[J, c0:c0 + chunk]
        rng = np.linalg.norm(a - b, axis=-1)
        margin[:, c0:c0 + chunk] = np.minimum(los_clearance_km(a, b, grazing_height_km), max_range_km - rng)

    def margin_at(idx, tt):
        a = constellation.positions_ecef_km_at(I[idx], tt)
        b = constellation.positions_ecef_km_at(J[idx], tt)
        return np.minimum(los_clearance_km(a, b, grazing_height_km), max_range_km - np.linalg.norm(a - b, axis=-1))

    if refine:
        k, st, en = windows_from_margin(t, margin, margin_at, tol_s)
    else:
        k, st, en = windows_from_margin(t, margin, margin_at, tol_s=np.inf)
        # without refinement take the grid samples themselves (first/last inside sample)
        _, ks, ke = true_runs(margin > 0)
        st, en = t[ks], t[ke - 1]
    return I[k], J[k], st, en


def isl_contact_plan(scenario, constellation: Constellation | None = None, *, step_s: float = 10.0,
                     tol_s: float = 1e-3) -> ContactPlan:
    """Directed ISL contacts (both ways) over the scenario horizon; see the module docstring."""
    c = constellation or build_constellation(scenario)
    isl = scenario.isl
    i, j, st, en = isl_windows(c, 0.0, float(scenario.scenario.horizon_s), grazing_height_km=isl.grazing_height_km,
                               max_range_km=isl.max_range_km, step_s=step_s, tol_s=tol_s)
    keep = en > st
    i, j, st, en = i[keep], j[keep], st[keep], en[keep]
    n = 21  # range samples per window, ends included
    light_s = mean_range_km(lambda t: c.positions_ecef_km_at(np.repeat(i, n), t),
                            lambda t: c.positions_ecef_km_at(np.repeat(j, n), t), st, en, n) / C_KM_S
    contacts = []
    for a, b, s0, s1, lt in zip(i, j, st, en, light_s):
        na, nb = c.names[a], c.names[b]
        s0, s1 = round(float(s0), 3), round(float(s1), 3)
        contacts.append(Contact(s0, s1, na, nb, float(isl.rate_bps), float(lt)))
        contacts.append(Contact(s0, s1, nb, na, float(isl.rate_bps), float(lt)))
    return ContactPlan(contacts)
