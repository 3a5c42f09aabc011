"""bringup/analysis/compare.py: combining seeds, ratios and tables on hand-made reports (values worked out by hand)."""

from __future__ import annotations

import math

import pytest

from bringup.analysis import compare as C


def _rep(mode, value, frac, n, dup, err):
    return {"mode": mode, "value": {"cumulative": value, "assumed_error_mean": err},
            "coverage": {"gp_observed_fraction": frac}, "observations": {"count": n, "duplicates_15min": dup}}


def test_get_path():
    r = _rep("distributed", 10.0, 0.5, 3, 0, 0.1)
    assert C.get_path(r, "value.cumulative") == 10.0
    assert C.get_path(r, "value.nope") is None
    assert C.get_path(r, "mode.x") is None


def test_combine_first_report_plus_mean_std():
    a, b = _rep("distributed", 100.0, 0.9, 10, 1, 0.04), _rep("distributed", 300.0, 0.7, 20, 3, None)
    out = C.combine([a, b], [1, 2])
    assert out["value"]["cumulative"] == 100.0  # first seed's report unchanged
    s = out["seeds"]
    assert s["seeds"] == [1, 2]
    assert s["mean"]["value.cumulative"] == 200.0
    assert s["std"]["value.cumulative"] == 100.0  # population std of 100, 300
    assert s["mean"]["coverage.gp_observed_fraction"] == pytest.approx(0.8)
    assert s["mean"]["value.assumed_error_mean"] == 0.04  # null in seed 2: mean over the rest
    assert s["per_seed"]["observations.count"] == [10, 20]
    assert "seeds" not in a  # inputs not mutated


def test_combine_rejects_mismatch():
    with pytest.raises(ValueError):
        C.combine([], [])
    with pytest.raises(ValueError):
        C.combine([_rep("x", 1, 1, 1, 0, 0)], [1, 2])


def test_ratios_per_seed_then_spread():
    by = {"distributed": [_rep("d", 120.0, 0.95, 100, 0, 0.04), _rep("d", 90.0, 0.9, 90, 0, 0.05)],
          "centralized": [_rep("c", 100.0, 0.99, 80, 2, 0.7), _rep("c", 100.0, 0.98, 85, 1, 0.5)],
          "nonagile": [_rep("n", 10.0, 0.08, 8, 0, 0.0), _rep("n", 0.0, 0.0, 0, 0, None)]}
    r = C.ratios(by, [1, 2])
    v = r["value.distributed_over_centralized"]
    assert v["per_seed"] == [pytest.approx(1.2), pytest.approx(0.9)]
    assert v["mean"] == pytest.approx(1.05) and v["std"] == pytest.approx(0.15)
    assert v["min"] == pytest.approx(0.9) and v["max"] == pytest.approx(1.2)
    an = r["value.agile_over_nonagile"]
    assert an["per_seed"] == [pytest.approx(12.0), None]  # zero denominator -> null for that seed
    assert an["mean"] == pytest.approx(12.0) and an["std"] == 0.0
    e = r["assumed_error.distributed_over_centralized"]
    assert e["per_seed"] == [pytest.approx(0.04 / 0.7), pytest.approx(0.1)]


def test_compare_result_shape_and_tables():
    by = {m: [_rep(m, v, f, 5, 0, 0.1)] for m, v, f in
          (("distributed", 50.0, 0.9), ("centralized", 40.0, 0.95), ("nonagile", 5.0, 0.1))}
    res = C.compare_result(by, [7])
    assert set(res) == {"distributed", "centralized", "nonagile", "ratios"}
    assert res["ratios"]["value.agile_over_nonagile"]["mean"] == pytest.approx(10.0)
    t = C.table_markdown(res)
    assert t.count("\n") == 4 and "| distributed | 50 | 90.0% |" in t
    assert "±" not in t  # one seed: no spread shown
    assert "value.distributed_over_centralized | 1.250" in C.ratios_markdown(res)


def test_stats_ignores_non_finite():
    s = C._stats([1.0, None, float("nan"), 3.0])
    assert s["n"] == 2 and s["mean"] == 2.0 and math.isclose(s["std"], 1.0)


def test_scenario_variant_changes_one_parameter(paper_scenario):
    sc = paper_scenario.with_overrides(sats=12)
    v = C.scenario_variant(sc, replan_period_s=300.0)
    assert v.scheduler.replan_period_s == 300.0 and v.scheduler.plan_lookahead_s == 300.0 and v.isl == sc.isl
    assert C.scenario_variant(sc, isl_rate_bps=4000.0).isl.rate_bps == 4000.0
    w = C.scenario_variant(sc, sats_per_plane=2)
    assert w.constellation.total_sats == 2 * sc.constellation.planes
    assert [s.name for s in C.scenario_variant(sc, n_stations=1).ground.stations] == [sc.ground.stations[0].name]
    from bringup.errors import UserError

    with pytest.raises(UserError):
        C.scenario_variant(sc, n_stations=5)


def test_cli_rejects_bad_counts_in_one_line(capsys):
    from bringup.cli.main import main

    assert main(["compare", "--seeds", "0", "--out", "/nonexistent/never-written"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--seeds 0" in err[0]
    assert main(["sweep", "--replan-s", "300,abc"]) == 2
    assert "--replan-s" in capsys.readouterr().err


def test_sweep_rows_plan_marks_the_baseline(paper_scenario):
    import argparse

    from bringup.cli import sweep

    p = argparse.ArgumentParser()
    sweep.add_arguments(p)
    args = p.parse_args(["--replan-s", "300,600", "--sats-per-plane", "4,8", "--only", "replan_period_s",
                         "--only", "sats_per_plane"])
    rows = sweep._rows_plan(paper_scenario, args)
    assert [(r[0], r[1], r[2], r[4]) for r in rows] == [
        ("replan_period_s", 300.0, "distributed", False), ("replan_period_s", 600.0, "distributed", True),
        ("sats_per_plane", 4, "distributed", False), ("sats_per_plane", 4, "nonagile", False),
        ("sats_per_plane", 8, "distributed", True), ("sats_per_plane", 8, "nonagile", True)]
    md = sweep.table_markdown({"scenario": "paper", "sats": 24, "hours": 6.0, "seed": 1, "rows": [
        {"parameter": "replan_period_s", "value": 600.0, "baseline": True, "mode": "distributed", "n_sats": 24,
         "value_cumulative": 41050.1, "gp_observed_fraction": 0.994, "observations": 3332, "duplicates_15min": 85,
         "assumed_error_mean": 0.063, "delivery_ratio": None}]})
    assert "| replan_period_s | 600 * | distributed | 24 | 41050 | 99.4% | 3332 | 85 | 6.3% | - |" in md


def test_mean_ci95_by_hand():
    r = C.mean_ci95([1.0, 2.0, 3.0, None, float("nan")])
    # mean 2, sample sd 1, t(0.975, 2) = 4.302653: half-width 4.302653 / sqrt(3)
    assert r["mean"] == 2.0 and r["n"] == 3 and r["ci95"] == pytest.approx(4.302653 / math.sqrt(3), rel=1e-6)
    assert C.mean_ci95([5.0])["ci95"] is None and C.mean_ci95([])["mean"] is None


def test_transiency_sweep_rows_and_plot(paper_scenario, tmp_path):
    """The transiency sweep's rows from given reports (a fake run): per-seed ratios, their mean and
    interval, the variants' transiency and seed, and the plot of them."""
    from bringup.analysis.figures import figure_transiency_sweep, plot_transiency_sweep
    from bringup.cli.sweep import transiency_markdown, transiency_rows

    seen = []

    def fake(sc, mode):
        seen.append((sc.value.transiency_min, sc.scenario.seed, mode))
        v = 100.0 * sc.scenario.seed + (50.0 if mode == "distributed" else 0.0) - sc.value.transiency_min
        return {"value": {"cumulative": v}, "osse": {"transiency_min": sc.value.transiency_min * 1.1},
                "knowledge": {"info_age_s": {"median": 60.0}}}

    rows = transiency_rows(paper_scenario, [15.0, 60.0], [1, 2], run=fake)
    assert seen == [(15.0, 1, "distributed"), (15.0, 1, "centralized"), (15.0, 2, "distributed"),
                    (15.0, 2, "centralized"), (60.0, 1, "distributed"), (60.0, 1, "centralized"),
                    (60.0, 2, "distributed"), (60.0, 2, "centralized")]
    want = [135.0 / 85.0, 235.0 / 185.0]
    assert rows[0]["values"] == pytest.approx(want) and rows[0]["mean"] == pytest.approx(sum(want) / 2)
    assert rows[0]["measured_min"] == pytest.approx(16.5) and rows[1]["ci95"] > 0
    md = transiency_markdown({"scenario": "paper", "sats": 24, "hours": 6.0, "seeds": [1, 2], "knowledge": "observed",
                              "rows": rows})
    assert md.count("\n| ") == 3 and "| 1.429 |" in md
    fig = figure_transiency_sweep(rows)
    line = fig.axes[0].lines[0]
    assert list(line.get_xdata()) == [15.0, 60.0]
    assert plot_transiency_sweep(tmp_path / "t.png", rows).stat().st_size > 1000
