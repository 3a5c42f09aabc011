"""bringup/analysis/assumed_error.py: the assumed-value error three ways and the same-slot / other-slot
split, on looks worked out by hand; and report.json carries it beside the unchanged mean."""

from __future__ import annotations

import math

import pytest

from bringup.analysis.assumed_error import assumed_error_figures, error_summary
from msgs_json import schemas as S

S_NS = 1_000_000_000


def _obs(t_s, info_s, assumed, gp=0):
    return S.Observation(sat="sat_11", gp=gp, t_ns=int(t_s * S_NS), assumed_value=assumed, recorded_value=100.0,
                         schedule_version=1, info_ns=None if info_s is None else int(info_s * S_NS))


def test_summary_by_hand():
    # errors |a - r| / r: 10/100 = 0.1, 5/10 = 0.5, 0/50 = 0; the r = 0 look is left out
    s = error_summary([110.0, 15.0, 50.0, 7.0], [100.0, 10.0, 50.0, 0.0])
    assert s["n"] == 3
    assert s["mean"] == pytest.approx(0.2) and s["median"] == pytest.approx(0.1)
    assert s["sum_based"] == pytest.approx(15.0 / 160.0)
    # sample sd of (0.1, 0.5, 0): deviations -0.1, 0.3, -0.2 -> sqrt(0.14 / 2)
    assert s["se"] == pytest.approx(math.sqrt(0.07) / math.sqrt(3))
    assert error_summary([1.0], [2.0])["se"] is None
    assert error_summary([], [])["mean"] is None and error_summary([], [])["n"] == 0


def test_slot_split_on_both_sides_of_a_boundary():
    rows = [
        (_obs(950.0, 900.0, 104.0), 100.0, False),    # slot 1, info in slot 1: same (error 0.04)
        (_obs(950.0, 899.999, 150.0), 100.0, False),  # info 1 ms before the slot: other (0.5)
        (_obs(1799.0, 900.0, 98.0), 100.0, False),    # last moment of slot 1: same (0.02)
        (_obs(1800.0, 900.0, 40.0), 50.0, False),     # first of slot 2: other (0.2)
        (_obs(2000.0, None, 10.0), 20.0, False),      # no information time: in neither (0.5)
        (_obs(2100.0, 2000.0, 10.0), 0.0, True),      # true value 0: in none
        (_obs(3600.0, 2800.0, 60.0), 50.0, False),    # t = horizon: the last slot (3), info in slot 3: same (0.2)
    ]
    f = assumed_error_figures(rows, 900.0, 3600.0)
    assert f["n"] == 6 and f["mean"] == pytest.approx((0.04 + 0.5 + 0.02 + 0.2 + 0.5 + 0.2) / 6)
    assert f["same_slot"]["n"] == 3 and f["same_slot"]["mean"] == pytest.approx((0.04 + 0.02 + 0.2) / 3)
    assert f["same_slot"]["sum_based"] == pytest.approx((4.0 + 2.0 + 10.0) / 250.0)
    assert f["other_slot"]["n"] == 2 and f["other_slot"]["median"] == pytest.approx(0.35)
    assert f["without_info_time"] == 1 and f["slot_s"] == 900.0
    with pytest.raises(ValueError, match="slot_s"):
        assumed_error_figures(rows, 0.0, 3600.0)


def test_report_carries_it_beside_the_unchanged_mean():
    from bringup.analysis.report import RunMeta, build_report
    from msgs_json import codec
    from msgs_json import topics as T
    from msgs_json.envelope import Envelope

    obs = [_obs(950.0, 900.0, 104.0, gp=1), _obs(2000.0, 100.0, 150.0, gp=2)]
    envs = [Envelope(o.t_ns, "sat_11", i, T.observations_topic("sat_11"), codec.encode(o)) for i, o in enumerate(obs)]
    meta = RunMeta(scenario="t", mode="distributed", engine="local", seed=1, horizon_s=3600.0, n_sats=1, n_gp=4,
                   slot_s=900.0)
    rep = build_report(envs, meta)
    e = rep["value"]["assumed_error"]
    assert rep["value"]["assumed_error_mean"] == pytest.approx(e["mean"]) == pytest.approx((0.04 + 0.5) / 2)
    assert e["same_slot"]["n"] == 1 and e["other_slot"]["n"] == 1 and e["other_slot"]["mean"] == pytest.approx(0.5)
    with pytest.raises(ValueError, match="slot_s"):
        RunMeta.from_dict(dict(meta.__dict__, slot_s=0.0))
    from bringup.analysis.report_md import report_md

    md = report_md(rep)
    assert "| error median / sum-based | 27.0 % / 27.0 % |" in md  # (4 + 50) / (100 + 100); median of 0.04, 0.5
    assert "| error of same-slot looks (mean, n) / other-slot looks | 4.0 % (1) / 50.0 % (1) |" in md
