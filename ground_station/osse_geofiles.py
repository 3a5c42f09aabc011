"""Value fields from geoscience files: NetCDF-4 / CF (xarray + h5netcdf) and GeoTIFF (rasterio).

What ground_station/osse_io.py reads when a value file is a NetCDF-4 (HDF5) file, a NetCDF-3 file
with ``value.grid.variable`` set, or a GeoTIFF (``.tif``, ``.tiff``). Both give a (time, y, x) grid
that osse_io interpolates onto the GPs and slot starts exactly like its NPZ grids (bilinear in
space, linear in time); the values are physical or already 1..256 as ``value.grid.scale`` says
(ground_station/osse_scale.py).

NetCDF (CF conventions 1.x, sections 4 and 5): the variable ``value.grid.variable`` (or the file's
only variable with two or more dimensions) on 1-D latitude and longitude coordinates, found by
``standard_name`` (latitude, longitude), ``units`` (degrees_north, degrees_east, ...) or name (lat,
latitude, lon, longitude, lat_deg, lon_deg); time by ``standard_name``/``axis`` T, a decoded datetime
coordinate or the name ``time``, in CF units ("hours since 2026-01-01 00:00:00"; standard, gregorian
or proleptic_gregorian calendars), or ``t_s`` (seconds since the scenario epoch, the project's own
files); no time dimension = one field held over the run. Other dimensions must have length 1
(a level, an ensemble member: select one first). ``scale_factor``/``add_offset``/``_FillValue`` are
applied (missing cells become NaN). Longitudes may run -180..180 or 0..360. A variable on a projected
grid (a ``grid_mapping`` other than latitude_longitude, or 2-D latitude/longitude) is refused: regrid
it to lat/lon or write it as a GeoTIFF.

GeoTIFF: every band one time step. A band's time is ``value.grid.band_start_utc`` (default: the
scenario epoch) + (band - 1) x ``value.grid.band_step_s``; with band_step_s 0 the band descriptions,
when every band has one, must be ISO 8601 UTC times ("2026-01-01T06:00:00Z"); one band without either
is held over the run. Any CRS rasterio (PROJ) knows: for EPSG:4326 the pixel centres are lon/lat;
for any other the GPs are carried into the raster's CRS (``rasterio.warp.transform``, exact, no
resampling of the data) and interpolated there. A GeoTIFF without a CRS, or with a rotated or
sheared transform, is refused. Nodata cells become NaN; band scales and offsets are applied.

Only the part of a file the run needs is read: the cells around the GPs (one cell beyond them on
each side) and the time steps around the run. Before reading, its size is estimated (cells x (the
stored item size + 16 bytes for the float64 copies)) and refused above ``value.grid.max_memory_mib``.
Every problem is one :class:`~ground_station.osse.OsseError` line naming the file: a missing
variable (with the ones there are), a wrong CRS, a time axis without CF units or with a calendar
that is not the standard one, a units attribute other than ``value.grid.units``, the estimate.

How we know it is right (tests/unit/test_geo_fields.py): the same physical field written by the
test as NetCDF-4 (xarray, h5netcdf), as a GeoTIFF (rasterio, bands = time steps) and as NPZ gives
identical GP values; a field linear in Web-Mercator metres, written as an EPSG:3857 GeoTIFF, is
reproduced at the GPs against the projection's own formula (Snyder, USGS PP 1395, eq. 7-2); each bad
file is one line and exit 2 from the CLI.
"""

from __future__ import annotations

import datetime as _dt
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ground_station.osse import OsseError

__all__ = ["GeoFileOptions", "RawGrid", "is_hdf5", "read_geotiff", "read_netcdf_cf"]

_MIB = 2 ** 20
_LAT_UNITS = ("degrees_north", "degree_north", "degree_n", "degrees_n", "degreen", "degreesn")
_LON_UNITS = ("degrees_east", "degree_east", "degree_e", "degrees_e", "degreee", "degreese")


@dataclass(frozen=True)
class GeoFileOptions:
    """How to read a geoscience file (the scenario's ``[value.grid]``)."""

    variable: str = ""
    units: str = ""
    band_start_s: float = 0.0  # band 1's time [s since the scenario epoch]
    band_step_s: float = 0.0
    max_memory_mib: float = 1024.0
    epoch: _dt.datetime | None = None  # the scenario epoch (UTC): CF and ISO times are taken from it


@dataclass
class RawGrid:
    """A (time, y, x) grid as read: axes as stored (either direction); ``to_grid(lat, lon)`` gives
    the GPs' (y, x) in the grid's coordinates (None: y = lat, x = lon)."""

    t_s: np.ndarray
    y: np.ndarray
    x: np.ndarray
    value: np.ndarray
    to_grid: Callable | None = None
    axis_names: tuple[str, str] = ("lat_deg", "lon_deg")


def is_hdf5(path: Path) -> bool:
    with open(path, "rb") as fh:
        return fh.read(8) == b"\x89HDF\r\n\x1a\n"


def _window(axis: np.ndarray, lo: float, hi: float) -> slice:
    """Indices of ``axis`` (either direction) covering [lo, hi] and one more on each side."""
    n = axis.size
    if n == 1:
        return slice(0, 1)
    idx = np.flatnonzero((axis >= lo) & (axis <= hi))
    if idx.size == 0:  # between two nodes, or outside: the nearest ones (coverage is checked later)
        idx = np.array([int(np.argmin(np.abs(axis - 0.5 * (lo + hi))))])
    return slice(max(int(idx.min()) - 1, 0), min(int(idx.max()) + 2, n))  # (n >= 2: at least two)


def _check_memory(path: Path, what: str, shape: tuple[int, ...], itemsize: int, opts: GeoFileOptions) -> None:
    cells = float(np.prod(shape, dtype=np.float64))
    need = cells * (itemsize + 16)
    if need > opts.max_memory_mib * _MIB:
        raise OsseError(f"{path}: reading {what} over the regions and the run ({' x '.join(map(str, shape))} cells) "
                        f"needs ~{need / _MIB:.0f} MiB, over value.grid.max_memory_mib = {opts.max_memory_mib:g}; "
                        "raise it, or give a coarser or smaller file")


def _epoch64(opts: GeoFileOptions) -> np.datetime64:
    ep = opts.epoch or _dt.datetime(2000, 1, 1, tzinfo=_dt.UTC)
    return np.datetime64(ep.astimezone(_dt.UTC).replace(tzinfo=None), "ns")


def _check_units(path: Path, what: str, got, opts: GeoFileOptions) -> None:
    if opts.units and str(got or "").strip() != opts.units.strip():
        raise OsseError(f"{path}: {what} has units {str(got or '') or '(none)'!r}, the scenario's value.grid.units "
                        f"says {opts.units!r} (no unit conversion is made: convert the file or fix the key)")


# --------------------------------------------------------------------------------------------
# NetCDF / CF
# --------------------------------------------------------------------------------------------
def _role(name: str, coord) -> str | None:
    """'time', 'lat', 'lon' or None for a dimension's coordinate variable (or None if it has none)."""
    low = name.lower()
    attrs = {} if coord is None else {k: str(v).lower() for k, v in coord.attrs.items()}
    std, units, axis = attrs.get("standard_name", ""), attrs.get("units", ""), attrs.get("axis", "")
    if std == "latitude" or units in _LAT_UNITS or low in ("lat", "latitude", "lat_deg"):
        return "lat"
    if std == "longitude" or units in _LON_UNITS or low in ("lon", "longitude", "lon_deg"):
        return "lon"
    if (std == "time" or axis == "t" or low in ("time", "t_s", "time_s")
            or (coord is not None and np.issubdtype(coord.dtype, np.datetime64))):
        return "time"
    return None


def _time_seconds(path: Path, name: str, coord, opts: GeoFileOptions) -> np.ndarray:
    v = coord.values
    if np.issubdtype(v.dtype, np.datetime64):
        return (v.astype("datetime64[ns]") - _epoch64(opts)) / np.timedelta64(1, "s")
    if v.dtype == object:
        cal = coord.encoding.get("calendar") or coord.attrs.get("calendar") or "?"
        raise OsseError(f"{path}: time axis '{name}' uses the calendar {cal!r}: only the standard (gregorian, "
                        "proleptic_gregorian) calendar is supported")
    if name.lower() in ("t_s", "time_s"):
        return np.asarray(v, dtype=np.float64)  # the project's own: seconds since the scenario epoch
    raise OsseError(f"{path}: time axis '{name}' has no CF time units (e.g. units = 'hours since 2026-01-01 "
                    f"00:00:00'; got {coord.attrs.get('units', 'none')!r})")


def read_netcdf_cf(path: Path, opts: GeoFileOptions, gp_lat: np.ndarray, gp_lon: np.ndarray,
                   t_range: tuple[float, float]) -> RawGrid:
    """The variable's part around the GPs and the run (module docstring)."""
    import xarray as xr

    engine = "h5netcdf" if is_hdf5(path) else "scipy"
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ds = xr.open_dataset(path, engine=engine, decode_times=True, mask_and_scale=True, cache=False)
    except Exception as exc:  # noqa: BLE001 - the libraries raise assorted errors on bad files; one line
        raise OsseError(f"{path}: unreadable NetCDF file ({type(exc).__name__}: {' '.join(str(exc).split())[:200]})") \
            from None
    with ds:
        return _read_cf(path, ds, opts, gp_lat, gp_lon, t_range)


def _read_cf(path, ds, opts, gp_lat, gp_lon, t_range) -> RawGrid:
    data_vars = [str(k) for k in ds.data_vars]
    name = opts.variable
    if not name:
        cands = [k for k in data_vars if ds[k].ndim >= 2]
        if len(cands) != 1:
            raise OsseError(f"{path}: {len(cands)} gridded variables ({', '.join(cands) or 'none'}): name one in "
                            "value.grid.variable")
        name = cands[0]
    if name not in ds.variables:
        raise OsseError(f"{path}: no variable '{name}' (variables: {', '.join(data_vars) or 'none'})")
    da = ds[name]
    gm = da.attrs.get("grid_mapping")
    if gm:
        gmn = str(ds[gm].attrs.get("grid_mapping_name", "?")) if gm in ds.variables else "?"
        if gmn != "latitude_longitude":
            raise OsseError(f"{path}: variable '{name}' is on a projected grid (grid_mapping_name '{gmn}'): only "
                            "regular lat/lon NetCDF grids are read; regrid it to lat/lon or write it as a GeoTIFF")
    roles: dict[str, str] = {}
    squeeze = {}
    for d in da.dims:
        coord = ds[d] if d in ds.variables else None
        role = _role(str(d), coord)
        if role is None or role in roles:
            if da.sizes[d] == 1:
                squeeze[d] = 0
                continue
            lat2d = [k for k in ds.variables if _role(str(k), ds[k]) == "lat" and ds[k].ndim == 2]
            hint = (" (2-D latitude/longitude: a curvilinear or projected grid; regrid it to lat/lon)" if lat2d
                    else "; only regular lat/lon grids with an optional time axis are read")
            raise OsseError(f"{path}: variable '{name}' dimension '{d}' (length {da.sizes[d]}) is not time, latitude "
                            f"or longitude{hint}")
        roles[role] = str(d)
    if "lat" not in roles or "lon" not in roles:
        raise OsseError(f"{path}: variable '{name}' has no latitude and longitude dimensions (dims: "
                        f"{', '.join(map(str, da.dims))}); only regular lat/lon grids are read")
    for role in ("lat", "lon"):
        if roles[role] not in ds.variables:
            raise OsseError(f"{path}: dimension '{roles[role]}' of variable '{name}' has no coordinate variable "
                            f"(its {'latitudes' if role == 'lat' else 'longitudes'} are not in the file)")
    da = da.isel(squeeze)
    _check_units(path, f"variable '{name}'", da.attrs.get("units"), opts)
    lat = np.asarray(ds[roles["lat"]].values, dtype=np.float64)
    lon = np.asarray(ds[roles["lon"]].values, dtype=np.float64)
    wrap = lon.size and float(np.nanmax(lon)) > 180.0
    glon = gp_lon % 360.0 if wrap else gp_lon
    sel = {roles["lat"]: _window(lat, float(gp_lat.min()), float(gp_lat.max())),
           roles["lon"]: _window(lon, float(glon.min()), float(glon.max()))}
    if "time" in roles:
        t_s = _time_seconds(path, roles["time"], ds[roles["time"]], opts) if roles["time"] in ds.variables else None
        if t_s is None:
            raise OsseError(f"{path}: time dimension '{roles['time']}' has no coordinate variable")
        sel[roles["time"]] = _window(t_s, *t_range)
        t_s = t_s[sel[roles["time"]]]
        order = (roles["time"], roles["lat"], roles["lon"])
    else:
        t_s = np.array([0.0])
        order = (roles["lat"], roles["lon"])
    da = da.isel(sel).transpose(*order)
    _check_memory(path, f"variable '{name}'", da.shape, da.dtype.itemsize, opts)
    value = np.asarray(da.values, dtype=np.float64)
    if "time" not in roles:
        value = value[None]
    to_grid = (lambda la, lo: (la, lo % 360.0)) if wrap else None
    return RawGrid(t_s=t_s, y=lat[sel[roles["lat"]]], x=lon[sel[roles["lon"]]], value=value, to_grid=to_grid)


# --------------------------------------------------------------------------------------------
# GeoTIFF
# --------------------------------------------------------------------------------------------
def _band_times(path: Path, src, opts: GeoFileOptions) -> np.ndarray:
    n = src.count
    if opts.band_step_s > 0:
        return opts.band_start_s + np.arange(n) * opts.band_step_s
    desc = list(src.descriptions or ())
    if n > 1 and not (len(desc) == n and all(desc)):
        raise OsseError(f"{path}: {n} bands and no time for them: set value.grid.band_step_s (and band_start_utc), "
                        "or give every band an ISO 8601 UTC description")
    if n == 1 and not (desc and desc[0]):
        return np.array([opts.band_start_s])
    ep = _epoch64(opts)
    out = []
    for k, d in enumerate(desc):
        try:
            t = _dt.datetime.fromisoformat(d.strip())
        except ValueError:
            raise OsseError(f"{path}: band {k + 1} description {d!r} is not an ISO 8601 UTC time (set "
                            "value.grid.band_step_s to time the bands instead)") from None
        if t.tzinfo is None:
            raise OsseError(f"{path}: band {k + 1} time {d!r} has no time zone (end it in Z)")
        out.append((np.datetime64(t.astimezone(_dt.UTC).replace(tzinfo=None), "ns") - ep) / np.timedelta64(1, "s"))
    return np.asarray(out, dtype=np.float64)


def read_geotiff(path: Path, opts: GeoFileOptions, gp_lat: np.ndarray, gp_lon: np.ndarray,
                 t_range: tuple[float, float]) -> RawGrid:
    """The bands' part around the GPs and the run (module docstring)."""
    import rasterio
    from rasterio.errors import RasterioError
    from rasterio.windows import Window

    try:
        with warnings.catch_warnings():  # (NotGeoreferencedWarning: the missing CRS is reported below, as one line)
            warnings.simplefilter("ignore")
            src = rasterio.open(path)
    except (RasterioError, OSError) as exc:
        raise OsseError(f"{path}: unreadable GeoTIFF ({' '.join(str(exc).split())[:200]})") from None
    with src:
        if src.crs is None:
            raise OsseError(f"{path}: GeoTIFF has no CRS (georeference it, e.g. gdal_edit.py -a_srs EPSG:4326)")
        tr = src.transform
        if tr.b != 0 or tr.d != 0:
            raise OsseError(f"{path}: GeoTIFF transform is rotated or sheared ({tr.b:g}, {tr.d:g}); warp it to a "
                            "north-up grid first")
        _check_units(path, "band 1", (src.units or [None])[0], opts)
        lonlat = src.crs.to_epsg() == 4326 or src.crs.to_string() == "OGC:CRS84"
        if lonlat:
            to_grid = None
            gx, gy = gp_lon, gp_lat
            names = ("lat_deg", "lon_deg")
        else:
            from rasterio.crs import CRS
            from rasterio.warp import transform as warp_transform

            crs = src.crs

            def to_grid(la, lo):
                xs, ys = warp_transform(CRS.from_epsg(4326), crs, np.asarray(lo, float).tolist(),
                                        np.asarray(la, float).tolist())
                return np.asarray(ys, dtype=np.float64), np.asarray(xs, dtype=np.float64)

            gy, gx = to_grid(gp_lat, gp_lon)
            if not (np.all(np.isfinite(gx)) and np.all(np.isfinite(gy))):
                raise OsseError(f"{path}: the GPs have no coordinates in the GeoTIFF's CRS {crs.to_string()}")
            names = (f"y [{crs.to_string()}]", f"x [{crs.to_string()}]")
        x = tr.c + (np.arange(src.width) + 0.5) * tr.a
        y = tr.f + (np.arange(src.height) + 0.5) * tr.e
        cols = _window(x, float(np.min(gx)), float(np.max(gx)))
        rows = _window(y, float(np.min(gy)), float(np.max(gy)))
        t_s = _band_times(path, src, opts)
        bands = _window(t_s, *t_range)
        shape = (bands.stop - bands.start, rows.stop - rows.start, cols.stop - cols.start)
        _check_memory(path, "its bands", shape, np.dtype(src.dtypes[0]).itemsize, opts)
        win = Window(cols.start, rows.start, shape[2], shape[1])
        idx = list(range(bands.start + 1, bands.stop + 1))
        data = src.read(idx, window=win, masked=True)
        value = np.ma.filled(data.astype(np.float64), np.nan)
        scales = np.asarray(src.scales, dtype=np.float64)[bands]
        offsets = np.asarray(src.offsets, dtype=np.float64)[bands]
        value = value * scales[:, None, None] + offsets[:, None, None]
    return RawGrid(t_s=t_s[bands], y=y[rows], x=x[cols], value=value, to_grid=to_grid, axis_names=names)
