"""The OSSE's time resolution (the study's "transiency") apart from the field's decorrelation.

``value.osse_resolution_min`` sets the value slot and Eq. 1's zero-value window together; the
transient field is drawn on a step of at most 15 min whatever the slot, so a coarser OSSE is the
same field sampled less often; ``value.flash_floods = false`` takes the flash floods out of the same
field; the relative change of the values by lag (ground_station/osse_stats.py) against brute force.
"""

from __future__ import annotations

import numpy as np
import pytest
from scenario_edit import raw_scenario, set_key

from bringup.scenario.config import ScenarioError, _validate
from ground_station.osse_sources import osse_from_scenario
from ground_station.osse_stats import relative_change_at, relative_change_by_lag
from orbit_clock.ground_points import ground_points


def _with(sc, **keys):
    raw = raw_scenario(sc)
    for k, v in keys.items():
        set_key(raw, k.replace("__", "."), v)
    return _validate(raw, "test.toml")


def test_resolution_moves_slot_and_zero_window_together(paper_scenario):
    assert paper_scenario.value.osse_resolution_min == 15.0  # the study's
    assert paper_scenario.value.slot_s == paper_scenario.value.revisit_zero_s == 900.0
    sc = _with(paper_scenario, value__osse_resolution_min=60.0)
    assert sc.value.slot_s == sc.value.revisit_zero_s == 3600.0
    assert sc.value.field_step_s == 900.0
    assert _with(paper_scenario, value__osse_resolution_min=20.0).value.field_step_s == 600.0
    assert _with(paper_scenario, value__osse_resolution_min=5.0).value.field_step_s == 300.0


def test_decorrelation_below_the_drawing_step_and_floods_of_the_slow_field_are_refused(paper_scenario):
    with pytest.raises(ScenarioError, match="value.transiency_min.*drawing step"):
        _with(paper_scenario, value__transiency_min=10.0)
    # a 2-h OSSE of a field that decorrelates in 15 min is legal: the field is drawn every 15 min
    assert _with(paper_scenario, value__osse_resolution_min=120.0).value.transiency_min == 15.0
    with pytest.raises(ScenarioError, match="value.flash_floods"):
        _with(paper_scenario, value__transiency_min=0.0, value__flash_floods=False)


def test_a_coarser_osse_is_the_same_field_sampled_less_often(paper_scenario):
    """Oracle: the 15-min OSSE of the same seed and decorrelation, every 4th slot."""
    sc15 = paper_scenario.with_overrides(hours=3)
    sc60 = _with(sc15, value__osse_resolution_min=60.0)
    gps = ground_points(sc15)
    f15, f60 = osse_from_scenario(sc15, gps), osse_from_scenario(sc60, gps)
    assert f60.slot_s == 3600.0 and f60.n_slots == 3
    np.testing.assert_array_equal(f60.values, f15.values[::4])
    np.testing.assert_array_equal(f60.forecast, f15.forecast[::4])
    r15, r60 = f15.meta["rank"], f60.meta["rank"]
    assert r60["decorrelation_min"] == pytest.approx(r15["decorrelation_min"])
    assert r60["osse_resolution_min"] == 60.0 and r15["osse_resolution_min"] == 15.0
    assert 12.0 <= r15["decorrelation_min"] <= 18.0


def test_without_flash_floods_the_same_field_lacks_only_the_floods(paper_scenario):
    """A flood adds intensity and the value grows with intensity: the field without them is nowhere
    above the field with them, below it where a flood is, and the same elsewhere."""
    sc = paper_scenario.with_overrides(hours=3)
    gps = ground_points(sc)
    on = osse_from_scenario(sc, gps)
    off = osse_from_scenario(_with(sc, value__flash_floods=False), gps)
    assert on.meta["rank"]["flash_floods"] is True and off.meta["rank"]["flash_floods"] is False
    for a, b in ((off.values, on.values), (off.forecast, on.forecast)):
        assert np.all(a <= b)
    lower = off.values < on.values
    assert 0 < lower.mean() < 0.5, lower.mean()
    # the time constants are the same (calibrated on the field with its floods)
    assert off.meta["calibration"] == on.meta["calibration"]


def test_relative_change_by_lag_equals_a_loop_over_every_pair():
    rng = np.random.default_rng(3)
    v = rng.integers(1, 257, size=(7, 11))
    got = relative_change_by_lag(v)
    for k in range(7):
        pairs = [abs(int(v[s + k, g]) - int(v[s, g])) / int(v[s + k, g]) for s in range(7 - k) for g in range(11)]
        assert got["mean"][k] == pytest.approx(sum(pairs) / len(pairs))
        assert got["median"][k] == pytest.approx(float(np.median(pairs)))
    with pytest.raises(ValueError, match="> 0"):
        relative_change_by_lag(np.zeros((3, 2)))


def test_relative_change_between_slot_lags_is_the_average_over_look_times():
    """Brute force: looks at times spread uniformly over the field, each knowing the value ``lag``
    earlier, on a field held constant over each slot whose relative change at a slot lag does not
    depend on the start slot (geometric growth); their mean relative change equals the curve read
    at that lag."""
    slot = 900.0
    v = (1.0 + 0.1 * np.arange(9))[None, :] * 1.3 ** np.arange(12)[:, None]
    curve = relative_change_by_lag(v)["mean"]
    np.testing.assert_allclose(curve, 1.0 - 1.3 ** -np.arange(12.0))
    for lag in (0.0, 300.0, 900.0, 1234.5, 2700.0):
        # look times uniform over whole slots, their information inside the field
        t = np.arange(np.ceil(lag / slot) * slot, 12 * slot, 0.5) + 0.25
        now, then = (t // slot).astype(int), ((t - lag) // slot).astype(int)
        direct = float(np.mean(np.abs(v[now] - v[then]) / v[now]))
        assert relative_change_at(curve, slot, lag) == pytest.approx(direct, rel=1e-3, abs=1e-9)
    assert relative_change_at(curve, slot, 11 * slot) == pytest.approx(curve[11])
    assert relative_change_at(curve, slot, 11.5 * slot) is None
    assert relative_change_at(curve, slot, -1.0) is None
