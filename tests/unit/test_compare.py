"""bringup/analysis/compare.py: combining seeds (means at the top, sample sd, 95 % CI), ratios and tables on
hand-made reports (values worked out by hand)."""

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


def test_combine_means_at_the_top_with_sample_sd_and_ci():
    a, b = _rep("distributed", 100.0, 0.9, 10, 1, 0.04), _rep("distributed", 300.0, 0.7, 20, 3, None)
    a["engine"], b["engine"] = "local", "ros"  # a non-number the seeds disagree on: left out
    a["seed"], b["seed"] = 1, 2
    out = C.combine([a, b], [1, 2])
    # the top level holds the means over seeds, report-shaped (not seed 1's figures)
    assert out["value"]["cumulative"] == 200.0 and out["observations"]["count"] == 15.0
    assert out["coverage"]["gp_observed_fraction"] == pytest.approx(0.8)
    assert out["value"]["assumed_error_mean"] == 0.04  # null in seed 2: the mean of the others
    assert out["mode"] == "distributed" and "engine" not in out and out["seed"] == [1, 2]
    s = out["seeds"]
    assert s["seeds"] == [1, 2] and s["n"] == 2
    v = s["figures"]["value.cumulative"]
    # sample sd of (100, 300): sqrt((100^2 + 100^2) / 1); t(0.975, 1) = 12.706205: half-width 12.706205 x 100
    assert v["mean"] == 200.0 and v["sd"] == pytest.approx(math.sqrt(20000.0)) and v["n"] == 2
    assert v["ci95"] == pytest.approx([200.0 - 1270.6205, 200.0 + 1270.6205], abs=1e-3)
    assert v["per_seed"] == [100.0, 300.0] and (v["min"], v["max"]) == (100.0, 300.0)
    e = s["figures"]["value.assumed_error_mean"]
    assert e["mean"] == 0.04 and e["n"] == 1 and e["sd"] is None and e["per_seed"] == [0.04, None]
    assert s["figures"]["observations.count"]["per_seed"] == [10, 20]
    assert "seeds" not in a and a["seed"] == 1  # inputs not mutated


def test_mean_report_nested_and_missing_keys():
    r1 = {"a": {"x": 1, "y": [1, 2], "z": None}, "k": "same", "t": True}
    r2 = {"a": {"x": 3, "y": [1, 2], "w": 5.0}, "k": "same", "t": True}
    m = C.mean_report([r1, r2])
    assert m == {"a": {"x": 2.0, "y": [1, 2], "z": None, "w": 5.0}, "k": "same", "t": True}


def test_combine_rejects_mismatch():
    with pytest.raises(ValueError):
        C.combine([], [])
    with pytest.raises(ValueError):
        C.combine([_rep("x", 1, 1, 1, 0, 0)], [1, 2])


def test_ratios_per_seed_then_summary():
    by = {"distributed": [_rep("d", 120.0, 0.95, 100, 0, 0.04), _rep("d", 90.0, 0.9, 90, 0, 0.05)],
          "centralized": [_rep("c", 100.0, 0.99, 80, 2, 0.7), _rep("c", 100.0, 0.98, 85, 1, 0.5)],
          "nonagile": [_rep("n", 10.0, 0.08, 8, 0, 0.0), _rep("n", 0.0, 0.0, 0, 0, None)]}
    r = C.ratios(by, [1, 2])
    v = r["value.distributed_over_centralized"]
    assert v["per_seed"] == [pytest.approx(1.2), pytest.approx(0.9)]
    # sample sd of (1.2, 0.9) = 0.3 / sqrt(2); 95 % CI half-width t(0.975, 1) x sd / sqrt(2) = 12.706205 x 0.15
    assert v["mean"] == pytest.approx(1.05) and v["sd"] == pytest.approx(0.3 / math.sqrt(2.0))
    assert v["ci95"] == pytest.approx([1.05 - 12.706205 * 0.15, 1.05 + 12.706205 * 0.15], rel=1e-6)
    assert v["min"] == pytest.approx(0.9) and v["max"] == pytest.approx(1.2) and v["n"] == 2
    an = r["value.agile_over_nonagile"]
    assert an["per_seed"] == [pytest.approx(12.0), None]  # zero denominator -> null for that seed
    assert an["mean"] == pytest.approx(12.0) and an["sd"] is None and an["n"] == 1
    e = r["assumed_error.distributed_over_centralized"]
    assert e["per_seed"] == [pytest.approx(0.04 / 0.7), pytest.approx(0.1)]


def test_compare_result_shape_and_tables():
    by = {m: [_rep(m, v, f, 5, 0, 0.1)] for m, v, f in
          (("distributed", 50.0, 0.9), ("centralized", 40.0, 0.95), ("nonagile", 5.0, 0.1))}
    res = C.compare_result(by, [7])
    assert set(res) == {"distributed", "centralized", "nonagile", "ratios", "table2"}
    assert res["ratios"]["value.agile_over_nonagile"]["mean"] == pytest.approx(10.0)
    t = C.table_markdown(res)
    assert t.startswith("Mean over 1 seed.") and t.count("\n") == 6 and "| distributed | 50 | 90.0% |" in t
    assert "±" not in t  # one seed: no spread shown
    rm = C.ratios_markdown(res)
    assert "sample sd" in rm and "95 % CI" in rm and "value.distributed_over_centralized | 1.250 | - | - |" in rm
    # Table 2: the study's 11.3x is a coverage ratio (95.2 % / 8.4 %); our coverage ratio 0.9 / 0.1 = 9
    t2 = C.table2_markdown(res)
    assert "| coverage ratio agile / non-agile | 9.0x | - | 11.3x |" in t2
    assert "| GPs observed, agile (distributed) | 90.0% | - | 95.2% |" in t2
    assert "| value ratio agile / non-agile | 10.0x | - | not in the study |" in t2
    assert C.STUDY_TABLE2["coverage.agile_over_nonagile"] == pytest.approx(11.33, abs=0.005)


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
