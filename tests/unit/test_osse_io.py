"""OSSE value files: round trips in every format, interpolation, and one-line errors on bad files."""

from __future__ import annotations

import numpy as np
import pytest

from ground_station import OsseError, load_value_grid, osse_from_scenario, write_value_grid
from tests.unit.test_osse import grid_gps  # the same plain GP grid as the generator tests


@pytest.fixture(scope="module")
def gps(paper_scenario):
    return grid_gps(paper_scenario)


@pytest.fixture(scope="module")
def field(paper_scenario, gps):
    return osse_from_scenario(paper_scenario.with_overrides(hours=2.0), gps)


@pytest.mark.parametrize("suffix", [".npz", ".csv", ".nc"])
def test_round_trip(field, gps, tmp_path, suffix):
    p = write_value_grid(field, tmp_path / f"v{suffix}")
    assert p.stat().st_size > 0
    back = load_value_grid(p, gps, horizon_s=2 * 3600.0, slot_s=900.0, region_names=field.region_names)
    assert back.values.dtype == np.int16
    assert np.array_equal(back.values, field.values)
    assert back.region_names == field.region_names


def test_linear_field_interpolated_off_nodes(tmp_path):
    """value = 10 + 2*lat + 3*lon + t/900 is linear in each axis, so interpolation is exact."""
    t = np.array([0.0, 1800.0, 3600.0])
    lat = np.array([10.0, 11.0, 12.0])
    lon = np.array([20.0, 21.0, 22.0, 23.0])
    T, LA, LO = np.meshgrid(t, lat, lon, indexing="ij")
    np.savez(tmp_path / "lin.npz", value=10 + 2 * (LA - 10) * 10 + 3 * (LO - 20) * 10 + T / 900,
             t_s=t, lat=lat, lon_deg=lon)
    glat = np.array([10.5, 11.25, 12.0])
    glon = np.array([20.5, 22.75, 21.0])
    f = load_value_grid(tmp_path / "lin.npz", (glat, glon, np.zeros(3, int)), horizon_s=3600.0, slot_s=900.0)
    expect = np.rint(10 + 20 * (glat - 10) + 30 * (glon - 20) + (np.arange(4) * 900.0 / 900)[:, None])
    assert np.array_equal(f.values, expect.astype(np.int16))


def test_descending_axes_and_single_time_step(tmp_path):
    lat = np.array([12.0, 11.0])                       # descending, as many NetCDF files are
    lon = np.array([20.0, 21.0])
    v = np.array([[[100.0, 200.0], [50.0, 60.0]]])     # one time step: held over the horizon
    np.savez(tmp_path / "d.npz", value=v, t_s=[0.0], lat_deg=lat, lon_deg=lon)
    f = load_value_grid(tmp_path / "d.npz", ([12.0, 11.0], [21.0, 20.0], [0, 0]), horizon_s=3600.0)
    assert f.values.shape == (4, 2)
    assert np.array_equal(f.values[:, 0], [200] * 4) and np.array_equal(f.values[:, 1], [50] * 4)


def _npz(tmp_path, name="g.npz", **over):
    arrays = dict(value=np.full((2, 2, 2), 5.0), t_s=[0.0, 3600.0], lat_deg=[0.0, 1.0], lon_deg=[0.0, 1.0])
    arrays.update(over)
    arrays = {k: v for k, v in arrays.items() if v is not None}
    np.savez(tmp_path / name, **arrays)
    return tmp_path / name


GPS = (np.array([0.5]), np.array([0.5]), np.array([0]))


@pytest.mark.parametrize("over, match", [
    (dict(value=None), "missing array 'value'"),
    (dict(value=np.full((2, 3, 2), 5.0)), r"shape \(2, 3, 2\), expected"),
    (dict(value=np.array([[[5, np.nan], [5, 5]], [[5, 5], [5, 5]]])), "1 NaN/inf cells"),
    (dict(value=np.full((2, 2, 2), 300.0)), "outside 1..256"),
    (dict(value=np.zeros((2, 2, 2))), "outside 1..256"),
    (dict(lat_deg=[0.0, 0.0]), "not strictly monotonic"),
    (dict(lat_deg=[0.0, 95.0]), "lat_deg must be in"),
    (dict(lat_deg=[2.0, 3.0]), "does not cover 1 GPs"),
    (dict(t_s=[0.0, 1800.0]), "does not cover the slot starts"),
])
def test_bad_npz(tmp_path, over, match):
    p = _npz(tmp_path, **over)
    with pytest.raises(OsseError, match=match) as ei:
        load_value_grid(p, GPS, horizon_s=3600.0)
    msg = str(ei.value)
    assert "\n" not in msg and str(p) in msg


def test_missing_and_unknown_files(tmp_path):
    with pytest.raises(OsseError, match="not found"):
        load_value_grid(tmp_path / "nope.npz", GPS, horizon_s=3600.0)
    with pytest.raises(OsseError, match="unknown OSSE file type '.txt'"):
        load_value_grid(tmp_path / "x.txt", GPS, horizon_s=3600.0)
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(OsseError, match="not a readable NPZ"):
        load_value_grid(tmp_path / "junk.npz", GPS, horizon_s=3600.0)
    (tmp_path / "h5.nc").write_bytes(b"\x89HDF\r\n\x1a\n" + b"\0" * 64)
    with pytest.raises(OsseError, match="h5.nc: unreadable NetCDF file"):
        load_value_grid(tmp_path / "h5.nc", GPS, horizon_s=3600.0)


@pytest.mark.parametrize("text, match", [
    ("", "empty CSV"),
    ("t_s,lat_deg,value\n0,0,5\n", "no 'lon_deg' column"),
    ("t_s,lat_deg,lon_deg,value\n", "no data rows"),
    ("t_s,lat_deg,lon_deg,value\n0,0,0,5\n0,0,x,5\n", r":3: not a number"),
    ("t_s,lat_deg,lon_deg,value\n0,0,0,5\n0,0,1\n", r":3: 3 fields"),
    ("t_s,lat_deg,lon_deg,value\n0,0,0,5\n0,0,1,5\n0,1,0,5\n", "1 cells missing"),
    ("t_s,lat_deg,lon_deg,value\n0,0,0,5\n0,0,0,6\n0,0,1,5\n0,1,0,5\n0,1,1,5\n", "more than once"),
    ("t_s,lat_deg,lon_deg,value\n0,0,0,5\n0,0,1,nan\n0,1,0,5\n0,1,1,5\n", "NaN/inf"),
])
def test_bad_csv(tmp_path, text, match):
    p = tmp_path / "g.csv"
    p.write_text(text)
    with pytest.raises(OsseError, match=match) as ei:
        load_value_grid(p, GPS, horizon_s=900.0)
    assert "\n" not in str(ei.value)


def test_round_trip_on_orbit_clock_ground_points(paper_scenario, tmp_path):
    """The real GP layout (orbit_clock.ground_points, WGS-84 local grid) also round-trips exactly."""
    from orbit_clock import ground_points

    sc = paper_scenario.with_overrides(hours=1.0, gp_spacing_km=8.0)  # 500 GPs: a CSV of 100k rows
    gp = ground_points(sc)
    f = osse_from_scenario(sc, gp)
    assert f.n_gp == len(gp) == 500
    back = load_value_grid(write_value_grid(f, tmp_path / "g.csv"), gp, horizon_s=3600.0)
    assert np.array_equal(back.values, f.values)
