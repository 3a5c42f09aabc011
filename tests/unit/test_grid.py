"""Parameter grids (bringup/analysis/grid.py, grid_figures.py) and `sweep`'s options: parsing and the
product, the summary against the standard library's statistics and scipy's t interval, the tidy
CSV, the named sweeps as presets equal to the variants they always made, refused options."""

from __future__ import annotations

import argparse
import csv
import io
import math
import statistics

import pytest
from scenario_edit import raw_scenario
from scipy import stats as sps

from bringup.analysis.compare import scenario_variant
from bringup.analysis.grid import cells_of, csv_text, parse_grid, split_values, summary
from bringup.errors import UserError
from bringup.scenario.overrides import apply_sets


def test_parse_grid_and_the_product():
    axes = parse_grid(["isl.rate_bps=250,1000,8000 scheduler.replan_period_s=300,600",
                       'acs.slew_coeffs_s=[1.0, 2.0],[3.0] value.knowledge=observed,"oracle"'])
    assert [a.name for a in axes] == ["isl.rate_bps", "scheduler.replan_period_s", "acs.slew_coeffs_s",
                                      "value.knowledge"]
    assert axes[0].labels == (250, 1000, 8000) and axes[2].labels == ([1.0, 2.0], [3.0])
    assert axes[3].labels == ("observed", "oracle")
    cells = cells_of(axes[:2], ["distributed", "centralized"])
    assert len(cells) == 12 and [c.id for c in cells][:2] == ["c1", "c2"]
    assert cells[0].params == {"isl.rate_bps": 250, "scheduler.replan_period_s": 300}
    assert cells[1].params == {"isl.rate_bps": 250, "scheduler.replan_period_s": 600}  # last axis fastest
    assert cells[6].mode == "centralized" and cells[6].sets == (("isl.rate_bps", 250), ("scheduler.replan_period_s", 300))
    assert split_values('1,"a,b",[2, 3]') == ["1", '"a,b"', "[2, 3]"]


@pytest.mark.parametrize("text,named", [
    ("isl.rate_bps", "KEY=V1,V2"),
    ("isl.rate_bps=1,,2", "empty value"),
    ("isl.rate_bps=1,1", "given twice"),
    ("isl.rate_bps=1 isl.rate_bps=2", "given twice"),
    ("scenario.seed=1,2", "--seeds"),
    ("isl.rate_bps=[1,", "not a TOML value"),
    ("9x=1", "not a dotted scenario key"),
])
def test_bad_grids_are_one_line(text, named):
    with pytest.raises(UserError) as e:
        parse_grid([text])
    assert named in str(e.value) and "\n" not in str(e.value)


def _rep(v, obs, err=None):
    return {"value": {"cumulative": v, "assumed_error_mean": err}, "observations": {"count": obs}}


def test_summary_and_csv_against_statistics_and_scipy():
    cells = cells_of(parse_grid(["isl.rate_bps=250,1000"]), ["distributed"])
    seeds = [1, 2, 3]
    vals = {("c1", 1): 10.0, ("c1", 2): 14.0, ("c1", 3): 11.5, ("c2", 1): 3.0, ("c2", 2): 3.0, ("c2", 3): 9.0}
    reports = {k: _rep(v, 5, err=0.1 if k == ("c1", 1) else None) for k, v in vals.items()}
    metrics = ["value.cumulative", "observations.count", "value.assumed_error_mean", "dtn.delivery_ratio"]
    res = summary(cells, reports, seeds, metrics)
    for c in res["cells"]:
        x = [vals[(c["cell"], s)] for s in seeds]
        m, sd = statistics.mean(x), statistics.stdev(x)
        lo, hi = sps.t.interval(0.95, len(x) - 1, loc=m, scale=sd / math.sqrt(len(x)))
        assert c["mean"]["value.cumulative"] == pytest.approx(m) and c["sd"]["value.cumulative"] == pytest.approx(sd)
        assert c["ci95"]["value.cumulative"] == pytest.approx([lo, hi])
        assert c["n"]["dtn.delivery_ratio"] == 0 and c["mean"]["dtn.delivery_ratio"] is None
    assert res["cells"][0]["n"]["value.assumed_error_mean"] == 1 and res["cells"][0]["sd"]["value.assumed_error_mean"] is None
    rows = list(csv.DictReader(io.StringIO(csv_text(cells, reports, seeds, metrics, ["isl.rate_bps"]))))
    # 6 runs x 2 metrics every report has, + the one error value; nothing for the missing ones
    assert len(rows) == 13 and set(rows[0]) == {"cell", "mode", "isl.rate_bps", "seed", "metric", "value"}
    assert {r["isl.rate_bps"] for r in rows if r["cell"] == "c2"} == {"1000"}


def _sweep_args(*argv):
    from bringup.cli import sweep

    p = argparse.ArgumentParser()
    sweep.add_arguments(p)
    return p.parse_args(list(argv))


def test_named_sweeps_are_presets_equal_to_their_old_variants(paper_scenario):
    from bringup.cli import sweep

    sc = paper_scenario
    plan = sweep._rows_plan(sc, _sweep_args())
    assert {r[0] for r in plan} == set(sweep.PARAMS) and len(plan) == 3 + 3 + 6 + 2
    for param, v, _mode, changes, _ in plan:
        got = apply_sets(sc, list(sweep.preset_sets(sc, param, v)))
        assert raw_scenario(got) == raw_scenario(scenario_variant(sc, **changes)), (param, v)


@pytest.mark.parametrize("argv,named", [
    (["--grid", "isl.rate_bps=1,2", "--replan-s", "300"], "--replan-s"),
    (["--grid", "isl.rate_bps=1,2", "--only", "isl_rate_bps"], "--only"),
    (["--transiency", "15,60", "--engine", "ros"], "--engine ros"),
    (["--transiency", "15,60", "--mode", "centralized"], "--mode"),
    (["--mode", "centralized"], "--mode goes with --grid"),
    (["--grid", "scenario.seed=1,2"], "--seeds"),
    (["--sats", "6", "--grid", "constellation.total_sats=6,12"], "--sats"),
    (["--grid", "isl.rate_bps=abc,1000"], "isl.rate_bps"),
    (["--grid", "isl.nosuch=1,2"], "nosuch"),
    (["--seeds", "0"], "--seeds 0"),
])
def test_sweep_refuses_what_it_would_ignore(tmp_path, capsys, argv, named):
    from bringup.cli.main import main

    assert main(["sweep", *argv, "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and named in err[0], err
    assert not (tmp_path / "out").exists()


def test_sweep_figure_draws_the_means_and_the_band():
    from bringup.analysis.grid_figures import figure_metric

    cells = cells_of(parse_grid(["isl.rate_bps=250,1000"]), ["distributed"])
    reports = {(c.id, s): _rep(v + s, 1) for c, v in zip(cells, (10.0, 20.0)) for s in (1, 2, 3)}
    res = summary(cells, reports, [1, 2, 3], ["value.cumulative"])
    fig = figure_metric(res, "value.cumulative", ["isl.rate_bps"])
    line = fig.axes[0].lines[0]
    assert list(line.get_xdata()) == [250.0, 1000.0] and list(line.get_ydata()) == [12.0, 22.0]
    band = fig.axes[0].collections[0].get_paths()[0].vertices
    lo, hi = res["cells"][0]["ci95"]["value.cumulative"]
    assert band[:, 1].min() == pytest.approx(min(lo, res["cells"][1]["ci95"]["value.cumulative"][0]))
    assert band[:, 1].max() == pytest.approx(max(hi, res["cells"][1]["ci95"]["value.cumulative"][1]))
