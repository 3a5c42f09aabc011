"""Gridded OSSE value files: load a (time, lat, lon) grid onto the ground points, and write one.

The study (Nag et al., ICAPS SPARK 2019, section 5) fed its scheduler a WRF-Hydro OSSE sampled per GP
and per 15-min slot. This module is how such an external forecast enters: a rectilinear grid of
values 1..256 over (t_s, lat_deg, lon_deg), interpolated (linear in time, bilinear in space) onto the
GPs at each slot start ``k * slot_s`` and rounded to integers.

Formats (by file suffix):

* ``.npz``: arrays ``value`` [T, NLAT, NLON], ``t_s`` [T], ``lat_deg`` [NLAT], ``lon_deg`` [NLON]
  (aliases accepted: ``values``/``flood_value``, ``time``/``time_s``, ``lat``/``latitude``,
  ``lon``/``longitude``).
* ``.csv``: header ``t_s,lat_deg,lon_deg,value`` (any column order), one row per grid cell; the rows
  must fill the grid exactly once.
* ``.nc``: NetCDF-3 classic/64-bit offset (read with ``scipy.io.netcdf_file``, no extra dependency)
  with the same variable names as NPZ; NetCDF-4 (HDF5) files get a one-line error suggesting
  ``nccopy -k classic`` or NPZ.

Axes may be ascending or descending (flipped on load); longitudes in -180..180; regions crossing the
dateline are not supported. The grid must cover every GP and every slot start of the horizon; a
single time step is held constant over the horizon. A second file of the same kind may hold the
a-priori forecast (``value.osse_forecast_file``): what a planner knows before it observes anything
(sat_node/knowledge.py); without one, the truth's first slot held over the horizon.

How we know it is right: ``tests/unit/test_osse_io.py`` writes a synthetic field with
:func:`write_value_grid` in each format and loads it back onto the same GPs bit for bit (GPs sit on
grid nodes, where bilinear interpolation is exact); an analytic linear field is reproduced at
off-node GPs; every bad-file case raises :class:`~ground_station.osse.OsseError` with one line.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ground_station.osse import VALUE_MAX, VALUE_MIN, OsseError, OsseField, as_ground_point_arrays

__all__ = ["GRID_SUFFIXES", "ValueGrid", "load_value_grid", "read_grid", "write_value_grid"]

GRID_SUFFIXES = (".npz", ".csv", ".nc")
_ALIASES = {
    "value": ("value", "values", "flood_value"),
    "t_s": ("t_s", "time_s", "time"),
    "lat_deg": ("lat_deg", "lat", "latitude"),
    "lon_deg": ("lon_deg", "lon", "longitude"),
}


class ValueGrid:
    """A validated rectilinear grid: value [T, NLAT, NLON] float64, ascending axes."""

    def __init__(self, path: Path, t_s, lat_deg, lon_deg, value):
        self.path = path
        axes = {}
        for name, a in (("t_s", t_s), ("lat_deg", lat_deg), ("lon_deg", lon_deg)):
            a = np.asarray(a, dtype=np.float64)
            if a.ndim != 1 or a.size == 0:
                raise OsseError(f"{path}: '{name}' must be a non-empty 1-D array, got shape {a.shape}")
            if not np.all(np.isfinite(a)):
                raise OsseError(f"{path}: '{name}' contains NaN or inf")
            axes[name] = a
        v = np.asarray(value, dtype=np.float64)
        want = (axes["t_s"].size, axes["lat_deg"].size, axes["lon_deg"].size)
        if v.shape != want:
            raise OsseError(f"{path}: 'value' has shape {v.shape}, expected (t_s, lat_deg, lon_deg) = {want}")
        for k, name in enumerate(("t_s", "lat_deg", "lon_deg")):
            a = axes[name]
            if a.size > 1 and np.all(np.diff(a) < 0):
                axes[name] = a[::-1]
                v = np.flip(v, axis=k)
            elif a.size > 1 and not np.all(np.diff(a) > 0):
                raise OsseError(f"{path}: axis '{name}' is not strictly monotonic (repeated or unsorted values)")
        if np.any(np.abs(axes["lat_deg"]) > 90) or np.any(np.abs(axes["lon_deg"]) > 180):
            raise OsseError(f"{path}: lat_deg must be in -90..90 and lon_deg in -180..180")
        for name in ("lat_deg", "lon_deg"):
            if axes[name].size < 2:
                raise OsseError(f"{path}: axis '{name}' needs at least 2 values to interpolate, got 1")
        bad = ~np.isfinite(v)
        if bad.any():
            k, i, j = np.argwhere(bad)[0]
            raise OsseError(f"{path}: 'value' has {int(bad.sum())} NaN/inf cells (first at t_s="
                            f"{axes['t_s'][k]:g}, lat_deg={axes['lat_deg'][i]:g}, lon_deg={axes['lon_deg'][j]:g})")
        out = (v < VALUE_MIN) | (v > VALUE_MAX)
        if out.any():
            k, i, j = np.argwhere(out)[0]
            raise OsseError(f"{path}: 'value' has {int(out.sum())} cells outside {VALUE_MIN}..{VALUE_MAX} "
                            f"(first {v[k, i, j]:g} at t_s={axes['t_s'][k]:g}, lat_deg={axes['lat_deg'][i]:g}, "
                            f"lon_deg={axes['lon_deg'][j]:g})")
        self.t_s, self.lat_deg, self.lon_deg, self.value = axes["t_s"], axes["lat_deg"], axes["lon_deg"], v


# --------------------------------------------------------------------------------------------
# Readers
# --------------------------------------------------------------------------------------------
def _pick(path: Path, arrays: dict, key: str):
    for n in _ALIASES[key]:
        if n in arrays:
            return arrays[n]
    raise OsseError(f"{path}: missing array '{key}' (also accepted: {', '.join(_ALIASES[key][1:])}; "
                    f"found: {', '.join(sorted(arrays)) or 'none'})")


def _read_npz(path: Path) -> ValueGrid:
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
    except (OSError, ValueError) as exc:
        raise OsseError(f"{path}: not a readable NPZ file ({exc})") from None
    return ValueGrid(path, *(_pick(path, arrays, k) for k in ("t_s", "lat_deg", "lon_deg", "value")))


def _read_csv(path: Path) -> ValueGrid:
    try:
        fh = open(path, newline="", encoding="utf-8")  # noqa: SIM115 - closed by the with below
    except OSError as exc:
        raise OsseError(f"{path}: cannot read: {exc.strerror or exc}") from None
    with fh:
        rd = csv.reader(fh)
        header = next(rd, None)
        if header is None:
            raise OsseError(f"{path}: empty CSV (expected header t_s,lat_deg,lon_deg,value)")
        header = [h.strip() for h in header]
        cols = {}
        for key in ("t_s", "lat_deg", "lon_deg", "value"):
            hit = [i for i, h in enumerate(header) if h in _ALIASES[key]]
            if not hit:
                raise OsseError(f"{path}: header has no '{key}' column (header: {','.join(header)})")
            cols[key] = hit[0]
        rows = []
        for lineno, row in enumerate(rd, start=2):
            if not row or all(not c.strip() for c in row):
                continue
            if len(row) != len(header):
                raise OsseError(f"{path}:{lineno}: {len(row)} fields, header has {len(header)}")
            try:
                rows.append([float(row[cols[k]]) for k in ("t_s", "lat_deg", "lon_deg", "value")])
            except ValueError:
                raise OsseError(f"{path}:{lineno}: not a number in {row!r}") from None
    if not rows:
        raise OsseError(f"{path}: no data rows")
    a = np.asarray(rows)
    axes, inv = [], []
    for c in range(3):
        u, iv = np.unique(a[:, c], return_inverse=True)
        axes.append(u)
        inv.append(iv)
    shape = tuple(u.size for u in axes)
    flat = np.ravel_multi_index(tuple(inv), shape)
    counts = np.bincount(flat, minlength=math.prod(shape))
    if (counts > 1).any():
        raise OsseError(f"{path}: {int((counts > 1).sum())} grid cells appear more than once")
    if (counts == 0).any():
        raise OsseError(f"{path}: rows do not fill the (t_s, lat_deg, lon_deg) grid {shape}: "
                        f"{int((counts == 0).sum())} cells missing")
    value = np.empty(math.prod(shape))
    value[flat] = a[:, 3]
    return ValueGrid(path, axes[0], axes[1], axes[2], value.reshape(shape))


def _read_nc(path: Path) -> ValueGrid:
    # here, not at the top: scipy.io costs ~0.08 s to import (python -X importtime) in every process
    # that loads the ground segment or a satellite, and only NetCDF value files need it
    from scipy.io import netcdf_file

    with open(path, "rb") as fh:
        magic = fh.read(4)
    if magic[:3] != b"CDF":
        hint = " (NetCDF-4/HDF5 is not supported: convert with 'nccopy -k classic' or use .npz)" \
            if magic == b"\x89HDF" else ""
        raise OsseError(f"{path}: not a NetCDF-3 file{hint}")
    try:
        with netcdf_file(path, "r", mmap=False) as nc:
            arrays = {k: np.array(v[:], dtype=np.float64) for k, v in nc.variables.items()}
    except Exception as exc:  # noqa: BLE001 - scipy raises assorted errors on corrupt files; report all as one line
        raise OsseError(f"{path}: unreadable NetCDF-3 file ({type(exc).__name__}: {exc})") from None
    return ValueGrid(path, *(_pick(path, arrays, k) for k in ("t_s", "lat_deg", "lon_deg", "value")))


_READERS = {".npz": _read_npz, ".csv": _read_csv, ".nc": _read_nc}


def read_grid(path: str | Path) -> ValueGrid:
    """Read and validate a value grid file; raises OsseError (one line) on any problem."""
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix not in _READERS:
        raise OsseError(f"{p}: unknown OSSE file type '{suffix}' (supported: {', '.join(GRID_SUFFIXES)})")
    if not p.is_file():
        raise OsseError(f"{p}: OSSE value file not found")
    return _READERS[suffix](p)


# --------------------------------------------------------------------------------------------
# Interpolation onto the GPs
# --------------------------------------------------------------------------------------------
def _bilinear_weights(axis: np.ndarray, x: np.ndarray):
    """Left index and weight of the right neighbour for points x inside [axis[0], axis[-1]]."""
    i = np.clip(np.searchsorted(axis, x, side="right") - 1, 0, axis.size - 2)
    w = (x - axis[i]) / (axis[i + 1] - axis[i])
    return i, w


def load_value_grid(path: str | Path, gps: Any, *, horizon_s: float, slot_s: float = 900.0,
                    region_names: Sequence[str] | None = None,
                    forecast_path: str | Path | None = None) -> OsseField:
    """Load a gridded truth value file and interpolate it onto the GPs at every slot start; with
    ``forecast_path``, the a-priori forecast from a second grid file the same way (else the field's
    default forecast: the first slot held over the horizon).

    Returns an :class:`OsseField` with n_slots = ceil(horizon_s / slot_s). Raises OsseError if a
    file is missing or malformed, or a grid does not cover every GP and slot start.
    """
    g = as_ground_point_arrays(gps)
    names = list(region_names) if region_names is not None else [f"region_{i}" for i in
                                                                 range(int(g.region_index.max()) + 1)]
    grid = read_grid(path)
    vals = _onto_gps(grid, g, names, horizon_s, slot_s)
    meta = {"path": str(grid.path), "grid_shape": grid.value.shape}
    forecast = None
    if forecast_path:
        fgrid = read_grid(forecast_path)
        forecast = _onto_gps(fgrid, g, names, horizon_s, slot_s)
        meta.update(forecast_path=str(fgrid.path), forecast="from the forecast file")
    return OsseField(values=vals, slot_s=float(slot_s), lat_deg=g.lat_deg, lon_deg=g.lon_deg,
                     region_index=g.region_index, region_names=names, source="file", meta=meta,
                     forecast=forecast)


def _onto_gps(grid: ValueGrid, g, names: list[str], horizon_s: float, slot_s: float) -> np.ndarray:
    """int16 [n_slots, n_gp]: the grid interpolated onto the GPs at every slot start."""
    p = grid.path
    n_slots = math.ceil(horizon_s / slot_s - 1e-9)
    t_slot = np.arange(n_slots) * float(slot_s)

    outside = ((g.lat_deg < grid.lat_deg[0]) | (g.lat_deg > grid.lat_deg[-1])
               | (g.lon_deg < grid.lon_deg[0]) | (g.lon_deg > grid.lon_deg[-1]))
    if outside.any():
        i = int(np.flatnonzero(outside)[0])
        r = int(g.region_index[i])
        rname = names[r] if r < len(names) else str(r)
        raise OsseError(f"{p}: grid lat {grid.lat_deg[0]:g}..{grid.lat_deg[-1]:g}, lon {grid.lon_deg[0]:g}.."
                        f"{grid.lon_deg[-1]:g} does not cover {int(outside.sum())} GPs (first: GP {i} of "
                        f"'{rname}' at {g.lat_deg[i]:g}, {g.lon_deg[i]:g})")
    if grid.t_s.size > 1 and (t_slot[0] < grid.t_s[0] or t_slot[-1] > grid.t_s[-1]):
        raise OsseError(f"{p}: grid t_s {grid.t_s[0]:g}..{grid.t_s[-1]:g} s does not cover the slot starts "
                        f"{t_slot[0]:g}..{t_slot[-1]:g} s of the {horizon_s:g} s horizon")

    ii, wi = _bilinear_weights(grid.lat_deg, g.lat_deg)
    jj, wj = _bilinear_weights(grid.lon_deg, g.lon_deg)

    def spatial(v2: np.ndarray) -> np.ndarray:       # v2 [..., NLAT, NLON] -> [..., n_gp]
        return ((1 - wi) * (1 - wj) * v2[..., ii, jj] + (1 - wi) * wj * v2[..., ii, jj + 1]
                + wi * (1 - wj) * v2[..., ii + 1, jj] + wi * wj * v2[..., ii + 1, jj + 1])

    at_nodes = spatial(grid.value)                    # [T, n_gp]
    if grid.t_s.size == 1:
        vals = np.repeat(at_nodes, n_slots, axis=0)
    else:
        k, wk = _bilinear_weights(grid.t_s, t_slot)
        vals = (1 - wk)[:, None] * at_nodes[k] + wk[:, None] * at_nodes[k + 1]
    return np.clip(np.rint(vals), VALUE_MIN, VALUE_MAX).astype(np.int16)


# --------------------------------------------------------------------------------------------
# Writer
# --------------------------------------------------------------------------------------------
def write_value_grid(field: OsseField, path: str | Path, *, which: str = "truth") -> Path:
    """Write a field's truth (``which="truth"``) or its forecast (``"forecast"``) as a rectilinear
    (t_s, lat_deg, lon_deg) grid whose nodes include every GP.

    Axes are the distinct GP latitudes and longitudes; cells that are not a GP hold 1 (the minimum).
    Format by suffix (.npz, .csv, .nc). Loading it back onto the same GPs gives the same values.
    """
    if which not in ("truth", "forecast"):
        raise OsseError(f"write_value_grid: which must be 'truth' or 'forecast', got {which!r}")
    values = field.values if which == "truth" else field.forecast
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix not in _READERS:
        raise OsseError(f"{p}: unknown OSSE file type '{suffix}' (supported: {', '.join(GRID_SUFFIXES)})")
    # GP grids that are not rectilinear in lat/lon (e.g. orbit_clock's, whose columns drift ~0.002 deg
    # from row to row) give one axis line per distinct value: 50 x 500 for the paper's 500 GPs.
    lat_ax, ii = np.unique(field.lat_deg, return_inverse=True)
    lon_ax, jj = np.unique(field.lon_deg, return_inverse=True)
    t_s = np.arange(field.n_slots) * field.slot_s
    value = np.full((field.n_slots, lat_ax.size, lon_ax.size), VALUE_MIN, dtype=np.float64)
    value[:, ii, jj] = values
    p.parent.mkdir(parents=True, exist_ok=True)
    if suffix == ".npz":
        np.savez_compressed(p, value=value, t_s=t_s, lat_deg=lat_ax, lon_deg=lon_ax)
    elif suffix == ".csv":
        T, L, M = np.meshgrid(t_s, lat_ax, lon_ax, indexing="ij")
        data = np.column_stack([T.ravel(), L.ravel(), M.ravel(), value.ravel()])
        np.savetxt(p, data, delimiter=",", header="t_s,lat_deg,lon_deg,value", comments="",
                   fmt=["%.3f", "%.17g", "%.17g", "%d"])
    else:
        from scipy.io import netcdf_file  # (only for NetCDF: see _read_nc)

        with netcdf_file(p, "w") as nc:
            nc.createDimension("time", t_s.size)
            nc.createDimension("lat", lat_ax.size)
            nc.createDimension("lon", lon_ax.size)
            for name, dims, arr, units in (("t_s", ("time",), t_s, "s since scenario epoch"),
                                           ("lat_deg", ("lat",), lat_ax, "degrees_north"),
                                           ("lon_deg", ("lon",), lon_ax, "degrees_east"),
                                           ("value", ("time", "lat", "lon"), value, "1")):
                var = nc.createVariable(name, "f8" if name != "value" else "i2", dims)
                var[:] = arr
                var.units = units
    return p
