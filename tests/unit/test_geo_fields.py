"""Value fields from geoscience files (ground_station/osse_geofiles.py) and their mapping to 1..256
(ground_station/osse_scale.py), read through a scenario as a run reads them.

Oracles: the same physical field written by this test as NPZ (the project's own reader), NetCDF-4
(xarray + h5netcdf, CF time in minutes, latitudes descending, longitudes 0..360) and GeoTIFF
(rasterio, one band per time step) gives identical GP values; the NPZ result against scipy's
RegularGridInterpolator and the linear mapping written out; a field linear in Web-Mercator metres as
an EPSG:3857 GeoTIFF against the projection's formula (Snyder, USGS PP 1395, eq. 7-2); the mappings
against values worked by hand; every bad input one line and exit 2 from the CLI.
"""

from __future__ import annotations

import datetime as dt
import math
import warnings

import msgspec
import numpy as np
import pytest
import rasterio
import xarray as xr
from affine import Affine
from scipy.interpolate import RegularGridInterpolator

from bringup.cli.main import main
from bringup.scenario.config import ScenarioError, load_scenario
from bringup.scenario.toml_text import to_toml
from ground_station import OsseError
from ground_station.osse_scale import ValueScale, scale_values
from ground_station.osse_sources import osse_from_scenario
from orbit_clock.ground_points import ground_points

HOURS = 2.0
DX = 0.05
WEST, NORTH, NX, NY = -91.3, 31.3, 34, 30  # cell edges: lon -91.3..-89.6, lat 29.8..31.3
T_STEP = 1800.0
T_S = -T_STEP + np.arange(7) * T_STEP  # -0.5 h .. 2.5 h around the 2-h run


def _axes():
    lon = WEST + (np.arange(NX) + 0.5) * DX
    lat_desc = NORTH + (np.arange(NY) + 0.5) * -DX  # as a north-up raster's rows
    return lon, lat_desc


def _rain(t_s, lat, lon, shift=0.0):
    """A storm moving east [mm/h]: positive, spanning decades."""
    T, LA, LO = np.meshgrid(t_s, lat, lon, indexing="ij")
    c = -91.0 + 0.3 * T / 3600.0 + shift
    return 0.05 + 40.0 * np.exp(-((LO - c) ** 2 + (LA - 30.5) ** 2) / 0.08)


@pytest.fixture(scope="module")
def base():
    sc = load_scenario("paper")
    raw = msgspec.to_builtins(sc)
    raw.pop("source_path")
    raw["scenario"]["horizon_s"] = HOURS * 3600.0
    raw["regions"]["list"] = [{"name": "Amite", "bbox_deg": [-91.0, 30.0, -90.0, 31.0]}]
    raw["value"]["osse_source"] = "file"
    return raw


@pytest.fixture(scope="module")
def files(tmp_path_factory, base):
    d = tmp_path_factory.mktemp("fields")
    lon, lat_desc = _axes()
    truth, fc = _rain(T_S, lat_desc, lon), _rain(T_S, lat_desc, lon, shift=0.1)
    epoch = np.datetime64(base["scenario"]["epoch_utc"][:-1], "ns")
    np.savez(d / "rain.npz", value=truth, t_s=T_S, lat_deg=lat_desc, lon_deg=lon)
    np.savez(d / "rain_fc.npz", value=fc, t_s=T_S, lat_deg=lat_desc, lon_deg=lon)
    times = epoch + (T_S * 1e9).astype("timedelta64[ns]")
    ds = xr.Dataset({"precip": (("time", "lat", "lon"), truth, {"units": "mm h-1"}),
                     "precip_fc": (("time", "lat", "lon"), fc, {"units": "mm h-1"}),
                     "orography": (("lat", "lon"), np.zeros((NY, NX)), {"units": "m"})},
                    coords={"time": times, "lat": ("lat", lat_desc, {"units": "degrees_north"}),
                            "lon": ("lon", lon + 360.0, {"units": "degrees_east"})})
    ds.to_netcdf(d / "rain.nc", engine="h5netcdf",
                 encoding={"time": {"units": f"minutes since {str(epoch)[:19].replace('T', ' ')}"}})
    with rasterio.open(d / "rain.tif", "w", driver="GTiff", width=NX, height=NY, count=T_S.size, dtype="float64",
                       crs="EPSG:4326", transform=Affine(DX, 0.0, WEST, 0.0, -DX, NORTH)) as dst:
        dst.write(truth)
    with rasterio.open(d / "rain_timed.tif", "w", driver="GTiff", width=NX, height=NY, count=T_S.size,
                       dtype="float32", crs="EPSG:4326", transform=Affine(DX, 0.0, WEST, 0.0, -DX, NORTH)) as dst:
        dst.write(truth.astype(np.float32))
        for k, t in enumerate(times):
            dst.set_band_description(k + 1, str(t)[:19] + "Z")
    _write_bad(d)
    return d


def _scenario(tmp_path, base, **value):
    raw = {k: (dict(v) if isinstance(v, dict) else v) for k, v in base.items()}
    raw["value"] = {**base["value"], **{k: v for k, v in value.items() if k != "grid"}}
    if "grid" in value:
        raw["value"]["grid"] = value["grid"]
    p = tmp_path / "s.toml"
    p.write_text(to_toml(raw))
    return load_scenario(p)


def _field(tmp_path, base, path, **grid):
    sc = _scenario(tmp_path, base, osse_file=str(path), grid=grid)
    return osse_from_scenario(sc, ground_points(sc)), sc


@pytest.mark.parametrize("scale", [{"scale": "linear", "low": 0.0, "high": 30.0},
                                   {"scale": "log", "low": 0.1, "high": 50.0}, {"scale": "quantile"}],
                         ids=["linear", "log", "quantile"])
def test_netcdf4_and_geotiff_give_the_npz_values(tmp_path, base, files, scale):
    start = (dt.datetime.fromisoformat(base["scenario"]["epoch_utc"][:-1]) + dt.timedelta(seconds=T_S[0]))
    npz, sc = _field(tmp_path, base, files / "rain.npz", **scale)
    nc, _ = _field(tmp_path, base, files / "rain.nc", variable="precip", units="mm h-1", **scale)
    tif, _ = _field(tmp_path, base, files / "rain.tif", band_step_s=T_STEP,
                    band_start_utc=start.isoformat() + "Z", **scale)
    assert npz.values.shape == (8, len(ground_points(sc))) and npz.values.min() >= 1 and npz.values.max() <= 256
    assert np.ptp(npz.values) > 100  # the storm spans the scale
    assert np.array_equal(nc.values, npz.values)
    assert np.array_equal(tif.values, npz.values)
    timed, _ = _field(tmp_path, base, files / "rain_timed.tif", **scale)  # float32, times in the descriptions
    assert np.abs(timed.values.astype(int) - npz.values).max() <= 1 and np.mean(timed.values == npz.values) > 0.99
    if scale["scale"] == "linear":  # independent: scipy's interpolation, the mapping written out
        lon, lat_desc = _axes()
        f = RegularGridInterpolator((T_S, lat_desc[::-1], lon), _rain(T_S, lat_desc, lon)[:, ::-1, :])
        g = ground_points(sc)
        t = np.arange(8) * 900.0
        pts = np.stack(np.broadcast_arrays(t[:, None], g.lat_deg[None], g.lon_deg[None]), axis=-1)
        want = np.clip(np.rint(1 + 255 * f(pts) / 30.0), 1, 256)
        assert np.abs(want - npz.values).max() <= 1 and np.mean(want == npz.values) > 0.999


def test_forecast_variable_and_file(tmp_path, base, files):
    lin = {"scale": "linear", "low": 0.0, "high": 30.0}
    from_var, _ = _field(tmp_path, base, files / "rain.nc", variable="precip", forecast_variable="precip_fc", **lin)
    sc = _scenario(tmp_path, base, osse_file=str(files / "rain.npz"), osse_forecast_file=str(files / "rain_fc.npz"),
                   grid=lin)
    from_file = osse_from_scenario(sc, ground_points(sc))
    assert np.array_equal(from_var.forecast, from_file.forecast)
    assert not np.array_equal(from_var.forecast, from_var.values)
    assert from_var.meta["forecast_variable"] == "precip_fc"


def test_projected_geotiff_against_the_mercator_formula(tmp_path, base):
    """value = 1 + (x - x0) / 1000 + 2 (y - y0) / 1000 on an EPSG:3857 raster: bilinear interpolation is
    exact for a linear field, so the GP values are the formula at the GPs' Mercator coordinates."""
    r = 6378137.0
    x0, y0, px = r * math.radians(-91.2), r * math.log(math.tan(math.pi / 4 + math.radians(31.2) / 2)), 2000.0
    nx, ny = 80, 90
    xc = x0 + (np.arange(nx) + 0.5) * px
    yc = y0 - (np.arange(ny) + 0.5) * px
    val = 1.0 + (xc[None, :] - x0) / 1000.0 + 2.0 * (yc[:, None] - y0) / 1000.0 + 400.0
    with rasterio.open(tmp_path / "merc.tif", "w", driver="GTiff", width=nx, height=ny, count=1, dtype="float64",
                       crs="EPSG:3857", transform=Affine(px, 0.0, x0, 0.0, -px, y0)) as dst:
        dst.write(val[None])
    field, sc = _field(tmp_path, base, tmp_path / "merc.tif", scale="linear", low=0.0, high=1000.0)
    g = ground_points(sc)
    gx = r * np.radians(g.lon_deg)
    gy = r * np.log(np.tan(np.pi / 4 + np.radians(g.lat_deg) / 2))
    want = np.clip(np.rint(1 + 255 * (1.0 + (gx - x0) / 1000.0 + 2.0 * (gy - y0) / 1000.0 + 400.0) / 1000.0), 1, 256)
    assert np.abs(field.values[0] - want).max() <= 1 and np.mean(field.values[0] == want) > 0.99
    assert np.all(field.values == field.values[0])  # one band: held over the run


def test_scales_against_hand_worked_values():
    lin = ValueScale("linear", 0.0, 51.0)
    assert scale_values([10.2, -5.0, 0.0, 51.0, 100.0], lin).tolist() == [52, 1, 1, 256, 256]
    log = ValueScale("log", 0.1, 100.0)
    assert scale_values([1.0, 10.0, 0.0, -1.0, 0.1, 1e6], log).tolist() == [86, 171, 1, 1, 1, 256]
    q = ValueScale("quantile")
    ref = np.array([3.0, 1.0, 2.0, 2.0, 5.0])
    assert scale_values(ref, q).tolist() == [192, 1, 97, 97, 256]
    assert scale_values([4.0, 0.0, 9.0], q, reference=ref).tolist() == [224, 1, 256]
    assert scale_values([7.0, 7.0], q).tolist() == [128, 128]  # one value: the middle (128.5, half to even)
    assert scale_values([1.4, 255.6], ValueScale()).tolist() == [1, 256]
    for bad, want in ((ValueScale("log", 0.0, 1.0), "low > 0"), (ValueScale("linear", 2.0, 1.0), "low < "),
                      (ValueScale("cubic"), "not one of")):
        with pytest.raises(OsseError, match=want):
            scale_values([1.0], bad)


def _write_bad(d):
    """Bad files: (name, writer)."""
    lon, lat_desc = _axes()
    v = _rain(T_S, lat_desc, lon)
    xr.Dataset({"precip": (("time", "lat", "lon"), v)},
               coords={"time": ("time", T_S, {"units": "furlongs"}), "lat": lat_desc, "lon": lon}
               ).to_netcdf(d / "notime.nc", engine="h5netcdf")
    xr.Dataset({"precip": (("y", "x"), v[0], {"grid_mapping": "crs"}), "crs": ((), 0, {
        "grid_mapping_name": "lambert_conformal_conic"})},
        coords={"y": np.arange(NY) * 1000.0, "x": np.arange(NX) * 1000.0}).to_netcdf(d / "lcc.nc", engine="h5netcdf")
    xr.Dataset({"precip": (("time", "lat", "lon"), v)}, coords={"time": ("time", T_S)}
               ).to_netcdf(d / "nocoords.nc", engine="h5netcdf")
    with warnings.catch_warnings():  # (rasterio: NotGeoreferencedWarning, what this file is for)
        warnings.simplefilter("ignore")
        with rasterio.open(d / "nocrs.tif", "w", driver="GTiff", width=NX, height=NY, count=1, dtype="float64") as dst:
            dst.write(v[:1])


def _bad_cases(files):
    lin = {"scale": "linear", "low": 0.0, "high": 30.0}
    return {
        "missing variable": (files / "rain.nc", {**lin, "variable": "rainfall"},
                             "no variable 'rainfall' (variables: precip, precip_fc, orography)"),
        "no CRS": (files / "nocrs.tif", lin, "GeoTIFF has no CRS"),
        "projected NetCDF": (files / "lcc.nc", {**lin, "variable": "precip"},
                             "projected grid (grid_mapping_name 'lambert_conformal_conic')"),
        "time axis short": (files / "rain.tif", {**lin, "band_step_s": 60.0}, "does not cover the slot starts"),
        "time without units": (files / "notime.nc", {**lin, "variable": "precip"}, "has no CF time units"),
        "units": (files / "rain.nc", {**lin, "variable": "precip", "units": "m"}, "has units 'mm h-1'"),
        "memory": (files / "rain.nc", {**lin, "variable": "precip", "max_memory_mib": 0.01}, "value.grid.max_memory_mib"),
        "bands untimed": (files / "rain.tif", lin, "7 bands and no time for them"),
        "no coordinates": (files / "nocoords.nc", {**lin, "variable": "precip"}, "dimension 'lat' of variable "
                           "'precip' has no coordinate variable"),
        "not scaled": (files / "rain.npz", {}, "outside 1..256"),
    }


@pytest.mark.parametrize("case", ["missing variable", "no CRS", "projected NetCDF", "time axis short",
                                  "time without units", "units", "memory", "bands untimed", "no coordinates",
                                  "not scaled"])
def test_bad_field_files_are_one_line_exit_2(tmp_path, base, files, capsys, case):
    path, grid, want = _bad_cases(files)[case]
    sc = _scenario(tmp_path, base, osse_file=str(path), grid=grid)
    code = main(["run", "--engine", "local", "--scenario", sc.source_path, "--sats", "1", "--planes", "1",
                 "--hours", "0.5", "--out", str(tmp_path / "run"), "--no-progress"])
    stderr = capsys.readouterr().err
    err = [ln for ln in stderr.strip().splitlines() if "error" in ln]
    assert code == 2 and "Warning" not in stderr
    assert len(err) == 1 and path.name in err[0] and want in err[0], err


def test_bad_grid_keys_name_the_key(tmp_path, base):
    for grid, key in (({"scale": "log", "low": 0.0, "high": 10.0}, "value.grid.low"),
                      ({"scale": "linear", "low": 5.0, "high": 5.0}, "value.grid.high"),
                      ({"band_start_utc": "yesterday"}, "value.grid.band_start_utc"),
                      ({"scale": "cubic"}, "value.grid.scale")):
        with pytest.raises(ScenarioError, match=f"key '{key}'"):
            _scenario(tmp_path, base, osse_file="x.nc", grid=grid)
    with pytest.raises(ScenarioError, match="key 'value.grid': reads value.osse_file"):
        _scenario(tmp_path, base, osse_source="synthetic", grid={"scale": "quantile"})
