"""Ground-point access: when each satellite can point at each GP within its field of regard.

Model (Nag et al. 2019, section 3-5): a satellite at r_sat (ECEF) can image a GP at r_gp when the
off-nadir angle eta = angle(-r_sat, r_gp - r_sat) (geocentric nadir) is <= the field of regard
(paper: 55 deg) and the GP is on the near side of the Earth ((r_sat - r_gp) . r_gp > 0). At 710 km
55 deg off-nadir is 24.45 deg elevation (about 1175 km ground range).

Search, coarse then refine (``access_windows``):
1. coarse grid (default 20 s): angle between each satellite and each region centre; a region is a
   candidate at a sample when that angle is within the largest possible access angle (upper bound
   from the highest satellite radius and the polar Earth radius) + the region's half diagonal + the
   satellite's ground-relative angular motion over one coarse step. If a GP is visible at t in
   [t_k, t_k+1], both t_k and t_k+1 are flagged, so no window escapes a candidate interval.
2. candidate interval on a fine grid (default 1 s) with SGP4: eta for every GP of the region; runs of
   visible samples are windows; each edge is placed by linear interpolation of (limit - eta)
   between the bracketing samples (eta is smooth: the error is milliseconds, far below 1 s).
   min_off_nadir_deg is the smallest eta on the fine samples of the window.
Windows shorter than one fine step can be missed (a grazing pass that dips below the limit between
two samples); windows are clipped to [t0_s, t1_s].

How we know it is right (tests/unit/test_orbit_access.py): skyfield ``find_events`` with the
elevation mask equivalent to the off-nadir limit agrees on every pass to within 2 s (passes whose
peak is within 1 deg of the mask are excluded: there the edges are ill-conditioned); the brute-force
1 s grid over every GP (``access_windows_bruteforce``) finds the same windows; invariants (ordered,
non-overlapping per (sat, gp), inside the horizon, eta <= limit inside).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from orbit_clock.frames import WGS84_B_KM, geodetic_to_ecef_km
from orbit_clock.ground_points import GroundPoints
from orbit_clock.propagation import MU_WGS84_KM3_S2, Constellation

__all__ = [
    "AccessWindows",
    "access_windows",
    "access_windows_bruteforce",
    "off_nadir_deg",
    "off_nadir_profile",
    "visibility_matrix",
]


def off_nadir_deg(sat_ecef_km: np.ndarray, gp_ecef_km: np.ndarray) -> np.ndarray:
    """Off-nadir angle [deg] from satellites to GPs, broadcasting over leading axes ([..., 3])."""
    s = np.asarray(sat_ecef_km, dtype=float)
    g = np.asarray(gp_ecef_km, dtype=float)
    d = g - s
    cos_eta = -np.einsum("...k,...k->...", s, d) / (np.linalg.norm(s, axis=-1) * np.linalg.norm(d, axis=-1))
    return np.rad2deg(np.arccos(np.clip(cos_eta, -1.0, 1.0)))


def _eta_grid(sat_ecef_km: np.ndarray, gp_ecef_km: np.ndarray):
    """(eta_deg [n_t, n_gp], near_side bool [n_t, n_gp]) for positions (n_t, 3) and GPs (n_gp, 3)."""
    s2 = np.einsum("tk,tk->t", sat_ecef_km, sat_ecef_km)[:, None]
    g2 = np.einsum("gk,gk->g", gp_ecef_km, gp_ecef_km)[None, :]
    sg = sat_ecef_km @ gp_ecef_km.T
    d = np.sqrt(np.maximum(s2 + g2 - 2.0 * sg, 1e-12))
    cos_eta = (s2 - sg) / (np.sqrt(s2) * d)
    eta = np.rad2deg(np.arccos(np.clip(cos_eta, -1.0, 1.0)))
    return eta, (sg - g2) > 0.0


def visibility_matrix(constellation: Constellation, sat, t_s, gps: GroundPoints, max_off_nadir_deg: float,
                      gp_ids=None):
    """For one satellite (index or name) on a time grid t_s [s]: (visible [n_t, n_gp] bool,
    off_nadir_deg [n_t, n_gp]) over all GPs or the given gp_ids (columns in that order)."""
    i = constellation.index(sat) if isinstance(sat, str) else int(sat)
    t = np.atleast_1d(np.asarray(t_s, dtype=float))
    r = constellation.positions_ecef_km_at(np.full(t.size, i), t)
    g = gps.ecef_km if gp_ids is None else gps.ecef_km[np.asarray(gp_ids)]
    eta, near = _eta_grid(r, g)
    return near & (eta <= max_off_nadir_deg), eta


@dataclass
class AccessWindows:
    """Access windows sorted by (sat, gp, start_s); arrays of equal length.

    sat: satellite index into ``sat_names``; gp: global GP id; start_s/end_s [s since epoch];
    min_off_nadir_deg: smallest off-nadir angle in the window [deg].
    """

    sat_names: list[str]
    sat: np.ndarray
    gp: np.ndarray
    start_s: np.ndarray
    end_s: np.ndarray
    min_off_nadir_deg: np.ndarray
    max_off_nadir_deg: float = 55.0
    t0_s: float = 0.0
    t1_s: float = 0.0
    meta: dict = field(default_factory=dict)
    gp_region: np.ndarray | None = None  # (n_gp,) region index of every GP id (GroundPoints.region_index)
    region_names: list[str] | None = None

    def region_id(self, region) -> int:
        """Region index from a name or an index (needs region_names)."""
        names = self.region_names or []
        if isinstance(region, (int, np.integer)):
            if not 0 <= region < len(names):
                raise ValueError(f"region index {region}: out of range 0..{len(names) - 1}")
            return int(region)
        if region not in names:
            raise ValueError(f"region {region!r}: not one of {names}")
        return names.index(region)

    @property
    def region(self) -> np.ndarray:
        """Region index of each window."""
        if self.gp_region is None:
            raise ValueError("these access windows carry no GP -> region table")
        return self.gp_region[self.gp]

    def __post_init__(self) -> None:
        order = np.lexsort((self.start_s, self.gp, self.sat))
        for k in ("sat", "gp", "start_s", "end_s", "min_off_nadir_deg"):
            setattr(self, k, np.asarray(getattr(self, k))[order])

    def __len__(self) -> int:
        return int(self.sat.size)

    def region_of(self, gps: GroundPoints) -> np.ndarray:
        return gps.region_index[self.gp]

    def select(self, mask) -> AccessWindows:
        return AccessWindows(self.sat_names, self.sat[mask], self.gp[mask], self.start_s[mask], self.end_s[mask],
                             self.min_off_nadir_deg[mask], self.max_off_nadir_deg, self.t0_s, self.t1_s, self.meta,
                             self.gp_region, self.region_names)

    def rows(self, gps: GroundPoints):
        """Yield dicts with the CLI columns: sat, region, gp, lat_deg, lon_deg, start_s, end_s, min_off_nadir_deg."""
        for k in range(len(self)):
            g = int(self.gp[k])
            yield {
                "sat": self.sat_names[int(self.sat[k])],
                "region": gps.region_names[int(gps.region_index[g])],
                "gp": g,
                "lat_deg": float(gps.lat_deg[g]),
                "lon_deg": float(gps.lon_deg[g]),
                "start_s": float(self.start_s[k]),
                "end_s": float(self.end_s[k]),
                "min_off_nadir_deg": float(self.min_off_nadir_deg[k]),
            }


def _runs(t: np.ndarray, eta: np.ndarray, vis: np.ndarray, limit_deg: float):
    """Windows from a sampled grid: (col, start_s, end_s, min_eta) arrays, edges interpolated."""
    n_t, n_g = vis.shape
    pad = np.zeros((1, n_g), dtype=np.int8)
    d = np.diff(np.concatenate([pad, vis.astype(np.int8), pad]), axis=0)  # (n_t+1, n_g)
    sg, sk = np.nonzero(d.T == 1)  # first visible sample k
    eg, ek = np.nonzero(d.T == -1)  # first non-visible sample after the run
    # starts
    m = limit_deg - eta  # >= 0 inside
    start = t[sk].copy()
    inner = sk > 0
    k = sk[inner]
    a, b = m[k - 1, sg[inner]], m[k, sg[inner]]
    frac = np.where(b != a, (0.0 - a) / np.where(b != a, b - a, 1.0), 0.0)
    start[inner] = t[k - 1] + np.clip(frac, 0.0, 1.0) * (t[k] - t[k - 1])
    end = t[ek - 1].copy()
    inner = ek < n_t
    k = ek[inner]
    a, b = m[k - 1, eg[inner]], m[k, eg[inner]]
    frac = np.where(b != a, (0.0 - a) / np.where(b != a, b - a, 1.0), 1.0)
    end[inner] = t[k - 1] + np.clip(frac, 0.0, 1.0) * (t[k] - t[k - 1])
    flat = np.concatenate([eta.T.ravel(), [np.inf]])
    idx = np.column_stack([sg * n_t + sk, eg * n_t + ek]).ravel()
    mins = np.minimum.reduceat(flat, idx)[::2] if idx.size else np.empty(0)
    return sg, start, end, mins


def _grid(t0_s: float, t1_s: float, step_s: float) -> np.ndarray:
    t = np.arange(t0_s, t1_s, step_s, dtype=float)
    return np.append(t, t1_s) if t.size == 0 or t[-1] < t1_s else t


def _max_access_angle_rad(r_sat_max_km: float, max_off_nadir_deg: float) -> float:
    """Upper bound of the Earth-central angle between a satellite and a GP it can see."""
    r_g = WGS84_B_KM
    eta = np.deg2rad(max_off_nadir_deg)
    x = r_sat_max_km / r_g * np.sin(eta)
    horizon = np.arccos(r_g / r_sat_max_km)
    return float(horizon if x >= 1.0 else min(np.arcsin(x) - eta, horizon))


def access_windows(constellation: Constellation, gps: GroundPoints, t0_s: float, t1_s: float,
                   max_off_nadir_deg: float, *, coarse_step_s: float = 20.0, fine_step_s: float = 1.0,
                   sats=None) -> AccessWindows:
    """All access windows in [t0_s, t1_s] of the satellites (all, or indices ``sats``) to the GPs."""
    if not t1_s > t0_s:
        raise ValueError(f"access_windows: empty horizon [{t0_s}, {t1_s}] s")
    if not (0 < fine_step_s <= coarse_step_s):
        raise ValueError(f"access_windows: need 0 < fine_step_s ({fine_step_s}) <= coarse_step_s ({coarse_step_s})")
    sat_list = np.arange(len(constellation)) if sats is None else np.asarray(sats, dtype=int)
    tc = _grid(t0_s, t1_s, coarse_step_s)
    r = constellation.positions_ecef_km(tc)[sat_list]  # (n_s, n_c, 3)
    rn = np.linalg.norm(r, axis=-1)
    lam = _max_access_angle_rad(float(rn.max()) * 1.001, max_off_nadir_deg)
    rate_rad_s = 1.1 * (float(np.sqrt(MU_WGS84_KM3_S2 / rn.min() ** 3)) + 7.3e-5)
    centers = geodetic_to_ecef_km(gps.region_center_lat_deg, gps.region_center_lon_deg, 0.0)
    cu = centers / np.linalg.norm(centers, axis=-1, keepdims=True)
    ang = np.arccos(np.clip(np.einsum("sck,rk->src", r / rn[..., None], cu), -1.0, 1.0))  # (n_s, n_r, n_c)
    thr = lam + 1.01 * gps.region_half_diag_km / WGS84_B_KM + rate_rad_s * coarse_step_s + 1e-3
    flag = ang <= thr[None, :, None]
    out = {k: [] for k in ("sat", "gp", "start", "end", "min")}
    n_fine = 0
    for si, ri in zip(*np.nonzero(flag.any(axis=2))):
        f = np.concatenate([[0], flag[si, ri].astype(np.int8), [0]])
        dd = np.diff(f)
        for a, b in zip(np.flatnonzero(dd == 1), np.flatnonzero(dd == -1) - 1):
            t = _grid(tc[a], tc[b], fine_step_s) if b > a else np.array([tc[a]])
            n_fine += t.size
            sat = int(sat_list[si])
            rr = constellation.positions_ecef_km_at(np.full(t.size, sat), t)
            gids = gps.in_region(int(ri))
            eta, near = _eta_grid(rr, gps.ecef_km[gids])
            col, st, en, mn = _runs(t, eta, near & (eta <= max_off_nadir_deg), max_off_nadir_deg)
            out["sat"].append(np.full(col.size, sat))
            out["gp"].append(gids[col])
            out["start"].append(st), out["end"].append(en), out["min"].append(mn)
    cat = (lambda k, dt: np.concatenate(out[k]).astype(dt) if out[k] else np.empty(0, dt))
    return AccessWindows(list(constellation.names), cat("sat", np.int64), cat("gp", np.int64), cat("start", float),
                         cat("end", float), cat("min", float), max_off_nadir_deg, float(t0_s), float(t1_s),
                         {"coarse_step_s": coarse_step_s, "fine_step_s": fine_step_s,
                          "fine_samples": n_fine, "coarse_samples": int(tc.size * sat_list.size)},
                         gps.region_index, list(gps.region_names))


def access_windows_bruteforce(constellation: Constellation, gps: GroundPoints, t0_s: float, t1_s: float,
                              max_off_nadir_deg: float, *, step_s: float = 1.0, sats=None) -> AccessWindows:
    """Reference: every GP of every satellite on a uniform grid (no prefilter). Slow; the oracle of the tests and benchmarks."""
    sat_list = np.arange(len(constellation)) if sats is None else np.asarray(sats, dtype=int)
    t = _grid(t0_s, t1_s, step_s)
    out = {k: [] for k in ("sat", "gp", "start", "end", "min")}
    chunk = 2000
    for sat in sat_list:
        r_all = constellation.positions_ecef_km_at(np.full(t.size, sat), t)
        eta = np.empty((t.size, len(gps)))
        vis = np.empty((t.size, len(gps)), dtype=bool)
        for c0 in range(0, t.size, chunk):
            e, near = _eta_grid(r_all[c0:c0 + chunk], gps.ecef_km)
            eta[c0:c0 + chunk], vis[c0:c0 + chunk] = e, near & (e <= max_off_nadir_deg)
        col, st, en, mn = _runs(t, eta, vis, max_off_nadir_deg)
        out["sat"].append(np.full(col.size, sat)), out["gp"].append(col)
        out["start"].append(st), out["end"].append(en), out["min"].append(mn)
    cat = (lambda k, dt: np.concatenate(out[k]).astype(dt) if out[k] else np.empty(0, dt))
    return AccessWindows(list(constellation.names), cat("sat", np.int64), cat("gp", np.int64), cat("start", float),
                         cat("end", float), cat("min", float), max_off_nadir_deg, float(t0_s), float(t1_s),
                         {"step_s": step_s}, gps.region_index, list(gps.region_names))


def off_nadir_profile(constellation: Constellation, gps: GroundPoints, windows: AccessWindows, k: int,
                      step_s: float = 1.0):
    """(t_s, off_nadir_deg) of window k sampled every step_s [s] from start_s to end_s inclusive."""
    t = _grid(float(windows.start_s[k]), float(windows.end_s[k]), step_s)
    r = constellation.positions_ecef_km_at(np.full(t.size, int(windows.sat[k])), t)
    return t, off_nadir_deg(r, gps.ecef_km[int(windows.gp[k])])
