"""The transient OSSE field (ground_station/osse_transient.py) and its rank statistics
(ground_station/osse_stats.py).

Oracles: scipy's Spearman on random data with ties; a drawn correlation curve whose crossing is
known; the measured transiency of the generated field against the request over several seeds (within
20 %, the issue's tolerance); the forecast against what it may hold (the epoch state, no event born
later).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import spearmanr

from bringup.scenario.config import load_scenario
from ground_station.osse import as_ground_point_arrays
from ground_station.osse_sources import osse_from_scenario
from ground_station.osse_stats import (
    field_rank_figures,
    measured_transiency_min,
    rank_correlation,
    relative_change_by_lag,
    spearman,
)
from ground_station.osse_transient import TransientParams, transient_field_arrays
from orbit_clock import ground_points


def test_spearman_equals_scipy_with_ties():
    rng = np.random.default_rng(0)
    for _ in range(50):
        a = rng.integers(1, 12, 300)
        b = a + rng.integers(-5, 6, 300)
        assert spearman(a, b) == pytest.approx(spearmanr(a, b).statistic, abs=1e-12)


def test_rank_correlation_is_the_mean_over_start_slots():
    rng = np.random.default_rng(1)
    v = rng.integers(1, 257, (10, 200))
    for lag in (1, 3):
        want = np.mean([spearmanr(v[t], v[t + lag]).statistic for t in range(10 - lag)])
        assert rank_correlation(v, lag) == pytest.approx(want, abs=1e-12)
    assert rank_correlation(v, 0) == 1.0 and rank_correlation(v, 10) is None


def test_transiency_is_found_where_the_curve_crosses_one_half():
    """A field whose slot-to-slot ranks are shuffled with a known share: crossing between lags 2 and 3."""
    rng = np.random.default_rng(2)
    base = rng.standard_normal(4000)
    rows = [base]
    for _ in range(12):  # AR(1) over the GPs: corr(k) = 0.75 ** k -> rank corr ~ 0.73, 0.54, 0.40
        rows.append(0.75 * rows[-1] + np.sqrt(1 - 0.75 ** 2) * rng.standard_normal(4000))
    v = np.array(rows)
    rc = [rank_correlation(v, k) for k in (1, 2, 3)]
    assert rc[1] > 0.5 > rc[2]
    t = measured_transiency_min(v, 900.0)
    assert t == pytest.approx(15 * (2 + (rc[1] - 0.5) / (rc[1] - rc[2])))
    assert measured_transiency_min(np.tile(base, (5, 1)), 900.0) is None  # never decorrelates


@pytest.fixture(scope="module")
def paper_gps():
    sc = load_scenario("paper")
    return sc, as_ground_point_arrays(ground_points(sc))


def _field(sc, gps, seed: int, minutes: float):
    rl = sc.regions.list
    return transient_field_arrays(gps, region_names=[r.name for r in rl],
                                  region_centers_deg=[(r.lat_deg, r.lon_deg) for r in rl],
                                  region_sizes_km=[r.size_km for r in rl], horizon_s=21600.0, slot_s=900.0,
                                  seed=seed, params=TransientParams(transiency_min=minutes))


@pytest.mark.parametrize("minutes", [15.0, 60.0])
def test_measured_transiency_is_within_20_percent_of_the_preset(paper_gps, minutes):
    sc, gps = paper_gps
    for seed in (1, 2, 3, 4):
        truth, _fc, meta = _field(sc, gps, seed, minutes)
        got = measured_transiency_min(truth, 900.0)
        assert got == pytest.approx(minutes, rel=0.2), (seed, got, meta["calibration"])
        assert truth.min() >= 1 and truth.max() <= 256 and truth.dtype == np.int16


def test_faster_field_decorrelates_faster_and_the_slow_one_is_slow(paper_gps):
    sc, gps = paper_gps
    f15, _, _ = _field(sc, gps, 1, 15.0)
    f60, _, _ = _field(sc, gps, 1, 60.0)
    assert rank_correlation(f15, 1) < rank_correlation(f60, 1) < 0.95
    slow = osse_from_scenario(sc.with_overrides(transiency_min=0), ground_points(sc))
    fig = slow.meta["rank"]
    assert fig["rank_corr_15min"] > 0.95 and fig["transiency_min"] > 120.0


def test_forecast_holds_the_epoch_and_no_event_born_later(paper_gps):
    sc, gps = paper_gps
    truth, fc, meta = _field(sc, gps, 3, 15.0)
    late = [e for d in meta["regions"].values() for e in d["events"] if e["t0_s"] > 0]
    assert late, "the field has events born after the epoch"
    # far from every event born after the epoch, the first slot's forecast is the truth
    region = gps.region_index
    from ground_station.osse import local_km

    near = np.zeros(len(gps), bool)
    for r, (name, d) in enumerate(meta["regions"].items()):
        idx = np.flatnonzero(region == r)
        rr = sc.regions.list[r]
        x, y = local_km(gps.lat_deg[idx], gps.lon_deg[idx], rr.lat_deg, rr.lon_deg)
        for e in d["events"]:
            if 0 < e["t0_s"] <= 450.0:
                near[idx[np.hypot(x - e["x_km"], y - e["y_km"]) < 6 * e["radius_km"]]] = True
    assert np.array_equal(fc[0, ~near], truth[0, ~near])
    # later the forecast misses the events: the truth is higher where an event struck
    assert (truth.astype(int) - fc).max() > 100
    assert np.mean(np.abs(truth.astype(float) - fc) / truth) > 0.2


def test_same_seed_same_field(paper_gps):
    sc, gps = paper_gps
    a = _field(sc, gps, 5, 30.0)
    b = _field(sc, gps, 5, 30.0)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
    assert not np.array_equal(a[0], _field(sc, gps, 6, 30.0)[0])


def test_every_field_leaves_the_registry_with_its_rank_figures(paper_gps):
    sc, _ = paper_gps
    f = osse_from_scenario(sc.with_overrides(hours=2.0), ground_points(sc))
    rank = dict(f.meta["rank"])
    curve = rank.pop("rel_change_by_slot_lag")
    assert curve == relative_change_by_lag(f.values)
    # a 15-min OSSE is drawn on its own slot: its decorrelation is the rank figure's transiency
    assert rank.pop("decorrelation_min") == rank["transiency_min"]
    assert rank.pop("osse_resolution_min") == 15.0 and rank.pop("flash_floods") is True
    assert rank == field_rank_figures(f.values, f.slot_s)
    assert set(rank) == {"rank_corr_15min", "rank_corr_60min", "transiency_min"}
