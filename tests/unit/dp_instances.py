"""Small generated scheduling instances shared by the DP / MILP / non-agile tests (not a test module)."""

from __future__ import annotations

import numpy as np

from sat_node.acs import SlewModel
from sat_node.scheduler.problem import WGS84_A_KM, build_problem, for_mask

PAPER_SLEW = SlewModel((6.1974e-6, 1.3904e-3, 1.4165e-1, 4.6231), 0.4232)
ALT_KM = 710.0
OMEGA_RAD_S = np.sqrt(398600.4418 / (WGS84_A_KM + ALT_KM) ** 3)


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
