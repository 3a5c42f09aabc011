"""`constellation compare` end to end on a reduced paper scenario (12 satellites, 1 h, 2 seeds).

Oracles: the JSON is exactly one object with the three modes, the ratios and the Table 2 rows; every
mode's entry has the report.json keys of docs/design.md section 6; its top-level figures are the
means over the seeds, and they, the sample standard deviations and the ratios equal an independent
recomputation (numpy) from each run folder's own report.json; agile beats non-agile in value; Figure 5's
gaps equal a brute-force recomputation from the raw access-window arrays.
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

pytestmark = [pytest.mark.system]

SATS, HOURS, SEEDS = 12, 1.0, 2

DESIGN_KEYS = [
    "scenario", "mode", "engine", "seed", "horizon_s", "n_sats", "value.cumulative", "value.assumed_error_mean",
    "coverage.gp_observed_fraction", "observations.count", "observations.duplicates_15min",
    "dtn.bundles_created", "dtn.bundles_delivered", "dtn.delivery_ratio", "dtn.latency_s.mean",
    "dtn.latency_s.median", "dtn.latency_s.p95", "dtn.latency_s.max", "dtn.dropped.ttl", "dtn.dropped.integrity",
    "dtn.dropped.other", "dtn.copies_discarded", "runtime.wall_s", "runtime.real_time_factor",
    "runtime.scheduler_cpu_s_per_sat",
]
_MISSING = object()


def _get(d, key):
    for p in key.split("."):
        if not isinstance(d, dict) or p not in d:
            return _MISSING
        d = d[p]
    return d


@pytest.fixture(scope="module")
def cmp(tmp_path_factory):
    out = tmp_path_factory.mktemp("compare")
    cmd = [sys.executable, "-m", "bringup.cli", "compare", "--scenario", "paper", "--sats", str(SATS), "--hours",
           str(HOURS), "--seeds", str(SEEDS), "--jobs", "2", "--json", "--out", str(out)]
    r = subprocess.run(cmd, check=False, capture_output=True, text=True, timeout=1200)
    assert r.returncode == 0, r.stderr[-3000:]
    return out, r.stdout


def test_json_is_one_object_with_design_keys(cmp):
    out, stdout = cmp
    res = json.loads(stdout)  # exactly one JSON document (json.loads rejects trailing data)
    assert set(res) == {"distributed", "centralized", "nonagile", "ratios", "table2", "provenance"}
    assert res["provenance"]["command"].startswith("constellation compare --scenario paper")
    for mode in ("distributed", "centralized", "nonagile"):
        rep = res[mode]
        missing = [k for k in DESIGN_KEYS if _get(rep, k) is _MISSING]
        assert not missing, f"{mode}: {missing}"
        assert rep["mode"] == mode and rep["n_sats"] == SATS and rep["seed"] == [1, 2]
        assert rep["seeds"]["seeds"] == [1, 2]
        for k in range(1, 16):
            assert _get(rep, f"dtn.latency_s_by_priority.{k}.median") is not _MISSING
    assert json.loads((out / "compare.json").read_text()).keys() == res.keys()


def test_means_and_ratios_recomputed_from_run_folders(cmp):
    out, stdout = cmp
    res = json.loads(stdout)
    reps = {m: [json.loads((out / f"{m}-s{s}" / "report.json").read_text()) for s in (1, 2)]
            for m in ("distributed", "centralized", "nonagile")}
    for m, rs in reps.items():
        assert [r["seed"] for r in rs] == [1, 2]
        vals = [r["value"]["cumulative"] for r in rs]
        fig = res[m]["seeds"]["figures"]["value.cumulative"]
        assert fig["mean"] == pytest.approx(np.mean(vals)) and fig["per_seed"] == vals
        assert fig["sd"] == pytest.approx(np.std(vals, ddof=1))
        assert res[m]["value"]["cumulative"] == pytest.approx(np.mean(vals))  # the mean, not seed 1's
        cov = [r["coverage"]["gp_observed_fraction"] for r in rs]
        assert res[m]["coverage"]["gp_observed_fraction"] == pytest.approx(np.mean(cov))
    r = res["ratios"]["value.distributed_over_centralized"]
    exp = [a["value"]["cumulative"] / b["value"]["cumulative"] for a, b in zip(reps["distributed"], reps["centralized"])]
    assert r["per_seed"] == pytest.approx(exp)
    assert r["mean"] == pytest.approx(np.mean(exp))


def test_agile_beats_nonagile(cmp):
    res = json.loads(cmp[1])
    for s in range(SEEDS):
        na = res["nonagile"]["seeds"]["figures"]["value.cumulative"]["per_seed"][s]
        assert res["distributed"]["seeds"]["figures"]["value.cumulative"]["per_seed"][s] > na
        assert res["centralized"]["seeds"]["figures"]["value.cumulative"]["per_seed"][s] > na
    # the ground never sends two satellites to one GP within 15 min (uplinked plans are commitments)
    assert res["centralized"]["observations"]["duplicates_15min"] == 0


def test_plots_and_figure5_gaps_brute_force(cmp):
    out, stdout = cmp
    res = json.loads(stdout)
    for name in ("value_over_time.png", "figure5.png"):
        p = out / "plots" / name
        assert p.exists() and 0 < p.stat().st_size < 300_000
    from bringup.analysis.figure5 import bundle_rows_from_bag, figure5_data
    from bringup.scenario.config import load_scenario
    from bringup.scenario.world import World

    sc = load_scenario("paper").with_overrides(sats=SATS, hours=HOURS, seed=1)
    world = World.cached(sc, out / "distributed-s1" / "cache")
    rows = bundle_rows_from_bag(out / "distributed-s1" / "bag")
    assert rows, "no bundles in the distributed run"
    data = figure5_data(rows, world.access, world.ctx.gps.region_index)
    acc, reg = world.access, world.ctx.gps.region_index
    names = list(acc.sat_names)
    for p, d in data["by_priority"].items():
        brute = []
        for r in (x for x in rows if x.priority == p):
            t = r.created_ns / 1e9
            m = (acc.sat == names.index(r.dst)) & (reg[acc.gp] == reg[r.gp]) & (acc.end_s > t)
            if m.any():
                brute.append(float(np.min(np.maximum(acc.start_s[m], t))) - t)
        assert sorted(d["gap_s"]) == pytest.approx(sorted(brute), abs=1e-9)
        assert d["count"] == sum(1 for x in rows if x.priority == p)
    assert res["distributed"]["figure5"]["overall"]["count"] == len(rows)
