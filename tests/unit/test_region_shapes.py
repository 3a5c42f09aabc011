"""Regions drawn as shapes (orbit_clock/region_shapes.py, bringup/scenario/regions_geojson.py): GeoJSON
polygons and bounding boxes gridded at the scenario's GP spacing.

Oracles: shapely's own containment on a dense random sample of the polygon (every GP inside; every
sample point deeper than half a cell diagonal within half a cell diagonal of a GP, and every sample
point within two spacings of one), the polygon's area on the authalic sphere by Monte Carlo with
shapely's containment (GP count x spacing^2), the meridian arc against scipy's quadrature of its
integral, neighbour chords on the ellipsoid; bad files give one line naming the file and feature and
exit 2 from the CLI.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import shapely
from scipy.integrate import quad
from scipy.spatial import cKDTree

from bringup.cli.main import main
from bringup.scenario.config import ScenarioError, load_scenario
from bringup.scenario.regions_geojson import GeoJsonError, read_geojson_regions
from bringup.scenario.toml_text import to_toml
from orbit_clock.frames import WGS84_A_KM, WGS84_B_KM, WGS84_E2, geodetic_to_ecef_km
from orbit_clock.ground_points import ground_points
from orbit_clock.region_shapes import RegionShapeError, meridian_arc_km, shape_grid, shape_problem

# a concave basin (a notch in its north edge) with a lake (a hole)
BASIN = [[[-91.0, 30.0], [-90.0, 30.0], [-90.0, 31.0], [-90.5, 30.5], [-91.0, 31.0], [-91.0, 30.0]],
         [[-90.8, 30.2], [-90.6, 30.2], [-90.6, 30.4], [-90.8, 30.4], [-90.8, 30.2]]]
# islands either side of the antimeridian, split at +-180 as RFC 7946 asks
FIJI = [[[[178.0, -18.0], [180.0, -18.0], [180.0, -16.0], [178.0, -16.0], [178.0, -18.0]]],
        [[[-180.0, -18.0], [-179.0, -18.0], [-179.0, -16.0], [-180.0, -16.0], [-180.0, -18.0]]]]
R_AUTHALIC_KM = 6371.0072


def _feature(name, gtype, coords):
    return {"type": "Feature", "properties": {"name": name}, "geometry": {"type": gtype, "coordinates": coords}}


def _write(path, obj):
    path.write_text(json.dumps(obj))
    return path


def _shapely(multi):
    return [shapely.Polygon(p[0], p[1:]) for p in multi]


def _inside(parts, lon, lat):
    out = np.zeros(np.shape(lon), dtype=bool)
    for p in parts:
        out |= shapely.contains_xy(p, lon, lat)
    return out


def _sample(multi, n, rng):
    """Uniform points on the sphere over the shape's lon/lat box (unwrapped longitudes), those inside,
    and the box's area on the authalic sphere."""
    lon = np.concatenate([np.asarray(r)[:, 0] % 360.0 if len(multi) > 1 else np.asarray(r)[:, 0]
                          for p in multi for r in p])
    lat = np.concatenate([np.asarray(r)[:, 1] for p in multi for r in p])
    lo0, lo1, la0, la1 = lon.min(), lon.max(), lat.min(), lat.max()
    x = rng.uniform(lo0, lo1, n)
    y = np.rad2deg(np.arcsin(rng.uniform(math.sin(math.radians(la0)), math.sin(math.radians(la1)), n)))
    xw = (x + 180.0) % 360.0 - 180.0
    box_km2 = R_AUTHALIC_KM ** 2 * math.radians(lo1 - lo0) * (math.sin(math.radians(la1)) - math.sin(math.radians(la0)))
    return xw, y, box_km2


@pytest.mark.parametrize("multi,spacing", [([BASIN], 4.0), ([BASIN], 2.0), (FIJI, 5.0)], ids=["basin4", "basin2", "fiji"])
def test_gps_lie_inside_and_fill_the_shape(multi, spacing):
    lat, lon, _, _ = shape_grid(multi, spacing)
    parts = _shapely(multi)
    assert np.all((lon >= -180) & (lon < 180))
    assert _inside(parts, lon, lat).all(), "a GP outside the shape"
    rng = np.random.default_rng(7)
    x, y, box_km2 = _sample(multi, 200_000, rng)
    m = _inside(parts, x, y)
    d, _ = cKDTree(geodetic_to_ecef_km(lat, lon)).query(geodetic_to_ecef_km(y[m], x[m]))
    # deeper than half a cell diagonal (distance to the boundary in degrees times the fewest km a
    # degree spans here): the grid's own cell holds a GP within half its diagonal
    km_per_deg = math.radians(1.0) * WGS84_B_KM * min(math.cos(math.radians(v)) for v in (y.min(), y.max()))
    deep = np.zeros(m.sum(), dtype=bool)
    for p in parts:
        deep |= shapely.contains_xy(p, x[m], y[m]) & (
            shapely.distance(p.boundary, shapely.points(x[m], y[m])) * km_per_deg > spacing / math.sqrt(2))
    assert deep.sum() > 0.5 * m.sum()
    assert d[deep].max() <= 1.01 * spacing / math.sqrt(2)
    assert d.max() <= 2.0 * spacing  # near corners: the nearest GP inside may be a cell further in
    # GP count x spacing^2 against the shape's area (Monte Carlo on the authalic sphere)
    area = box_km2 * m.mean()
    assert lat.size * spacing ** 2 == pytest.approx(area, rel=0.06 if spacing >= 4 else 0.03)
    if multi is FIJI:
        assert (lon > 0).any() and (lon < 0).any()


def test_neighbours_are_spacing_apart_and_ids_are_row_major():
    lat, lon, row, col = shape_grid([BASIN], 4.0)
    order = np.lexsort((col, row))
    assert np.array_equal(order, np.arange(lat.size))  # north to south, west to east
    assert np.all(np.diff(lat[row == row.min() + 1]) == 0) and lat[row == row.min()].mean() > lat[row == row.max()].mean()
    xyz = geodetic_to_ecef_km(lat, lon)
    key = {(int(r), int(c)): i for i, (r, c) in enumerate(zip(row, col, strict=True))}
    east = [np.linalg.norm(xyz[i] - xyz[key[(r, c + 1)]]) for (r, c), i in key.items() if (r, c + 1) in key]
    south = [np.linalg.norm(xyz[i] - xyz[key[(r + 1, c)]]) for (r, c), i in key.items() if (r + 1, c) in key]
    assert np.allclose(east, 4.0, rtol=1e-3)  # along a parallel: spacing exactly (chord ~ arc at 4 km)
    assert np.allclose(south, 4.0, rtol=1e-2)  # along a column: spacing, sheared off the central meridian


def test_meridian_arc_against_quadrature():
    for lat in (-80.0, -30.0, 0.0, 12.5, 45.0, 84.9):
        ref, _ = quad(lambda p: WGS84_A_KM * (1 - WGS84_E2) / (1 - WGS84_E2 * math.sin(p) ** 2) ** 1.5, 0.0,
                      math.radians(lat))
        assert float(meridian_arc_km(lat)) == pytest.approx(ref, abs=1e-6)


def test_geojson_scenario_and_bbox_grid_beside_squares(tmp_path):
    _write(tmp_path / "basins.geojson", {"type": "FeatureCollection", "features": [
        _feature("Amite", "Polygon", BASIN), _feature("Fiji", "MultiPolygon", FIJI)]})
    raw = json.loads(json.dumps(__import__("msgspec").to_builtins(load_scenario("paper"))))
    raw.pop("source_path")
    raw["regions"]["list"] = raw["regions"]["list"][:1] + [{"name": "box", "bbox_deg": [-1.0, 51.0, 0.5, 52.0]}]
    raw["regions"]["geojson_file"] = "basins.geojson"
    (tmp_path / "s.toml").write_text(to_toml(raw))
    sc = load_scenario(tmp_path / "s.toml")
    assert [r.name for r in sc.regions.list] == ["Dhaka", "box", "Amite", "Fiji"]
    assert [r.kind for r in sc.regions.list] == ["square", "bbox", "polygon", "polygon"]
    g = ground_points(sc)
    assert np.sum(g.region_index == 0) == 400  # the square is unchanged
    for k, multi in ((1, [[[[-1.0, 51.0], [0.5, 51.0], [0.5, 52.0], [-1.0, 52.0], [-1.0, 51.0]]]]), (2, [BASIN]),
                     (3, FIJI)):
        ids = g.in_region(k)
        assert _inside(_shapely(multi), g.lon_deg[ids], g.lat_deg[ids]).all()
        # the access search's region bound reaches every GP (orbit_clock/access.py)
        c = geodetic_to_ecef_km(g.region_center_lat_deg[k], g.region_center_lon_deg[k])
        u = g.ecef_km[ids] / np.linalg.norm(g.ecef_km[ids], axis=1, keepdims=True)
        ang = np.arccos(np.clip(u @ (c / np.linalg.norm(c)), -1, 1))
        assert ang.max() <= g.region_half_diag_km[k] / WGS84_B_KM
    # the loaded scenario holds the shapes: written back and loaded, the same GPs (no file needed)
    raw2 = __import__("msgspec").to_builtins(sc)
    raw2.pop("source_path")
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "s2.toml").write_text(to_toml(raw2))
    g2 = ground_points(load_scenario(tmp_path / "sub" / "s2.toml"))
    assert np.array_equal(g.lat_deg, g2.lat_deg) and np.array_equal(g.lon_deg, g2.lon_deg)


def test_feature_forms_and_names(tmp_path):
    one = read_geojson_regions(_write(tmp_path / "one.geojson", _feature("Amite", "Polygon", BASIN)))
    assert [(r["name"], r["source"]) for r in one] == [("Amite", "one.geojson feature 0")]
    bare = read_geojson_regions(_write(tmp_path / "bare.json", {"type": "MultiPolygon", "coordinates": FIJI}))
    assert bare[0]["name"] == "bare_1" and len(bare[0]["polygon_deg"]) == 2


_BOWTIE = [[[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0], [0.0, 0.0]]]
_BAD = {
    "self-intersecting": (_feature("Bow", "Polygon", _BOWTIE), "feature 0 'Bow': polygon: invalid polygon: Self-intersection"),
    "lat beyond 90": (_feature("Swap", "Polygon", [[[30, 0], [31, 0], [31, 95], [30, 0]]]), "is not [lon, lat]"),
    "not numbers": (_feature("Str", "Polygon", [[["a", 0], [1, 0], [1, 1], ["a", 0]]]), "expected [lon, lat] numbers"),
    "unclosed": (_feature("Open", "Polygon", [[[0, 0], [1, 0], [1, 1], [0, 1]]]), "ring is not closed"),
    "empty": ({"type": "FeatureCollection", "features": []}, "has no features"),
    "empty polygon": (_feature("E", "Polygon", []), "feature 0 'E': empty Polygon"),
    "point": (_feature("P", "Point", [0, 0]), "geometry is a Point"),
    "antimeridian": (_feature("Wide", "Polygon", [[[170, 0], [-170, 0], [-170, 1], [170, 1], [170, 0]]]),
                     "split at +-180"),
    "polar": (_feature("Pole", "Polygon", [[[0, 80], [10, 80], [10, 89], [0, 80]]]), "polar regions"),
    "crs": ({"type": "FeatureCollection", "crs": {"type": "name", "properties": {"name": "EPSG:32615"}},
             "features": [_feature("A", "Polygon", BASIN)]}, "only WGS-84 lon/lat"),
    "too small": (_feature("Pond", "Polygon", [[[10.0, 10.0], [10.01, 10.0], [10.01, 10.01], [10.0, 10.0]]]),
                  "region 'Pond' (bad.geojson feature 0): too small or thin for one GP"),
}


@pytest.mark.parametrize("case", sorted(_BAD))
def test_bad_regions_file_is_one_line_exit_2(tmp_path, capsys, case):
    doc, want = _BAD[case]
    f = _write(tmp_path / "bad.geojson", doc)
    code = main(["access", "--regions", str(f), "--hours", "0.1", "--sats", "1", "--planes", "1"])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert len(err.splitlines()) == 1, err
    assert "bad.geojson" in err and want in err, err


def test_bad_shapes_in_the_scenario_name_the_key(tmp_path):
    assert "Self-intersection" in shape_problem([_BOWTIE])
    raw = __import__("msgspec").to_builtins(load_scenario("paper"))
    raw.pop("source_path")
    for region, want in (({"name": "b", "bbox_deg": [1.0, 5.0, 2.0, 4.0]}, "south must be below north"),
                         ({"name": "b", "lat_deg": 1.0, "bbox_deg": [1.0, 4.0, 2.0, 5.0]}, "exactly one of"),
                         ({"name": "q", "lat_deg": 1.0, "lon_deg": 2.0}, "missing size_km"),
                         ({"name": "p", "polygon_deg": [_BOWTIE]}, "Self-intersection")):
        raw["regions"]["list"] = [region]
        (tmp_path / "s.toml").write_text(to_toml(raw))
        with pytest.raises(ScenarioError, match=r"key 'regions\.list\[0\]'") as ei:
            load_scenario(tmp_path / "s.toml")
        assert want in str(ei.value) and "\n" not in str(ei.value)
    with pytest.raises(RegionShapeError, match="'x': too small"):
        shape_grid([[[[0.0, 0.0], [0.01, 0.0], [0.01, 0.01], [0.0, 0.0]]]], 4.0, name="'x'")
    with pytest.raises(GeoJsonError, match="not found"):
        read_geojson_regions(tmp_path / "none.geojson")


def test_bbox_on_the_command_line(capsys):
    code = main(["access", "--regions=-91,30,-90.9,30.1", "--hours", "0.1", "--sats", "1", "--planes", "1",
                 "--format", "json"])
    assert code == 0
    assert json.loads(capsys.readouterr().out)["scenario"] == "paper"
    code = main(["access", "--regions=-91,30.1,-90,30", "--hours", "0.1"])
    assert code == 2 and "south must be below north" in capsys.readouterr().err


def test_ground_track_figure_draws_a_shape_outline():
    from bringup.analysis.figures import figure_ground_tracks

    fig = figure_ground_tracks({"sat_11": ([30.0, 31.0], [-91.0, -90.0])},
                               regions=[{"name": "Amite", "lat_deg": 30.5, "lon_deg": -90.5, "outline_deg": [BASIN]}])
    lines = [ln for ln in fig.axes[0].get_lines() if ln.get_gid() == "region:Amite"]
    assert len(lines) == 2  # the outer ring and the lake
    assert np.allclose(lines[0].get_xydata(), np.asarray(BASIN[0]))


def test_regions_override_reaches_the_ros_processes(tmp_path):
    """A ROS run's processes load the scenario from the run spec file the launcher writes: with
    --regions they must get the same shapes, hence the same world key, as the launcher."""
    from bringup.engine.ros.run_spec import RunSpec
    from bringup.scenario.regions_geojson import regions_arg
    from bringup.scenario.world import scenario_key

    f = _write(tmp_path / "basins.geojson", {"type": "FeatureCollection", "features": [
        _feature("Amite", "Polygon", BASIN), _feature("Fiji", "MultiPolygon", FIJI)]})
    launcher = load_scenario("paper").with_overrides(regions=regions_arg(str(f)), sats=2, planes=1)
    spec = RunSpec(factory="m:f", roles=["sat_11"], scenario=launcher.source_path,
                   overrides={"regions": regions_arg(str(f)), "sats": 2, "planes": 1})
    spec.to_file(tmp_path / "spec.json")
    f.unlink()  # the processes need the spec only, not the file
    process = RunSpec.from_file(tmp_path / "spec.json").load_scenario()
    assert [r.name for r in process.regions.list] == ["Amite", "Fiji"]
    assert scenario_key(process) == scenario_key(launcher)
