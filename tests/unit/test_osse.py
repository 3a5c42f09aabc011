"""OSSE synthetic field: determinism, range, spatial clustering, temporal change, registry, queries."""

from __future__ import annotations

import numpy as np
import pytest

from ground_station import OSSE_SOURCES, OsseError, OsseField, osse_from_scenario, synthetic_field
from ground_station.osse import local_km


def grid_gps(sc):
    """Plain GP arrays: a square n x n grid per region at the scenario's spacing (test stand-in)."""
    lat, lon, reg = [], [], []
    for r, R in enumerate(sc.regions.list):
        n = int(round(R.size_km / sc.gp_spacing_km))
        off = (np.arange(n) - (n - 1) / 2) * sc.gp_spacing_km
        dy, dx = np.meshgrid(off, off, indexing="ij")
        lat.append(R.lat_deg + dy.ravel() / 110.574)
        lon.append(R.lon_deg + dx.ravel() / (111.320 * np.cos(np.radians(R.lat_deg))))
        reg.append(np.full(n * n, r))
    return np.concatenate(lat), np.concatenate(lon), np.concatenate(reg)


@pytest.fixture(scope="module")
def gps(paper_scenario):
    return grid_gps(paper_scenario)


@pytest.fixture(scope="module")
def field(paper_scenario, gps):
    return osse_from_scenario(paper_scenario, gps)


def morans_i(values: np.ndarray, x_km: np.ndarray, y_km: np.ndarray, radius_km: float) -> float:
    """Moran's I with binary weights for GP pairs closer than radius_km (8-neighbourhood)."""
    d = np.hypot(x_km[:, None] - x_km[None, :], y_km[:, None] - y_km[None, :])
    w = ((d > 0) & (d < radius_km)).astype(float)
    z = values - values.mean()
    den = (z ** 2).sum()
    if den == 0:
        return 0.0
    return float(len(z) / w.sum() * (z @ w @ z) / den)


def test_shape_dtype_and_range(field, paper_scenario, gps):
    n_slots = int(np.ceil(paper_scenario.scenario.horizon_s / paper_scenario.value.slot_s))
    assert field.values.shape == (n_slots, len(gps[0])) == (24, 2000)
    assert field.values.dtype == np.int16
    assert field.values.min() >= 1 and field.values.max() <= 256
    assert field.slot_s == 900.0
    # The field is not flat: some GPs are clearly flooded at some time.
    assert field.values.max() > 100


def test_same_seed_same_field_other_seed_different(paper_scenario, gps, field):
    again = osse_from_scenario(paper_scenario, gps)
    assert np.array_equal(again.values, field.values)
    other = osse_from_scenario(paper_scenario.with_overrides(seed=2), gps)
    assert not np.array_equal(other.values, field.values)
    assert np.mean(other.values != field.values) > 0.5


def test_region_field_independent_of_other_regions(paper_scenario, gps):
    """The storm-cell field (transiency 0): a region's values depend on the seed and its own name,
    not on the region list. (The transient field's time constant is corrected from all regions'
    measured rank correlation, ground_station/osse_transient.py: it does depend on the list.)"""
    field = osse_from_scenario(paper_scenario.with_overrides(transiency_min=0), gps)
    lat, lon, reg = gps
    keep = reg == 3                                            # London alone
    rl = paper_scenario.regions.list
    alone = synthetic_field((lat[keep], lon[keep], np.zeros(keep.sum(), int)), region_names=[rl[3].name],
                            region_centers_deg=[(rl[3].lat_deg, rl[3].lon_deg)], region_sizes_km=[rl[3].size_km],
                            horizon_s=21600.0, slot_s=900.0, seed=paper_scenario.scenario.seed)
    assert np.array_equal(alone.values, field.values[:, keep])


def test_spatially_clustered_far_above_shuffled(field, paper_scenario):
    rng = np.random.default_rng(0)
    real, shuffled = [], []
    for r, R in enumerate(paper_scenario.regions.list):
        idx = field.region_gps(r)
        x, y = local_km(field.lat_deg[idx], field.lon_deg[idx], R.lat_deg, R.lon_deg)
        for k in range(0, field.n_slots, 3):
            v = field.values[k, idx].astype(float)
            if v.std() < 1.0:                                   # a calm, flat snapshot says nothing
                continue
            real.append(morans_i(v, x, y, 1.5 * paper_scenario.gp_spacing_km))
            shuffled.append(morans_i(rng.permutation(v), x, y, 1.5 * paper_scenario.gp_spacing_km))
    assert len(real) >= 10
    assert np.median(real) > 0.45, np.round(real, 2)
    assert np.median(shuffled) < 0.1
    assert min(real) > max(shuffled)


def test_changes_within_horizon(field, paper_scenario):
    changed_regions = 0
    for r in range(len(paper_scenario.regions.list)):
        v = field.values[:, field.region_gps(r)].astype(int)
        step_change = np.abs(np.diff(v, axis=0)).sum()
        assert step_change > 0, f"region {r} is frozen"
        if np.mean(v[0] != v[-1]) > 0.5:
            changed_regions += 1
    assert changed_regions >= 3
    # The most valuable GP of a region moves over the horizon (cells travel).
    moves = [len({int(np.argmax(field.values[k, field.region_gps(r)])) for k in range(field.n_slots)})
             for r in range(5)]
    assert max(moves) >= 3


def test_value_at_vectorized_and_slot_edges(field):
    assert field.value_at(7, 0.0) == field.values[0, 7]
    assert field.value_at(7, 899.999) == field.values[0, 7]
    assert field.value_at(7, 900.0) == field.values[1, 7]
    assert field.value_at(7, 1e9) == field.values[-1, 7]       # past the horizon holds the last slot
    gp = np.array([0, 5, 499])
    t = np.array([[0.0], [4000.0]])
    got = field.value_at(gp, t)
    assert got.shape == (2, 3)
    assert np.array_equal(got[1], field.values[4, gp])
    assert np.array_equal(field.value_at_ns(gp, np.int64(4000) * 10**9), field.values[4, gp])


@pytest.mark.parametrize("gp, t, match", [
    (-1, 0.0, "gp_idx outside"), (2000, 0.0, "gp_idx outside"), (0, -1.0, "t_s must be finite"),
    (0, float("nan"), "t_s must be finite"), (1.5, 0.0, "must be integers"),
])
def test_value_at_bad_queries(field, gp, t, match):
    with pytest.raises(OsseError, match=match):
        field.value_at(gp, t)


def test_registry_and_file_source(paper_scenario, gps, field, tmp_path):
    import msgspec

    from ground_station import write_value_grid

    assert set(OSSE_SOURCES) == {"synthetic", "file"}
    f = write_value_grid(field, tmp_path / "v.npz")
    raw = msgspec.to_builtins(paper_scenario)
    raw.pop("source_path")
    raw["value"].update(osse_source="file", osse_file=str(f))
    from bringup.scenario.config import _validate

    sc = _validate(raw, str(tmp_path / "s.toml"))
    loaded = osse_from_scenario(sc, gps)
    assert loaded.source == "file"
    assert np.array_equal(loaded.values, field.values)
    # Relative osse_file resolves beside the scenario file.
    raw["value"]["osse_file"] = "v.npz"
    sc_rel = _validate(raw, str(tmp_path / "s.toml"))
    assert np.array_equal(osse_from_scenario(sc_rel, gps).values, field.values)
    # A source the registry does not know: one line naming the known ones.
    bad = msgspec.structs.replace(sc, value=msgspec.structs.replace(sc.value, osse_source="wrf"))
    with pytest.raises(OsseError, match=r"^value.osse_source 'wrf': unknown \(known: file, synthetic\)$"):
        osse_from_scenario(bad, gps)


def test_bad_ground_points():
    kw = dict(region_names=["a"], region_centers_deg=[(0.0, 0.0)], region_sizes_km=[80.0], horizon_s=3600.0)
    with pytest.raises(OsseError, match="differ in length"):
        synthetic_field((np.zeros(3), np.zeros(2), np.zeros(3, int)), **kw)
    with pytest.raises(OsseError, match="only 1 regions"):
        synthetic_field((np.zeros(3), np.zeros(3), np.array([0, 1, 0])), **kw)
    with pytest.raises(OsseError, match="NaN"):
        synthetic_field((np.array([np.nan]), np.zeros(1), np.zeros(1, int)), **kw)
    with pytest.raises(OsseError, match="need lat_deg"):
        synthetic_field({"lat_deg": [0.0]}, **kw)


def test_field_rejects_out_of_range():
    with pytest.raises(OsseError, match="outside 1..256"):
        OsseField(values=np.array([[0]]), slot_s=900.0, lat_deg=np.zeros(1), lon_deg=np.zeros(1),
                  region_index=np.zeros(1, int), region_names=["a"])
