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
* ``.nc``: NetCDF-3 classic/64-bit offset (read with ``scipy.io.netcdf_file``) with the same variable
  names as NPZ; a NetCDF-4 (HDF5) file, ``.nc4``, or a NetCDF-3 file with ``value.grid.variable`` set
  is read as CF (any regular lat/lon grid and CF time axis) by ground_station/osse_geofiles.py.
* ``.tif`` / ``.tiff``: a GeoTIFF, bands = time steps, any CRS (ground_station/osse_geofiles.py).

Values are 1..256 (the study's scale), or physical units mapped to it by ``value.grid.scale``
(linear, log, quantile: ground_station/osse_scale.py) after interpolation onto the GPs; a physical
grid may hold NaN (missing cells) away from the GPs, but a GP next to one is an error.

Axes may be ascending or descending (flipped on load); longitudes in -180..180; regions crossing the
dateline are not supported. The grid must cover every GP and every slot start of the horizon; a
single time step is held constant over the horizon. A second file of the same kind may hold the
a-priori forecast (``value.osse_forecast_file``): what a planner knows before it observes anything
(sat_node/knowledge.py); without one, the truth's first slot held over the horizon.

How we know it is right: ``tests/unit/test_osse_io.py`` writes a synthetic field with
:func:`write_value_grid` in each format and loads it back onto the same GPs bit for bit (GPs sit on
grid nodes, where bilinear interpolation is exact); an analytic linear field is reproduced at
off-node GPs; every bad-file case raises :class:`~ground_station.osse.OsseError` with one line;
``tests/unit/test_geo_fields.py`` the geoscience formats and the value scales.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from ground_station.osse import VALUE_MAX, VALUE_MIN, OsseError, OsseField, as_ground_point_arrays
from ground_station.osse_geofiles import GeoFileOptions, RawGrid, is_hdf5, read_geotiff, read_netcdf_cf
from ground_station.osse_scale import ValueScale, scale_values

__all__ = ["GRID_SUFFIXES", "ValueGrid", "load_value_grid", "read_grid", "write_value_grid"]

GRID_SUFFIXES = (".npz", ".csv", ".nc", ".nc4", ".tif", ".tiff")
_ALIASES = {
    "value": ("value", "values", "flood_value"),
    "t_s": ("t_s", "time_s", "time"),
    "lat_deg": ("lat_deg", "lat", "latitude"),
    "lon_deg": ("lon_deg", "lon", "longitude"),
}


class ValueGrid:
    """A validated rectilinear grid: value [T, NLAT, NLON] float64, ascending axes. ``physical``: the
    values are physical units (any finite number or NaN); else 1..256. ``to_grid(lat, lon)`` gives the
    GPs' (y, x) in the grid's own coordinates when these are not lat/lon degrees -180..180 (a
    projected GeoTIFF, a 0..360 longitude axis); ``lat_deg``/``lon_deg`` then hold y and x."""

    def __init__(self, path: Path, t_s, lat_deg, lon_deg, value, *, physical: bool = False, to_grid=None,
                 axis_names: tuple[str, str] = ("lat_deg", "lon_deg")):
        self.path = path
        self.physical, self.to_grid, self.axis_names = physical, to_grid, axis_names
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
        if to_grid is None and (np.any(np.abs(axes["lat_deg"]) > 90) or np.any(np.abs(axes["lon_deg"]) > 180)):
            raise OsseError(f"{path}: lat_deg must be in -90..90 and lon_deg in -180..180")
        for name in ("lat_deg", "lon_deg"):
            if axes[name].size < 2:
                raise OsseError(f"{path}: axis '{name}' needs at least 2 values to interpolate, got 1")
        self.t_s, self.lat_deg, self.lon_deg, self.value = axes["t_s"], axes["lat_deg"], axes["lon_deg"], v
        if physical:
            return
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


# --------------------------------------------------------------------------------------------
# Readers
# --------------------------------------------------------------------------------------------
def _pick(path: Path, arrays: dict, key: str):
    for n in _ALIASES[key]:
        if n in arrays:
            return arrays[n]
    raise OsseError(f"{path}: missing array '{key}' (also accepted: {', '.join(_ALIASES[key][1:])}; "
                    f"found: {', '.join(sorted(arrays)) or 'none'})")


def _read_npz(path: Path, physical: bool = False) -> ValueGrid:
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
    except (OSError, ValueError) as exc:
        raise OsseError(f"{path}: not a readable NPZ file ({exc})") from None
    return ValueGrid(path, *(_pick(path, arrays, k) for k in ("t_s", "lat_deg", "lon_deg", "value")),
                     physical=physical)


def _read_csv(path: Path, physical: bool = False) -> ValueGrid:
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
    return ValueGrid(path, axes[0], axes[1], axes[2], value.reshape(shape), physical=physical)


def _read_nc(path: Path, physical: bool = False) -> ValueGrid:
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
    return ValueGrid(path, *(_pick(path, arrays, k) for k in ("t_s", "lat_deg", "lon_deg", "value")),
                     physical=physical)


_READERS = {".npz": _read_npz, ".csv": _read_csv, ".nc": _read_nc}
_ALL = (-90.0, 90.0), (-180.0, 360.0), (-np.inf, np.inf)


def read_grid(path: str | Path, *, scale: ValueScale | None = None, options: GeoFileOptions | None = None,
              gp_lat=None, gp_lon=None, t_range: tuple[float, float] | None = None) -> ValueGrid:
    """Read and validate a value grid file; raises OsseError (one line) on any problem. ``scale``
    says whether its values are physical; a geoscience file (NetCDF-4 / CF, GeoTIFF) is read with
    ``options`` around the GPs ``gp_lat``/``gp_lon`` and the times ``t_range`` (default: all of it)."""
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix not in GRID_SUFFIXES:
        raise OsseError(f"{p}: unknown OSSE file type '{suffix}' (supported: {', '.join(GRID_SUFFIXES)})")
    if not p.is_file():
        raise OsseError(f"{p}: OSSE value file not found")
    scale = scale or ValueScale()
    opts = options or GeoFileOptions()
    geo = suffix in (".tif", ".tiff", ".nc4") or (suffix == ".nc" and (bool(opts.variable) or is_hdf5(p)))
    if not geo:
        return _READERS[suffix](p, scale.physical)
    la = np.asarray(gp_lat if gp_lat is not None else _ALL[0], dtype=np.float64)
    lo = np.asarray(gp_lon if gp_lon is not None else _ALL[1], dtype=np.float64)
    tr = t_range if t_range is not None else _ALL[2]
    reader = read_geotiff if suffix in (".tif", ".tiff") else read_netcdf_cf
    raw: RawGrid = reader(p, opts, la, lo, tr)
    return ValueGrid(p, raw.t_s, raw.y, raw.x, raw.value, physical=scale.physical, to_grid=raw.to_grid,
                     axis_names=raw.axis_names)


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
                    forecast_path: str | Path | None = None, scale: ValueScale | None = None,
                    options: GeoFileOptions | None = None, forecast_variable: str = "") -> OsseField:
    """Load a gridded truth value file and interpolate it onto the GPs at every slot start; with
    ``forecast_path`` and/or ``forecast_variable``, the a-priori forecast from that file (default:
    the truth's) and variable (default: ``options.variable``) the same way (else the field's default
    forecast: the first slot held over the horizon). Physical values become 1..256 by ``scale``
    (ground_station/osse_scale.py; quantile against the truth's GP values).

    Returns an :class:`OsseField` with n_slots = ceil(horizon_s / slot_s). Raises OsseError if a
    file is missing or malformed, or a grid does not cover every GP and slot start.
    """
    g = as_ground_point_arrays(gps)
    names = list(region_names) if region_names is not None else [f"region_{i}" for i in
                                                                 range(int(g.region_index.max()) + 1)]
    scale = scale or ValueScale()
    bad = scale.problem()
    if bad:
        raise OsseError(bad)
    opts = options or GeoFileOptions()
    n_slots = math.ceil(horizon_s / slot_s - 1e-9)
    t_range = (0.0, (n_slots - 1) * float(slot_s))
    kw = {"scale": scale, "gp_lat": g.lat_deg, "gp_lon": g.lon_deg, "t_range": t_range}
    grid = read_grid(path, options=opts, **kw)
    truth = _onto_gps(grid, g, names, horizon_s, slot_s)
    meta = {"path": str(grid.path), "grid_shape": grid.value.shape, "scale": scale.method}
    if scale.method in ("linear", "log"):
        meta.update(scale_low=scale.low, scale_high=scale.high)
    forecast = None
    if forecast_path or forecast_variable:
        fopts = replace(opts, variable=forecast_variable) if forecast_variable else opts
        fgrid = read_grid(forecast_path or path, options=fopts, **kw)
        forecast = scale_values(_onto_gps(fgrid, g, names, horizon_s, slot_s), scale, reference=truth)
        meta.update(forecast_path=str(fgrid.path), forecast="from the forecast file")
        if forecast_variable:
            meta.update(forecast_variable=forecast_variable, forecast="from the forecast variable")
    vals = scale_values(truth, scale)
    return OsseField(values=vals, slot_s=float(slot_s), lat_deg=g.lat_deg, lon_deg=g.lon_deg,
                     region_index=g.region_index, region_names=names, source="file", meta=meta,
                     forecast=forecast)


def _onto_gps(grid: ValueGrid, g, names: list[str], horizon_s: float, slot_s: float) -> np.ndarray:
    """float [n_slots, n_gp]: the grid interpolated onto the GPs at every slot start."""
    p = grid.path
    n_slots = math.ceil(horizon_s / slot_s - 1e-9)
    t_slot = np.arange(n_slots) * float(slot_s)
    gy, gx = (g.lat_deg, g.lon_deg) if grid.to_grid is None else grid.to_grid(g.lat_deg, g.lon_deg)
    ny, nx = grid.axis_names

    outside = ((gy < grid.lat_deg[0]) | (gy > grid.lat_deg[-1]) | (gx < grid.lon_deg[0]) | (gx > grid.lon_deg[-1]))
    if outside.any():
        i = int(np.flatnonzero(outside)[0])
        r = int(g.region_index[i])
        rname = names[r] if r < len(names) else str(r)
        raise OsseError(f"{p}: grid {ny} {grid.lat_deg[0]:g}..{grid.lat_deg[-1]:g}, {nx} {grid.lon_deg[0]:g}.."
                        f"{grid.lon_deg[-1]:g} does not cover {int(outside.sum())} GPs (first: GP {i} of "
                        f"'{rname}' at {g.lat_deg[i]:g}, {g.lon_deg[i]:g})")
    if grid.t_s.size > 1 and (t_slot[0] < grid.t_s[0] or t_slot[-1] > grid.t_s[-1]):
        raise OsseError(f"{p}: grid t_s {grid.t_s[0]:g}..{grid.t_s[-1]:g} s does not cover the slot starts "
                        f"{t_slot[0]:g}..{t_slot[-1]:g} s of the {horizon_s:g} s horizon (times are seconds "
                        "since the scenario epoch)")

    ii, wi = _bilinear_weights(grid.lat_deg, gy)
    jj, wj = _bilinear_weights(grid.lon_deg, gx)

    def spatial(v2: np.ndarray) -> np.ndarray:       # v2 [..., NLAT, NLON] -> [..., n_gp]
        return ((1 - wi) * (1 - wj) * v2[..., ii, jj] + (1 - wi) * wj * v2[..., ii, jj + 1]
                + wi * (1 - wj) * v2[..., ii + 1, jj] + wi * wj * v2[..., ii + 1, jj + 1])

    if grid.t_s.size == 1:
        vals = np.repeat(spatial(grid.value), n_slots, axis=0)
    else:
        k, wk = _bilinear_weights(grid.t_s, t_slot)
        used = np.union1d(k, k + 1)                   # only the time steps the slots fall between
        at_nodes = np.zeros((grid.t_s.size, ii.size))
        at_nodes[used] = spatial(grid.value[used])
        vals = (1 - wk)[:, None] * at_nodes[k] + wk[:, None] * at_nodes[k + 1]
    bad = ~np.isfinite(vals)
    if bad.any():
        s, i = (int(a[0]) for a in np.nonzero(bad))
        r = int(g.region_index[i])
        raise OsseError(f"{p}: {int(bad.any(axis=0).sum())} GPs sit next to missing cells (NaN / fill value), "
                        f"first GP {i} of '{names[r] if r < len(names) else r}' at {g.lat_deg[i]:g}, "
                        f"{g.lon_deg[i]:g} in slot {s}")
    return vals


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
