"""Ground-station passes: satellite <-> station contacts above a minimum elevation.

A station (geodetic lat/lon/height on WGS-84, scenario.ground.stations) sees a satellite while the
satellite's elevation above the station's ellipsoid horizon is >= scenario.ground.min_elevation_deg
(paper: polar Svalbard-like and Antarctic-like stations for the centralized mode, docs/design.md
section 1). Found on a coarse grid (default 10 s) and refined by bisection with SGP4 to 1 ms
(orbit_clock.windows.windows_from_margin); passes shorter than the coarse step can be missed.
Each pass gives two directed contacts (sat -> gs_<name> downlink, gs_<name> -> sat uplink) at
scenario.ground.rate_bps with range_light_s = mean slant range over the pass / c.

How often the ground can talk to a satellite (:func:`pass_figures`): the passes per satellite and
orbit (the Keplerian period of the scenario's circular orbit, :func:`orbit_period_s`), a satellite
in view of two stations at once counting one pass. The study assumed uplinks "twice an orbit".

How we know it is right (tests/unit/test_orbit_isl.py): pass edges against skyfield
``find_events`` at the same elevation mask within 2 s; invariants (both directions, ordered,
inside the horizon). tests/unit/test_ground_network.py: pass_figures against a hand-made plan, and
the paper scenario's passes per orbit 2 +- 0.3.
"""

from __future__ import annotations

import numpy as np

from orbit_clock.contact_plan import Contact, ContactPlan
import math

from orbit_clock.frames import C_KM_S, WGS84_A_KM, elevation_deg, geodetic_to_ecef_km, up_unit
from orbit_clock.propagation import MU_WGS84_KM3_S2, Constellation, build_constellation
from orbit_clock.windows import mean_range_km, time_grid, windows_from_margin

__all__ = ["ground_contact_plan", "orbit_period_s", "pass_figures", "station_names", "station_passes"]


def station_names(scenario) -> list[str]:
    """Node names gs_<name> of the scenario's stations, in scenario order (ipn 100 + index)."""
    return [f"gs_{s.name}" for s in scenario.ground.stations]


def station_passes(constellation: Constellation, lat_deg, lon_deg, alt_km, t0_s: float, t1_s: float,
                   min_elevation_deg: float, *, step_s: float = 10.0, tol_s: float = 1e-3):
    """Passes of every satellite over stations: (sat, station, start_s, end_s, mean_range_km) arrays."""
    site = geodetic_to_ecef_km(np.atleast_1d(lat_deg), np.atleast_1d(lon_deg), np.atleast_1d(alt_km))
    up = up_unit(np.atleast_1d(lat_deg), np.atleast_1d(lon_deg))
    n_sat, n_st = len(constellation), site.shape[0]
    S, G = np.repeat(np.arange(n_sat), n_st), np.tile(np.arange(n_st), n_sat)
    t = time_grid(t0_s, t1_s, step_s)
    r = constellation.positions_ecef_km(t)  # (n_sat, n_t, 3)
    margin = elevation_deg(r[S], site[G][:, None, :], up[G][:, None, :]) - min_elevation_deg

    def margin_at(idx, tt):
        rr = constellation.positions_ecef_km_at(S[idx], tt)
        return elevation_deg(rr, site[G[idx]], up[G[idx]]) - min_elevation_deg

    k, st, en = windows_from_margin(t, margin, margin_at, tol_s)
    n = 21  # range samples per pass, ends included
    rng = mean_range_km(lambda tt: constellation.positions_ecef_km_at(np.repeat(S[k], n), tt),
                        lambda tt: np.repeat(site[G[k]], n, axis=0), st, en, n)
    return S[k], G[k], st, en, rng


def ground_contact_plan(scenario, constellation: Constellation | None = None, *, step_s: float = 10.0,
                        tol_s: float = 1e-3) -> ContactPlan:
    """Directed satellite <-> ground-station contacts over the scenario horizon (both directions)."""
    c = constellation or build_constellation(scenario)
    g = scenario.ground
    if not g.stations:
        return ContactPlan([])
    names = station_names(scenario)
    sat, st_i, t0, t1, rng = station_passes(
        c, [s.lat_deg for s in g.stations], [s.lon_deg for s in g.stations], [s.alt_m / 1000.0 for s in g.stations],
        0.0, float(scenario.scenario.horizon_s), g.min_elevation_deg, step_s=step_s, tol_s=tol_s)
    out = []
    for s, k, a, b, r in zip(sat, st_i, t0, t1, rng):
        if b <= a:
            continue
        lt = float(r) / C_KM_S
        a, b = round(float(a), 3), round(float(b), 3)
        out.append(Contact(float(a), float(b), c.names[s], names[k], float(g.rate_bps), lt))
        out.append(Contact(float(a), float(b), names[k], c.names[s], float(g.rate_bps), lt))
    return ContactPlan(out)


def orbit_period_s(altitude_km: float) -> float:
    """Keplerian period [s] of a circular orbit ``altitude_km`` above the WGS-84 equatorial radius."""
    a = WGS84_A_KM + float(altitude_km)
    return 2.0 * math.pi * math.sqrt(a ** 3 / MU_WGS84_KM3_S2)


def pass_figures(plan: ContactPlan, sats, horizon_s: float, period_s: float) -> dict:
    """Passes of satellites ``sats`` over any station (downlink contacts, overlapping ones of one
    satellite merged) and their number per satellite and orbit over ``horizon_s``."""
    by_sat: dict[str, list[tuple[float, float]]] = {s: [] for s in sats}
    for c in plan.contacts:
        if c.src in by_sat:
            by_sat[c.src].append((c.start_s, c.end_s))
    n = 0
    for spans in by_sat.values():
        end = -math.inf
        for a, b in sorted(spans):
            if a > end:
                n += 1
            end = max(end, b)
    orbits = len(by_sat) * float(horizon_s) / float(period_s)
    return {"passes": n, "orbit_period_s": float(period_s),
            "passes_per_orbit": n / orbits if orbits > 0 else None}
