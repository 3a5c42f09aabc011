"""Small generated scheduling instances and two-body circular geometry shared by the DP / MILP /
non-agile / FOR tests (not a test module). The geometry is a simple stand-in (spherical Earth,
circular orbits, rotation at the sidereal rate, no J2, no SGP4), not the flight geometry."""

from __future__ import annotations

import math

import numpy as np

from orbit_clock.access import for_mask
from orbit_clock.frames import OMEGA_EARTH_RAD_S, WGS84_A_KM
from orbit_clock.propagation import MU_WGS84_KM3_S2
from sat_node.acs import SlewModel
from sat_node.scheduler.problem import build_problem

PAPER_SLEW = SlewModel((6.1974e-6, 1.3904e-3, 1.4165e-1, 4.6231), 0.4232)
ALT_KM = 710.0
OMEGA_RAD_S = np.sqrt(MU_WGS84_KM3_S2 / (WGS84_A_KM + ALT_KM) ** 3)


def track(t_s: np.ndarray, tilt_deg: float = 0.0) -> np.ndarray:
    """Circular orbit passing over lat 0, lon 0 at t = 0, in the x-z plane rotated about x by tilt."""
    r = WGS84_A_KM + ALT_KM
    a = OMEGA_RAD_S * t_s
    c, s = np.cos(np.radians(tilt_deg)), np.sin(np.radians(tilt_deg))
    return np.stack([r * np.cos(a), -s * r * np.sin(a), c * r * np.sin(a)], axis=1)


def gp_ecef(lat_deg, lon_deg) -> np.ndarray:
    la, lo = np.radians(lat_deg), np.radians(lon_deg)
    return WGS84_A_KM * np.stack([np.cos(la) * np.cos(lo), np.cos(la) * np.sin(lo), np.sin(la)], axis=-1)


def random_instance(seed: int, *, n_gp: int = 4, n_steps: int = 40, max_window: int = 5,
                    revisit_zero_s: float = 900.0, t0_s: float = -20.0, spread_deg: float = 3.0,
                    prior: bool = False, init_nadir: bool = True):
    """GPs scattered near the ground track; each available during one random run of <= max_window steps."""
    rng = np.random.default_rng(seed)
    times = t0_s + np.arange(n_steps, dtype=float)
    sat = track(times)
    gp = gp_ecef(rng.uniform(-spread_deg, spread_deg, n_gp), rng.uniform(-spread_deg, spread_deg, n_gp))
    geo = for_mask(sat, gp, 55.0)
    m = np.zeros_like(geo)
    for j in range(n_gp):
        length = int(rng.integers(1, max_window + 1))
        start = int(rng.integers(0, n_steps - length + 1))
        m[start:start + length, j] = True
    m &= geo
    absval = rng.integers(1, 257, size=(n_steps, n_gp)).astype(float)
    kw = {}
    if prior:
        kw["prior_count"] = rng.integers(0, 3, size=(n_steps, n_gp))
        kw["prior_recent"] = rng.random((n_steps, n_gp)) < 0.2
    init = None if init_nadir else gp[int(rng.integers(0, n_gp))]
    return build_problem(t0_s=t0_s, step_s=1.0, sat_pos_km=sat, gp_ecef_km=gp, in_for=m, absval=absval,
                         slew=PAPER_SLEW, revisit_zero_s=revisit_zero_s, init_target_km=init, **kw)


def circular_walker_ecef_km(times_s, *, total_sats: int, planes: int, phasing_f: int, altitude_km: float,
                            inclination_deg: float, raan0_deg: float = 0.0, pattern: str = "star",
                            gmst0_deg: float = 280.46) -> np.ndarray:
    """ECEF positions (n_sats, T, 3) [km] of a circular Walker constellation (two-body, no J2)."""
    t = np.asarray(times_s, dtype=np.float64)
    r = WGS84_A_KM + altitude_km
    n = math.sqrt(MU_WGS84_KM3_S2 / r**3)
    spp = total_sats // planes
    spread = 180.0 if pattern == "star" else 360.0
    inc = math.radians(inclination_deg)
    out = np.empty((total_sats, len(t), 3))
    theta = math.radians(gmst0_deg) + OMEGA_EARTH_RAD_S * t
    for p in range(planes):
        raan = math.radians(raan0_deg + p * spread / planes)
        for s in range(spp):
            u = math.radians(s * 360.0 / spp + p * phasing_f * 360.0 / total_sats) + n * t
            x = r * (np.cos(u) * math.cos(raan) - np.sin(u) * math.sin(raan) * math.cos(inc))
            y = r * (np.cos(u) * math.sin(raan) + np.sin(u) * math.cos(raan) * math.cos(inc))
            z = r * np.sin(u) * math.sin(inc)
            c, sn = np.cos(theta), np.sin(theta)
            out[p * spp + s, :, 0] = c * x + sn * y
            out[p * spp + s, :, 1] = -sn * x + c * y
            out[p * spp + s, :, 2] = z
    return out


def square_region_gp_ecef_km(lat_deg: float, lon_deg: float, size_km: float, spacing_km: float) -> np.ndarray:
    """GP centres (n*n, 3) of a size_km square on a spherical Earth of radius WGS84_A_KM."""
    n = max(1, round(size_km / spacing_km))
    off = (np.arange(n) + 0.5) * (size_km / n) - size_km / 2
    yy, xx = np.meshgrid(off, off, indexing="ij")
    lat = np.radians(lat_deg) + yy.ravel() / WGS84_A_KM
    lon = np.radians(lon_deg) + xx.ravel() / (WGS84_A_KM * math.cos(math.radians(lat_deg)))
    return WGS84_A_KM * np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], axis=1)
