"""OSSE flood-value forecast: the a-priori value of each ground point (GP) per 15-min slot.

What it implements: the value input of Nag et al., "Autonomous Scheduling of Agile Spacecraft
Constellations with Delay Tolerant Networking for Reactive Imaging" (ICAPS SPARK 2019), section 5,
where an Observing System Simulation Experiment (WRF-Hydro driven flood model) gives every GP an
integer value 1..256 per 15-min slot. We do not have their WRF-Hydro run, so the ``synthetic``
source is a seeded, physically-flavoured stand-in (docs/design.md section 1):

* **Watersheds.** Each region gets a static flood susceptibility ``s(x, y)`` in [0.25, 1]: 2-3
  meandering river channels (Gaussian cross-section, 4-10 km wide) and 1-3 low-lying basins.
* **Storm cells.** A Poisson number of convective cells per region (mean 7 over 6 h, at least 3),
  born at random times (some already active at t = 0) upwind of the region, moving with a common
  steering wind (8-40 km/h, one direction per region, +-25 deg per cell), each with a sinusoidal
  life cycle (1-3.5 h) in peak rain rate (15-70 mm/h) and radius (grows from 40 % to 100 % of
  5-15 km at mid-life and shrinks again).
* **Flood water.** Per GP, rain is accumulated with exponential drainage (e-folding 2 h), sub-sampled
  3 times per slot: ``F_n = F_{n-1} exp(-dt/tau) + rain_n dt``.
* **Value.** ``v = 1 + round(255 (1 - exp(-s (b + F / F0))))`` with background ``b = 0.04`` and
  ``F0 = 25 mm``: integer, bounded in 1..256 by construction, spatially clustered (cells and rivers
  are tens of km across, GPs 8 km apart) and changing within the horizon (cells move, grow, decay,
  water drains).

Each region draws from its own random stream seeded by ``(seed, crc32(region name))``, so a region's
field does not depend on which other regions the scenario lists.

The ``file`` source (``ground_station.osse_io``) loads a gridded (time, lat, lon) value field from
NPZ, CSV or NetCDF-3 and interpolates it onto the GPs; ``ground_station.osse_sources`` names both
sources for the scenario (``value.osse_source``). This module imports neither.

How we know it is right (oracle, ``tests/unit/test_osse.py``): the same seed reproduces the field
bit for bit and another seed changes it; every value is an integer in 1..256; Moran's I over
8-neighbour GP adjacency is clearly positive and far above the same values shuffled over the GPs
(the permutation null, I ~ -1/(n-1)); values change between the first and last slots; a field
written to NPZ / CSV / NetCDF and loaded back onto the same GPs is identical; bad files raise
:class:`OsseError` with one line naming the file and what is wrong.

Not done: no hydrology (no flow routing between GPs, no terrain data); no dateline-crossing regions
in the file loader.
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = [
    "VALUE_MAX",
    "VALUE_MIN",
    "GroundPointArrays",
    "OsseError",
    "OsseField",
    "SyntheticParams",
    "as_ground_point_arrays",
    "local_km",
    "synthetic_field",
]

VALUE_MIN = 1
VALUE_MAX = 256
_KM_PER_DEG_LAT = 110.574
_KM_PER_DEG_LON_EQ = 111.320


class OsseError(ValueError):
    """Unusable OSSE input (file, ground points, query); the message is one line naming what."""


# --------------------------------------------------------------------------------------------
# Ground points
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class GroundPointArrays:
    """Plain GP arrays: lat_deg, lon_deg [deg] and region_index (index into scenario regions)."""

    lat_deg: np.ndarray
    lon_deg: np.ndarray
    region_index: np.ndarray

    def __len__(self) -> int:
        return int(self.lat_deg.shape[0])


def as_ground_point_arrays(gps: Any) -> GroundPointArrays:
    """Normalise ground points to :class:`GroundPointArrays`.

    Accepts an object with attributes ``lat_deg``, ``lon_deg`` and ``region_index`` (or
    ``region_idx`` / ``region``), a mapping with those keys, or a 3-tuple of arrays
    ``(lat_deg, lon_deg, region_index)``. Raises :class:`OsseError` on bad shapes or values.
    """
    if isinstance(gps, GroundPointArrays):
        return gps

    def pick(names: Sequence[str]):
        for n in names:
            if isinstance(gps, Mapping) and n in gps:
                return gps[n]
            if not isinstance(gps, Mapping) and hasattr(gps, n):
                return getattr(gps, n)
        return None

    if isinstance(gps, (tuple, list)) and len(gps) == 3:
        lat, lon, reg = gps
    else:
        lat, lon = pick(["lat_deg"]), pick(["lon_deg"])
        reg = pick(["region_index", "region_idx", "region"])
        if lat is None or lon is None or reg is None:
            raise OsseError("ground points: need lat_deg, lon_deg and region_index (attributes, keys or a 3-tuple)")
    lat = np.asarray(lat, dtype=np.float64).ravel()
    lon = np.asarray(lon, dtype=np.float64).ravel()
    reg_raw = np.asarray(reg).ravel()
    if not (lat.shape == lon.shape == reg_raw.shape):
        raise OsseError(f"ground points: lat_deg {lat.shape}, lon_deg {lon.shape} and region_index "
                        f"{reg_raw.shape} differ in length")
    if lat.size == 0:
        raise OsseError("ground points: none given")
    if not (np.all(np.isfinite(lat)) and np.all(np.isfinite(lon))):
        raise OsseError("ground points: lat_deg/lon_deg contain NaN or inf")
    if np.any(np.abs(lat) > 90) or np.any(np.abs(lon) > 180):
        raise OsseError("ground points: lat_deg must be in -90..90 and lon_deg in -180..180")
    if not np.issubdtype(reg_raw.dtype, np.integer) or np.any(reg_raw < 0):
        raise OsseError("ground points: region_index must be non-negative integers")
    return GroundPointArrays(lat, lon, reg_raw.astype(np.int64))


def local_km(lat_deg: np.ndarray, lon_deg: np.ndarray, lat0_deg: float, lon0_deg: float):
    """East/north offsets [km] of points from (lat0, lon0), equirectangular (fine over ~100 km)."""
    dlon = (np.asarray(lon_deg) - lon0_deg + 180.0) % 360.0 - 180.0
    x_km = dlon * _KM_PER_DEG_LON_EQ * math.cos(math.radians(lat0_deg))
    y_km = (np.asarray(lat_deg) - lat0_deg) * _KM_PER_DEG_LAT
    return x_km, y_km


# --------------------------------------------------------------------------------------------
# The field
# --------------------------------------------------------------------------------------------
@dataclass
class OsseField:
    """Value per GP per slot.

    values: int16 [n_slots, n_gp], each in 1..256 - the truth, what an instrument records; slot k
    covers [k*slot_s, (k+1)*slot_s) seconds since the scenario epoch. lat_deg, lon_deg,
    region_index: the GPs (index = GP id). forecast: the a-priori forecast issued at the epoch, same
    shape (what a planner may know without observing; None: the truth of the first slot held over
    the horizon - persistence of the state at the epoch).
    """

    values: np.ndarray
    slot_s: float
    lat_deg: np.ndarray
    lon_deg: np.ndarray
    region_index: np.ndarray
    region_names: list[str]
    source: str = "synthetic"
    meta: dict = field(default_factory=dict)
    forecast: np.ndarray | None = None

    def __post_init__(self) -> None:
        v = np.asarray(self.values)
        if v.ndim != 2 or v.shape[1] != len(self.lat_deg):
            raise OsseError(f"OSSE values shape {v.shape}: expected [n_slots, n_gp={len(self.lat_deg)}]")
        if v.size and (v.min() < VALUE_MIN or v.max() > VALUE_MAX):
            raise OsseError(f"OSSE values outside {VALUE_MIN}..{VALUE_MAX}: min {v.min()}, max {v.max()}")
        self.values = v.astype(np.int16, copy=False)
        if not self.slot_s > 0:
            raise OsseError(f"OSSE slot_s must be > 0, got {self.slot_s}")
        if self.forecast is None:
            self.forecast = np.repeat(self.values[:1], self.values.shape[0], axis=0)
            self.meta.setdefault("forecast", "persistence of the first slot")
        f = np.asarray(self.forecast)
        if f.shape != v.shape:
            raise OsseError(f"OSSE forecast shape {f.shape}: expected the values' shape {v.shape}")
        if f.size and (f.min() < VALUE_MIN or f.max() > VALUE_MAX):
            raise OsseError(f"OSSE forecast outside {VALUE_MIN}..{VALUE_MAX}: min {f.min()}, max {f.max()}")
        self.forecast = f.astype(np.int16, copy=False)

    @property
    def n_slots(self) -> int:
        return int(self.values.shape[0])

    @property
    def n_gp(self) -> int:
        return int(self.values.shape[1])

    @property
    def horizon_s(self) -> float:
        return self.n_slots * self.slot_s

    def slot_of(self, t_s) -> np.ndarray:
        """Slot index of time(s) t_s [s]; times at or after the last slot hold the last slot."""
        t = np.asarray(t_s, dtype=np.float64)
        if np.any(~np.isfinite(t)) or np.any(t < 0):
            raise OsseError("OSSE query: t_s must be finite and >= 0 (seconds since the scenario epoch)")
        return np.minimum((t // self.slot_s).astype(np.int64), self.n_slots - 1)

    def value_at(self, gp_idx, t_s) -> np.ndarray:
        """Value (int16) of GP(s) ``gp_idx`` at time(s) ``t_s`` [s]; arrays broadcast together."""
        gi = np.asarray(gp_idx)
        if not np.issubdtype(gi.dtype, np.integer):
            raise OsseError("OSSE query: gp_idx must be integers")
        if np.any(gi < 0) or np.any(gi >= self.n_gp):
            raise OsseError(f"OSSE query: gp_idx outside 0..{self.n_gp - 1}")
        return self.values[self.slot_of(t_s), gi]

    def forecast_at(self, gp_idx, t_s) -> np.ndarray:
        """The a-priori forecast (int16) of GP(s) ``gp_idx`` at time(s) ``t_s`` [s], as :meth:`value_at`."""
        gi = np.asarray(gp_idx)
        if not np.issubdtype(gi.dtype, np.integer):
            raise OsseError("OSSE query: gp_idx must be integers")
        if np.any(gi < 0) or np.any(gi >= self.n_gp):
            raise OsseError(f"OSSE query: gp_idx outside 0..{self.n_gp - 1}")
        return self.forecast[self.slot_of(t_s), gi]

    def value_at_ns(self, gp_idx, t_ns) -> np.ndarray:
        """As :meth:`value_at` with integer nanoseconds since the epoch."""
        return self.value_at(gp_idx, np.asarray(t_ns, dtype=np.int64) / 1e9)

    def region_gps(self, region: int | str) -> np.ndarray:
        """GP indices of one region (by index or name)."""
        r = self.region_names.index(region) if isinstance(region, str) else int(region)
        return np.flatnonzero(self.region_index == r)

    def snapshot(self, slot: int) -> np.ndarray:
        """Values of every GP in one slot (int16 [n_gp])."""
        return self.values[int(slot)]


# --------------------------------------------------------------------------------------------
# Synthetic source
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class SyntheticParams:
    """Knobs of the synthetic storm model (units in names)."""

    cells_mean_per_6h: float = 7.0
    cells_min: int = 3
    cell_radius_km: tuple[float, float] = (5.0, 15.0)
    cell_rain_mm_h: tuple[float, float] = (15.0, 70.0)
    cell_life_h: tuple[float, float] = (1.0, 3.5)
    wind_km_h: tuple[float, float] = (8.0, 40.0)
    wind_spread_deg: float = 25.0
    drain_tau_h: float = 2.0
    flood_scale_mm: float = 25.0
    background: float = 0.04
    substeps_per_slot: int = 3
    rivers: tuple[int, int] = (2, 3)
    basins: tuple[int, int] = (1, 3)


def _region_rng(seed: int, name: str) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence([int(seed), zlib.crc32(name.encode("utf-8"))]))


def _susceptibility(rng: np.random.Generator, x_km: np.ndarray, y_km: np.ndarray,
                    half_km: float, p: SyntheticParams) -> np.ndarray:
    """Static flood susceptibility in [0.25, 1]: river channels and low-lying basins."""
    wet = np.zeros_like(x_km)
    for _ in range(int(rng.integers(p.rivers[0], p.rivers[1] + 1))):
        # A meandering channel across the region: offset d(u) = c + A sin(2 pi u / L + phi).
        ang = rng.uniform(0, np.pi)
        c, amp = rng.uniform(-0.6, 0.6) * half_km, rng.uniform(2.0, 10.0)
        wavelength, phi, width = rng.uniform(30.0, 90.0), rng.uniform(0, 2 * np.pi), rng.uniform(4.0, 10.0)
        u = x_km * np.cos(ang) + y_km * np.sin(ang)
        v = -x_km * np.sin(ang) + y_km * np.cos(ang)
        d = v - (c + amp * np.sin(2 * np.pi * u / wavelength + phi))
        wet = np.maximum(wet, np.exp(-0.5 * (d / width) ** 2))
    for _ in range(int(rng.integers(p.basins[0], p.basins[1] + 1))):
        cx, cy = rng.uniform(-half_km, half_km, size=2)
        r = rng.uniform(8.0, 20.0)
        wet = np.maximum(wet, 0.8 * np.exp(-0.5 * ((x_km - cx) ** 2 + (y_km - cy) ** 2) / r ** 2))
    return 0.25 + 0.75 * wet


def _region_values(rng: np.random.Generator, x_km: np.ndarray, y_km: np.ndarray, half_km: float,
                   n_slots: int, slot_s: float, p: SyntheticParams) -> tuple[np.ndarray, np.ndarray, list[dict]]:
    """int16 (truth, forecast) [n_slots, n_pts] for one region, and the storm cells drawn (for
    plots/tests). The forecast is the same model with only the cells born at or before the epoch."""
    s = _susceptibility(rng, x_km, y_km, half_km, p)
    horizon_h = n_slots * slot_s / 3600.0
    n_cells = max(p.cells_min, int(rng.poisson(p.cells_mean_per_6h * horizon_h / 6.0)))
    wind_dir = rng.uniform(0, 2 * np.pi)
    cells = []
    for _ in range(n_cells):
        life_h = rng.uniform(*p.cell_life_h)
        t0_h = rng.uniform(-0.6 * life_h, horizon_h - 0.3 * life_h)     # some already active at t=0
        speed = rng.uniform(*p.wind_km_h)
        direc = wind_dir + np.radians(rng.uniform(-p.wind_spread_deg, p.wind_spread_deg))
        vx, vy = speed * np.cos(direc), speed * np.sin(direc)
        # Place the cell so that at mid-life it is over (or near) the region.
        mx, my = rng.uniform(-1.1 * half_km, 1.1 * half_km, size=2)
        mid_h = t0_h + 0.5 * life_h
        cells.append({"t0_h": t0_h, "life_h": life_h, "x0_km": mx - vx * mid_h, "y0_km": my - vy * mid_h,
                      "vx_km_h": vx, "vy_km_h": vy, "radius_km": rng.uniform(*p.cell_radius_km),
                      "rain_mm_h": rng.uniform(*p.cell_rain_mm_h)})
    dt_h = slot_s / 3600.0 / p.substeps_per_slot
    decay = math.exp(-dt_h / p.drain_tau_h)
    flood = np.zeros_like(x_km)
    flood_f = np.zeros_like(x_km)
    out = np.empty((n_slots, x_km.size), dtype=np.int16)
    fc = np.empty_like(out)
    for k in range(n_slots):
        for j in range(p.substeps_per_slot):
            t_h = (k * p.substeps_per_slot + j + 0.5) * dt_h
            rain = np.zeros_like(x_km)
            rain_f = np.zeros_like(x_km)
            for c in cells:
                ph = (t_h - c["t0_h"]) / c["life_h"]
                if not 0.0 < ph < 1.0:
                    continue
                life = math.sin(math.pi * ph)
                r = c["radius_km"] * (0.4 + 0.6 * life)
                cx, cy = c["x0_km"] + c["vx_km_h"] * t_h, c["y0_km"] + c["vy_km_h"] * t_h
                cell = c["rain_mm_h"] * life * np.exp(-0.5 * ((x_km - cx) ** 2 + (y_km - cy) ** 2) / r ** 2)
                rain += cell
                if c["t0_h"] <= 0.0:
                    rain_f += cell
            flood = flood * decay + rain * dt_h
            flood_f = flood_f * decay + rain_f * dt_h
        out[k] = _flood_value(s, flood, p)
        fc[k] = _flood_value(s, flood_f, p)
    return out, fc, cells


def _flood_value(s: np.ndarray, flood_mm: np.ndarray, p: SyntheticParams) -> np.ndarray:
    v = 1.0 + np.rint(255.0 * (1.0 - np.exp(-s * (p.background + flood_mm / p.flood_scale_mm))))
    return np.clip(v, VALUE_MIN, VALUE_MAX).astype(np.int16)


def synthetic_field(gps: Any, *, region_names: Sequence[str], region_centers_deg: Sequence[tuple[float, float]],
                    region_sizes_km: Sequence[float], horizon_s: float, slot_s: float = 900.0, seed: int = 1,
                    params: SyntheticParams = SyntheticParams()) -> OsseField:
    """Seeded synthetic flood-value field over the GPs (see the module docstring for the model).

    gps: ground points (see :func:`as_ground_point_arrays`); region_index indexes region_names,
    region_centers_deg [(lat, lon)] and region_sizes_km. n_slots = ceil(horizon_s / slot_s).
    """
    g = as_ground_point_arrays(gps)
    n_reg = len(region_names)
    if not (len(region_centers_deg) == len(region_sizes_km) == n_reg):
        raise OsseError("synthetic OSSE: region_names, region_centers_deg and region_sizes_km differ in length")
    if g.region_index.max() >= n_reg:
        raise OsseError(f"ground points: region_index {g.region_index.max()} but only {n_reg} regions")
    if not (horizon_s > 0 and slot_s > 0):
        raise OsseError(f"synthetic OSSE: horizon_s ({horizon_s}) and slot_s ({slot_s}) must be > 0")
    n_slots = math.ceil(horizon_s / slot_s - 1e-9)
    values = np.empty((n_slots, len(g)), dtype=np.int16)
    forecast = np.empty_like(values)
    cells_by_region = {}
    for r, name in enumerate(region_names):
        idx = np.flatnonzero(g.region_index == r)
        rng = _region_rng(seed, name)
        lat0, lon0 = region_centers_deg[r]
        x, y = local_km(g.lat_deg[idx], g.lon_deg[idx], lat0, lon0)
        vals, fc, cells = _region_values(rng, x, y, 0.5 * float(region_sizes_km[r]), n_slots, slot_s, params)
        values[:, idx] = vals
        forecast[:, idx] = fc
        cells_by_region[name] = cells
    return OsseField(values=values, slot_s=float(slot_s), lat_deg=g.lat_deg, lon_deg=g.lon_deg,
                     region_index=g.region_index, region_names=list(region_names), source="synthetic",
                     meta={"seed": int(seed), "cells": cells_by_region,
                           "forecast": "the cells active at the epoch (cells born later are not foreseen)"},
                     forecast=forecast)
