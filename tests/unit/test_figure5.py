"""bringup/analysis/figure5.py on hand-built access windows and bundle events (gaps and margins worked out by hand)."""

from __future__ import annotations

import numpy as np
import pytest

from bringup.analysis.figure5 import bundle_rows, figure5_data, figure5_summary, plot_figure5
from msgs_json import schemas as S
from orbit_clock.access import AccessWindows

NS = 1_000_000_000
SATS = ["sat_11", "sat_12", "sat_13"]
GP_REGION = np.array([0, 0, 1])  # GPs 0, 1 in region 0; GP 2 in region 1


def _windows() -> AccessWindows:
    # (sat index, gp, start, end): sat_12 reaches region 0 at 80 s (GP 1) and 100 s (GP 0); sat_13 at
    # 500 s (GP 1); sat_13's window on GP 2 (region 1) at 300 s must not count for region 0.
    w = [(1, 0, 100.0, 150.0), (1, 1, 80.0, 90.0), (2, 1, 500.0, 520.0), (2, 2, 300.0, 320.0)]
    sat, gp, s, e = (np.array(x) for x in zip(*w))
    return AccessWindows(SATS, sat, gp, s, e, np.zeros(len(w)), 55.0, 0.0, 1000.0, {}, GP_REGION, ["R0", "R1"])


def _created(bid, dst, prio, t_s, gp):
    return S.BundleCreated(sat="sat_11", t_ns=int(t_s * NS), bundle_id=bid, src="sat_11", dst=dst, priority=prio,
                           creation_ns=int(t_s * NS), gp=gp, obs_t_ns=int(t_s * NS), lifetime_ns=900 * NS,
                           size_bits=2000)


def _delivered(bid, dst, prio, t0_s, t_s):
    return S.BundleDelivered(sat=dst, t_ns=int(t_s * NS), bundle_id=bid, src="sat_11", dst=dst, priority=prio,
                             creation_ns=int(t0_s * NS), hop_count=1)


def _events():
    return [
        _delivered("X", "sat_12", 1, 50, 70),  # a later copy: the first delivery (60 s) counts
        _created("X", "sat_12", 1, 50, 0), _delivered("X", "sat_12", 1, 50, 60),  # lat 10, gap 30: before
        _created("Y", "sat_13", 2, 50, 0), _delivered("Y", "sat_13", 2, 50, 600),  # lat 550, gap 450: late
        _created("Z", "sat_12", 1, 95, 1),  # gap 5 (sat_12 in view of region 0 at 100 s), never delivered
        _created("W", "sat_12", 1, 200, 0), _delivered("W", "sat_12", 1, 200, 210),  # no later access: no gap
        _delivered("Q", "sat_13", 3, 1, 2),  # delivered but never created in these events: ignored
    ]


def test_bundle_rows_first_delivery():
    rows = {r.bundle_id: r for r in bundle_rows(_events())}
    assert set(rows) == {"X", "Y", "Z", "W"}
    assert rows["X"].delivered_ns == 60 * NS and rows["Z"].delivered_ns is None and rows["Y"].gp == 0


def test_gaps_latencies_margins_by_hand():
    d = figure5_data(bundle_rows(_events()), _windows(), GP_REGION)
    p1, p2 = d["by_priority"][1], d["by_priority"][2]
    assert sorted(p1["latency_s"]) == [10.0, 10.0]
    assert sorted(p1["gap_s"]) == [5.0, 30.0]
    assert (p1["count"], p1["delivered"], p1["with_gap"], p1["arrived_before"]) == (3, 2, 2, 1)
    assert p1["margin_fraction"] == 0.5 and p1["margin_fraction_delivered"] == 1.0
    assert p2["latency_s"] == [550.0] and p2["gap_s"] == [450.0] and p2["margin_fraction"] == 0.0
    o = d["overall"]
    assert o["margin_fraction"] == pytest.approx(1 / 3) and o["margin_fraction_delivered"] == 0.5
    s = figure5_summary(d)
    assert s["by_priority"]["1"]["gap_s_median"] == 17.5 and s["by_priority"]["2"]["latency_s_median"] == 550.0


def test_in_view_at_creation_is_gap_zero_and_never_before():
    rows = bundle_rows([_created("A", "sat_12", 1, 120, 0), _delivered("A", "sat_12", 1, 120, 121)])
    d = figure5_data(rows, _windows(), GP_REGION)["by_priority"][1]
    assert d["gap_s"] == [0.0] and d["arrived_before"] == 0


def test_plot_written(tmp_path):
    d = figure5_data(bundle_rows(_events()), _windows(), GP_REGION)
    p = plot_figure5(tmp_path / "f5.png", d)
    assert p.exists() and p.stat().st_size > 1000


def test_plan_margin_needs_the_replan_before_the_access():
    # replans every 60 s: X (created 50, gap 30 -> access 80, last replan 60) arrives at 60: in time;
    # Y (created 50, access 500, last replan 480) arrives at 600: too late; Z undelivered.
    d = figure5_data(bundle_rows(_events()), _windows(), GP_REGION, replan_period_s=60.0)
    p1 = d["by_priority"][1]
    assert p1["arrived_before_plan"] == 1 and p1["plan_margin_fraction"] == 0.5
    # replans every 75 s: X's access at 80 s is planned at 75 s, after its arrival at 60 s: in time
    assert figure5_data(bundle_rows(_events()), _windows(), GP_REGION, 75.0)["by_priority"][1]["arrived_before_plan"] == 1
    # replans every 100 s: the plan for 80 s was made at 0 s, before X was even created
    assert figure5_data(bundle_rows(_events()), _windows(), GP_REGION, 100.0)["by_priority"][1]["arrived_before_plan"] == 0
    assert figure5_data(bundle_rows(_events()), _windows(), GP_REGION)["overall"]["plan_margin_fraction"] is None


def test_bundle_rows_per_recipient_of_a_multicast_bundle():
    """One multicast bundle "M" for sat_12 (P1) and sat_13 (P2): one row per recipient, each with its
    own first delivery; a delivery to sat_13 does not stand for sat_12's."""
    rows = bundle_rows([_created("M", "sat_12", 1, 50, 0), _created("M", "sat_13", 2, 50, 0),
                        _delivered("M", "sat_13", 2, 50, 58), _delivered("M", "sat_13", 2, 50, 70)])
    assert [(r.bundle_id, r.dst, r.priority, r.delivered_ns) for r in rows] == [
        ("M", "sat_12", 1, None), ("M", "sat_13", 2, 58 * NS)]
