"""Ground-point access: when each satellite can point at each GP within its field of regard.

Model (Nag et al. 2019, section 3-5): a satellite at r_sat (ECEF) can image a GP at r_gp when the
off-nadir angle eta = angle(-r_sat, r_gp - r_sat) (geocentric nadir) is <= the field of regard
(paper: 55 deg) and the GP is on the near side of the Earth ((r_sat - r_gp) . r_gp > 0). At 710 km
55 deg off-nadir is 24.45 deg elevation (about 1175 km ground range).

This module is the project's one field of regard: :func:`off_nadir_deg` (the angle),
:func:`for_central_angle_rad` (the largest Earth-central angle the FOR reaches, the bound every
pre-filter builds on), :func:`for_mask` (the FOR test of the scheduler's instances) and
:class:`RegionPrefilter` (which regions may enter a satellite's FOR in a time interval).

Search, coarse then refine (``access_windows``):
1. coarse grid (default 20 s): angle between each satellite and each region centre; a region is a
   candidate at a sample when that angle is within the largest possible access angle
   (:func:`for_central_angle_rad` of the highest satellite radius and the polar Earth radius) + the
   region's half diagonal + the satellite's ground-relative angular motion over one coarse step. If
   a GP is visible at t in [t_k, t_k+1], both t_k and t_k+1 are flagged, so no window escapes a
   candidate interval.
2. candidate interval on a fine grid (default 1 s) with SGP4: eta for every GP of the region; runs of
   visible samples are windows; each edge is placed by linear interpolation of (limit - eta)
   between the bracketing samples (eta is smooth: the error is milliseconds, far below 1 s).
   min_off_nadir_deg is the smallest eta on the fine samples of the window.
The field of regard may differ by satellite (a mixed fleet, bringup/scenario/fleet.py):
``max_off_nadir_deg`` is then one angle per satellite of the constellation, the coarse bound is
taken with the largest and each satellite's runs with its own.
Windows shorter than one fine step can be missed (a grazing pass that dips below the limit between
two samples); windows are clipped to [t0_s, t1_s].

How we know it is right (tests/unit/test_orbit_access.py): the off-nadir angle against the closed
form of the plane triangle (centre, satellite, GP) and an atan2 formula to 1e-9 deg; the FOR bound
against a brute-force search of the central angles; the FOR mask's row pre-filter equal to the test of
every pair; the region pre-filter never drops a GP the exact mask keeps (FOR inside and beyond the
horizon); skyfield ``find_events`` with the elevation mask equivalent to the off-nadir limit agrees
on every pass to within 2 s (passes whose peak is within 1 deg of the mask are excluded: there the
edges are ill-conditioned); the brute-force 1 s grid over every GP (``access_windows_bruteforce``)
finds the same windows; invariants (ordered, non-overlapping per (sat, gp), inside the horizon,
eta <= limit inside). Every observation a whole run executes is within the field of regard, by an
off-nadir angle recomputed with sgp4 and WGS-84 written out in tests/system/test_observation_physics.py.
One angle per satellite (tests/unit/test_fleet.py): the windows equal each satellite's alone with its
own angle and the brute-force grid's; for catalogue satellites skyfield's own TLE reader and frames
give the same windows within 2 s (tests/system/test_catalogue_runs.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from orbit_clock import access_kernels
from orbit_clock.frames import WGS84_B_KM, geodetic_to_ecef_km
from orbit_clock.ground_points import GroundPoints
from orbit_clock.propagation import MU_WGS84_KM3_S2, Constellation
from orbit_clock.windows import time_grid, true_runs

__all__ = [
    "AccessWindows",
    "RegionPrefilter",
    "access_windows",
    "access_windows_bruteforce",
    "for_central_angle_rad",
    "for_mask",
    "off_nadir_deg",
    "off_nadir_profile",
    "visibility_matrix",
]


def off_nadir_deg(sat_ecef_km: np.ndarray, gp_ecef_km: np.ndarray) -> np.ndarray:
    """Off-nadir angle [deg] from satellites to GPs, broadcasting over leading axes ([..., 3]).

    The angle at the satellite between geocentric nadir (-r_sat) and the line of sight (r_gp - r_sat).
    """
    s = np.asarray(sat_ecef_km, dtype=float)
    g = np.asarray(gp_ecef_km, dtype=float)
    d = g - s
    cos_eta = -np.einsum("...k,...k->...", s, d) / (np.linalg.norm(s, axis=-1) * np.linalg.norm(d, axis=-1))
    return np.rad2deg(np.arccos(np.clip(cos_eta, -1.0, 1.0)))


def for_central_angle_rad(r_sat_km: float, r_ground_km: float, max_off_nadir_deg: float) -> float:
    """Largest Earth-central angle [rad] between a satellite at radius ``r_sat_km`` and a ground point
    at radius ``r_ground_km`` that is within ``max_off_nadir_deg`` of nadir and above its horizon.

    Triangle Earth centre O, satellite S (|OS| = r), ground point P (|OP| = rho): the off-nadir angle
    eta at S and the central angle lam at O obey sin(eta + lam) = r sin(eta) / rho for the near
    intersection of the line of sight with the sphere, so lam = arcsin(r sin(eta) / rho) - eta while
    that arcsin exists and eta < 90 deg; beyond, the line of sight misses the Earth and the bound is
    the horizon, arccos(rho / r). The bound grows with r and shrinks with rho, so the largest
    satellite radius and the smallest ground radius give one bound for every pair. A satellite at or
    below the ground radius has no bound (pi).
    """
    r, rho = float(r_sat_km), float(r_ground_km)
    if not (r > rho > 0.0):
        return math.pi
    eta = math.radians(min(max(float(max_off_nadir_deg), 0.0), 180.0))
    horizon = math.acos(rho / r)
    x = r * math.sin(eta) / rho
    if x >= 1.0 or eta >= math.pi / 2:
        return horizon
    return min(math.asin(x) - eta, horizon)


def for_mask(sat_pos_km: np.ndarray, gp_ecef_km: np.ndarray, max_off_nadir_deg: float) -> np.ndarray:
    """(T, G) True where GP g is in the field of regard of the satellite at sat_pos_km[t] (ECEF km):
    within ``max_off_nadir_deg`` of nadir (:func:`off_nadir_deg`) and on the near side of the Earth.

    Only the (time, GP chunk) pairs where some GP may be in the FOR are tested (:func:`_for_chunks`,
    from :func:`for_central_angle_rad`), by the compiled :func:`orbit_clock.access_kernels.for_codes`;
    the pairs it leaves undecided (near the FOR's edge or the horizon) get the reference arithmetic of
    :func:`_for_mask_all`, so the mask is the same as :func:`_for_mask_all`'s bit for bit
    (tests/unit/test_orbit_access.py compares them).
    """
    sat = np.ascontiguousarray(sat_pos_km, np.float64)
    gp = np.ascontiguousarray(gp_ecef_km, np.float64)
    chunks = _for_chunks(sat, gp, max_off_nadir_deg) if 0.0 <= max_off_nadir_deg <= 180.0 else None
    if chunks is None:
        return _for_mask_all(sat, gp, max_off_nadir_deg)
    starts, ends, ok = chunks
    rows = np.flatnonzero(ok.any(axis=1))
    codes = np.zeros((sat.shape[0], gp.shape[0]), dtype=np.uint8)
    if len(rows):
        cos_lim = math.cos(math.radians(float(max_off_nadir_deg)))
        if access_kernels.for_codes(sat, gp, rows, starts, ends, np.ascontiguousarray(ok[rows]), cos_lim, codes):
            tt, gg = np.nonzero(codes == 2)
            s, g = sat[tt], gp[gg]
            codes[tt, gg] = (off_nadir_deg(s, g) <= max_off_nadir_deg) & (np.sum((s - g) * g, axis=-1) > 0.0)
    return codes.view(bool)


def _for_mask_all(sat_pos_km: np.ndarray, gp_ecef_km: np.ndarray, max_off_nadir_deg: float) -> np.ndarray:
    """The FOR test on every (time, GP) pair: off-nadir angle and the GP's local horizon."""
    sat = np.asarray(sat_pos_km, np.float64)[:, None, :]
    gp = np.asarray(gp_ecef_km, np.float64)[None, :, :]
    off = off_nadir_deg(sat, gp)
    above = np.sum((sat - gp) * gp, axis=-1) > 0.0
    return (off <= max_off_nadir_deg) & above


# Earth central angle margin [deg] of the row pre-filter (its own rounding is ~1e-13 deg)
_FOR_ROWS_MARGIN_DEG = 1.0


def _for_rows(sat: np.ndarray, gp: np.ndarray, max_off_nadir_deg: float, chunk: int = 64) -> np.ndarray | None:
    """Time rows where some GP may be in the FOR (a superset, :func:`_for_chunks`), or None to test
    every row."""
    chunks = _for_chunks(sat, gp, max_off_nadir_deg, chunk)
    return None if chunks is None else np.flatnonzero(chunks[2].any(axis=1))


def _for_chunks(sat: np.ndarray, gp: np.ndarray, max_off_nadir_deg: float,
                chunk: int = 64) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """GP chunks and, per time row, the chunks some GP of which may be in the FOR (a superset):
    ``(starts, ends, ok)`` with ``ok`` (T, chunks) bool, or None to test every pair.

    A chunk is kept at a row when some GP of it may be within :func:`for_central_angle_rad` (largest
    satellite radius, smallest GP radius) plus ``_FOR_ROWS_MARGIN_DEG`` of the sub-satellite point.
    The GPs are taken in chunks of ``chunk`` consecutive ids (a region's GPs are consecutive): a chunk
    is a spherical cap (the mean of its unit vectors and the largest angle from it to one of them),
    and by the triangle inequality no GP of it is within the bound of a sub-satellite point farther
    than the bound plus the cap's radius from the cap's centre - one cosine per time and chunk
    instead of one per time and GP. A chunk also ends where consecutive GPs are more than 0.5 deg
    apart (the next region), so caps stay small.
    """
    if sat.ndim != 2 or gp.ndim != 2 or sat.shape[1] != 3 or gp.shape[1] != 3 or len(sat) < 2 or len(gp) == 0:
        return None
    r_s = np.sqrt(np.einsum("ij,ij->i", sat, sat))
    caps = _gp_caps(gp, chunk)
    if caps is None or not np.all(np.isfinite(r_s)) or r_s.min() <= 0:
        return None
    rho, starts, ends, centre, radius = caps
    r = float(r_s.max())
    if r <= rho:
        return None  # a satellite at or below a GP's radius: no simple bound, test every pair
    lam = min(math.pi, for_central_angle_rad(r, rho, max_off_nadir_deg) + math.radians(_FOR_ROWS_MARGIN_DEG))
    reach = np.minimum(math.pi, lam + radius + 1e-9)
    cos_ang = (sat / r_s[:, None]) @ centre.T  # (T, chunks)
    return starts, ends, cos_ang >= np.cos(reach)[None, :]


# GP set (its bytes and the chunk length) -> its caps (_gp_caps): planners test the same GPs (a
# region's, the planned satellite's) against many tracks
_GP_CAPS: dict = {}
_GP_CAPS_MAX = 256


def _gp_caps(gp: np.ndarray, chunk: int):
    """The GP part of :func:`_for_chunks`: (smallest GP radius, chunk starts, ends, cap centres, cap
    radii), or None when a GP's radius is not finite and positive; remembered for the last
    ``_GP_CAPS_MAX`` GP sets (the same numbers: computed once from the same bytes; callers do not
    write to them)."""
    key = (gp.tobytes(), chunk)
    got = _GP_CAPS.get(key, False)
    if got is not False:
        return got
    r_g = np.sqrt(np.einsum("ij,ij->i", gp, gp))
    if not np.all(np.isfinite(r_g)) or r_g.min() <= 0:
        got = None
    else:
        ug = gp / r_g[:, None]
        n = len(ug)
        jump = np.flatnonzero(np.einsum("ij,ij->i", ug[1:], ug[:-1]) < math.cos(math.radians(0.5))) + 1
        starts = np.union1d(np.arange(0, n, chunk), jump)
        centre = np.add.reduceat(ug, starts, axis=0)
        centre /= np.linalg.norm(centre, axis=1)[:, None]
        which = np.repeat(np.arange(len(starts)), np.diff(np.append(starts, n)))
        cos_to_centre = np.clip(np.einsum("ij,ij->i", ug, centre[which]), -1.0, 1.0)
        radius = np.zeros(len(starts))
        np.maximum.at(radius, which, np.arccos(cos_to_centre))
        ends = np.append(starts[1:], n)
        # (not marked read-only: the compiled FOR test takes starts and ends as they are typed now)
        got = (float(r_g.min()), starts.astype(np.int64), ends.astype(np.int64), centre, radius)
    if len(_GP_CAPS) >= _GP_CAPS_MAX:
        _GP_CAPS.clear()
    _GP_CAPS[key] = got
    return got


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
    t = np.atleast_1d(np.asarray(t_s, dtype=float))
    r = constellation.track_ecef_km(sat, t)
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
    max_off_nadir_deg: float | list[float] = 55.0  # one field of regard, or one per satellite
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
    n_t = vis.shape[0]
    sg, sk, ek = true_runs(vis.T)  # GP column, first visible sample, first non-visible after the run
    eg = sg
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


class RegionPrefilter:
    """The GPs of the regions that may enter a satellite's field of regard during [t0_s, t1_s].

    A cheap pre-filter for the scheduler, which then computes the exact FOR mask on its grid: a
    region is kept when, at some sample of a ``step_s`` ephemeris over [0, horizon_s], the Earth
    central angle between the sub-satellite point and the region centre (the mean of its GP unit
    vectors) is within the FOR's central angle (:func:`for_central_angle_rad` from the highest
    orbit radius and the polar Earth radius) plus the region's angular radius plus the satellite's
    ground motion over one sample (8 km/s upper bound) plus 1 deg.

    The test is made once per run for every (region, satellite, sample) from the orbits, which
    every satellite knows (they are public, not observations of the field), and kept as a pass
    index: per region, per satellite, the running count of the samples at which it passes, so
    that whether a satellite passes a region in an interval is one subtraction.
    :meth:`candidate_gp_ids` answers for one satellite, :meth:`passing` for many satellites and the
    regions of a set of GPs at once, and :meth:`first_pass_s` when each of them first passes those
    regions (the joint planner's partner choice, sat_node/scheduler/planner.py ``Planner.group``). The ephemeris and the index are computed on
    the first query and not pickled.

    How we know it is right (tests/unit/test_region_passes.py): the index gives, for random
    satellites and intervals, the regions the angle test on that interval's samples alone keeps
    (the pre-filter as first written), :meth:`passing` equals ``candidate_gp_ids`` intersected
    with the GPs, satellite by satellite, and :meth:`first_pass_s` less one step is never after the
    first time of the exact FOR mask over the GPs on a 1-s grid.
    """

    def __init__(self, constellation: Constellation, gps: GroundPoints, horizon_s: float,
                 max_off_nadir_deg: float, step_s: float = 30.0):
        self.constellation = constellation
        self.gps = gps
        self.horizon_s = float(horizon_s)
        self.max_off_nadir_deg = float(np.max(max_off_nadir_deg))  # per satellite: the widest bounds them all
        self.step_s = float(step_s)
        self._coarse: dict | None = None

    def __getstate__(self):
        return {k: v for k, v in self.__dict__.items() if k != "_coarse"} | {"_coarse": None}

    def _samples(self, c: dict, t0_s, t1_s) -> tuple:
        """The first and one past the last sample index of [t0_s, t1_s] (arrays or floats)."""
        k0 = np.clip(np.floor(np.asarray(t0_s, np.float64) / self.step_s).astype(np.int64), 0, c["n_samples"])
        k1 = np.minimum(c["n_samples"] - 1, np.ceil(np.asarray(t1_s, np.float64) / self.step_s).astype(np.int64))
        return k0, np.maximum(k0, k1 + 1)

    def candidate_gp_ids(self, sat: str, t0_s: float, t1_s: float) -> np.ndarray:
        """GP ids (int64, by region in region order) that may be in ``sat``'s FOR in [t0_s, t1_s]."""
        c = self._coarse if self._coarse is not None else self._build()
        i = self.constellation.index(sat)
        k0, k1 = self._samples(c, t0_s, t1_s)
        cum = c["passes"][:, i]  # (R, K + 1)
        keep = np.flatnonzero(cum[:, k1] > cum[:, k0])
        if len(keep) == 0:
            return np.zeros(0, dtype=np.int64)
        return np.concatenate([c["region_gps"][r] for r in keep])

    def passing(self, gp_ids: np.ndarray, sat_idx: np.ndarray, t0_s: np.ndarray, t1_s: float) -> np.ndarray:
        """(len(sat_idx),) True where satellite ``sat_idx[j]`` may have one of the GPs ``gp_ids`` in
        its FOR in [t0_s[j], t1_s]: where ``candidate_gp_ids`` over that interval holds one of them."""
        c = self._coarse if self._coarse is not None else self._build()
        sat_idx = np.asarray(sat_idx, dtype=np.int64)
        regions = np.unique(self.gps.region_index[np.asarray(gp_ids, dtype=np.int64)])
        regions = regions[(regions >= 0) & (regions < len(c["region_gps"]))]
        out = np.zeros(len(sat_idx), dtype=bool)
        if len(sat_idx) == 0:
            return out
        k0, k1 = self._samples(c, t0_s, t1_s)
        k0 = np.broadcast_to(k0, sat_idx.shape)
        k1 = np.maximum(k0, k1)
        for r in regions:
            cum = c["passes"][r]  # (S, K + 1)
            out |= cum[sat_idx, k1] > cum[sat_idx, k0]
        return out

    def first_pass_s(self, gp_ids: np.ndarray, sat_idx: np.ndarray, t0_s: np.ndarray, t1_s: float) -> np.ndarray:
        """(len(sat_idx),) the first sample time [s] in [t0_s[j], t1_s] (the samples ``passing`` reads)
        at which satellite ``sat_idx[j]`` passes a region of the GPs ``gp_ids``; inf where none.
        A GP of those regions in the satellite's FOR at a time t between two samples flags both (the
        margin holds the motion over a sample), so no such t from the first of those samples on is
        earlier than this time less one step."""
        c = self._coarse if self._coarse is not None else self._build()
        sat_idx = np.asarray(sat_idx, dtype=np.int64)
        regions = np.unique(self.gps.region_index[np.asarray(gp_ids, dtype=np.int64)])
        regions = regions[(regions >= 0) & (regions < len(c["region_gps"]))]
        k0, k1 = self._samples(c, t0_s, t1_s)
        k0 = np.broadcast_to(k0, sat_idx.shape)
        k1 = np.broadcast_to(np.maximum(k0, k1), sat_idx.shape)
        out = np.full(len(sat_idx), np.inf)
        for j, i in enumerate(sat_idx.tolist()):
            a, b = int(k0[j]), int(k1[j])
            for r in regions:
                row = c["passes"][r, i]
                if row[b] > row[a]:  # passes at a sample in [a, b): the first is where the count rises
                    m = int(np.searchsorted(row[a:b + 1], row[a] + 1, side="left")) + a
                    out[j] = min(out[j], (m - 1) * self.step_s)
        return out

    def _build(self) -> dict:
        t = np.arange(0.0, self.horizon_s + self.step_s, self.step_s)
        pos = self.constellation.positions_ecef_km(t)
        r = np.linalg.norm(pos, axis=2)
        unit = pos / r[..., None]
        gps = self.gps
        n_reg = len(gps.region_names)
        region_gps = [np.flatnonzero(gps.region_index == k).astype(np.int64) for k in range(n_reg)]
        region_unit = np.zeros((n_reg, 3))
        half_ang = np.zeros(n_reg)
        for k in range(n_reg):
            g = gps.ecef_km[region_gps[k]]
            ctr = g.mean(axis=0)
            ctr /= np.linalg.norm(ctr)
            region_unit[k] = ctr
            gu = g / np.linalg.norm(g, axis=1, keepdims=True)
            half_ang[k] = float(np.max(np.arccos(np.clip(gu @ ctr, -1, 1)))) if len(g) else 0.0
        lam = for_central_angle_rad(float(r.max()), WGS84_B_KM, self.max_off_nadir_deg)
        v_ang = 8.0 * self.step_s / WGS84_B_KM  # ground motion over one sample [rad], 8 km/s upper bound
        lim = lam + half_ang + v_ang + math.radians(1.0)
        cos_limit = np.cos(np.minimum(lim, math.pi))
        n_sat, n_t = unit.shape[:2]
        # the pass index: passes[r, i, k] = samples before k at which satellite i passes region r; 2 bytes
        # each up to 65535 samples (22 days at 30 s), 4 beyond (bringup/scenario/limits.py counts more
        # for the access search's angles)
        passes = np.zeros((n_reg, n_sat, n_t + 1), dtype=np.uint16 if n_t < 2**16 - 1 else np.uint32)
        for i in range(n_sat):
            hit = (unit[i] @ region_unit.T) >= cos_limit[None, :]  # (K, R): one satellite's samples
            np.cumsum(hit.T, axis=1, out=passes[:, i, 1:])
        self._coarse = {"region_gps": region_gps, "passes": passes, "n_samples": n_t}
        return self._coarse


def _per_sat(max_off_nadir_deg, n: int) -> np.ndarray:
    """The field of regard [deg] of each of ``n`` satellites from one angle or one per satellite."""
    lim = np.asarray(max_off_nadir_deg, dtype=float)
    if lim.ndim == 0:
        return np.full(n, float(lim))
    if lim.shape != (n,):
        raise ValueError(f"max_off_nadir_deg: one angle or one per satellite ({n}), got {lim.shape}")
    return lim


def _as_reported(lim: np.ndarray) -> float | list[float]:
    return float(lim[0]) if lim.size and (lim == lim[0]).all() else [float(x) for x in lim]


def access_windows(constellation: Constellation, gps: GroundPoints, t0_s: float, t1_s: float,
                   max_off_nadir_deg, *, coarse_step_s: float = 20.0, fine_step_s: float = 1.0,
                   sats=None) -> AccessWindows:
    """All access windows in [t0_s, t1_s] of the satellites (all, or indices ``sats``) to the GPs;
    ``max_off_nadir_deg``: one field of regard [deg], or one per satellite of the constellation."""
    if not t1_s > t0_s:
        raise ValueError(f"access_windows: empty horizon [{t0_s}, {t1_s}] s")
    if not (0 < fine_step_s <= coarse_step_s):
        raise ValueError(f"access_windows: need 0 < fine_step_s ({fine_step_s}) <= coarse_step_s ({coarse_step_s})")
    lims = _per_sat(max_off_nadir_deg, len(constellation))
    sat_list = np.arange(len(constellation)) if sats is None else np.asarray(sats, dtype=int)
    tc = time_grid(t0_s, t1_s, coarse_step_s)
    r = constellation.positions_ecef_km(tc)[sat_list]  # (n_s, n_c, 3)
    rn = np.linalg.norm(r, axis=-1)
    lam = for_central_angle_rad(float(rn.max()) * 1.001, WGS84_B_KM, float(lims[sat_list].max()))
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
            t = time_grid(tc[a], tc[b], fine_step_s) if b > a else np.array([tc[a]])
            n_fine += t.size
            sat = int(sat_list[si])
            rr = constellation.track_ecef_km(sat, t)
            gids = gps.in_region(int(ri))
            eta, near = _eta_grid(rr, gps.ecef_km[gids])
            lim = float(lims[sat])
            col, st, en, mn = _runs(t, eta, near & (eta <= lim), lim)
            out["sat"].append(np.full(col.size, sat))
            out["gp"].append(gids[col])
            out["start"].append(st), out["end"].append(en), out["min"].append(mn)
    cat = (lambda k, dt: np.concatenate(out[k]).astype(dt) if out[k] else np.empty(0, dt))
    return AccessWindows(list(constellation.names), cat("sat", np.int64), cat("gp", np.int64), cat("start", float),
                         cat("end", float), cat("min", float), _as_reported(lims), float(t0_s), float(t1_s),
                         {"coarse_step_s": coarse_step_s, "fine_step_s": fine_step_s,
                          "fine_samples": n_fine, "coarse_samples": int(tc.size * sat_list.size)},
                         gps.region_index, list(gps.region_names))


def access_windows_bruteforce(constellation: Constellation, gps: GroundPoints, t0_s: float, t1_s: float,
                              max_off_nadir_deg: float, *, step_s: float = 1.0, sats=None) -> AccessWindows:
    """Reference: every GP of every satellite on a uniform grid (no prefilter). Slow; the oracle of the tests and benchmarks."""
    lims = _per_sat(max_off_nadir_deg, len(constellation))
    sat_list = np.arange(len(constellation)) if sats is None else np.asarray(sats, dtype=int)
    t = time_grid(t0_s, t1_s, step_s)
    out = {k: [] for k in ("sat", "gp", "start", "end", "min")}
    chunk = 2000
    for sat in sat_list:
        r_all = constellation.track_ecef_km(sat, t)
        eta = np.empty((t.size, len(gps)))
        vis = np.empty((t.size, len(gps)), dtype=bool)
        for c0 in range(0, t.size, chunk):
            e, near = _eta_grid(r_all[c0:c0 + chunk], gps.ecef_km)
            eta[c0:c0 + chunk], vis[c0:c0 + chunk] = e, near & (e <= lims[sat])
        col, st, en, mn = _runs(t, eta, vis, float(lims[sat]))
        out["sat"].append(np.full(col.size, sat)), out["gp"].append(col)
        out["start"].append(st), out["end"].append(en), out["min"].append(mn)
    cat = (lambda k, dt: np.concatenate(out[k]).astype(dt) if out[k] else np.empty(0, dt))
    return AccessWindows(list(constellation.names), cat("sat", np.int64), cat("gp", np.int64), cat("start", float),
                         cat("end", float), cat("min", float), _as_reported(lims), float(t0_s), float(t1_s),
                         {"step_s": step_s}, gps.region_index, list(gps.region_names))


def off_nadir_profile(constellation: Constellation, gps: GroundPoints, windows: AccessWindows, k: int,
                      step_s: float = 1.0):
    """(t_s, off_nadir_deg) of window k sampled every step_s [s] from start_s to end_s inclusive."""
    t = time_grid(float(windows.start_s[k]), float(windows.end_s[k]), step_s)
    r = constellation.track_ecef_km(int(windows.sat[k]), t)
    return t, off_nadir_deg(r, gps.ecef_km[int(windows.gp[k])])
