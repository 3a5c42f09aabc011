"""`constellation sweep --grid`: a real 2 keys x 2 values x 3 seeds sweep (6 satellites, 0.5 h, local
engine), killed (SIGKILL) after its first stored runs and started again: the stored runs are not
rerun (their files untouched), the missing ones are made; its tidy CSV, grouped by cell and metric
with the csv module, statistics.stdev and scipy's t interval (not the project's code), gives
sweep.json's means, sample standard deviations and 95 % intervals; the plots are written. A named
preset sweep (the ISL rate) honours --seeds."""

from __future__ import annotations

import csv
import json
import math
import os
import signal
import statistics
import subprocess
import sys
import time
from collections import defaultdict

import pytest
from scipy import stats as sps

pytestmark = [pytest.mark.system]

GRID = "instrument.for_off_nadir_deg=50,55 scheduler.replan_period_s=300,600"
CMD = ["-m", "bringup.cli", "sweep", "--grid", GRID, "--seeds", "3", "--sats", "6", "--hours", "0.5",
       "--engine", "local"]


def test_killed_sweep_resumes_and_its_csv_gives_the_json(tmp_path):
    out = tmp_path / "sweep"
    stored = out / "runs" / "local"
    p = subprocess.Popen([sys.executable, *CMD, "--out", str(out)], stdout=subprocess.DEVNULL,
                         stderr=subprocess.PIPE, start_new_session=True)
    try:
        t0 = time.monotonic()
        while not list(stored.glob("*.json")) and p.poll() is None and time.monotonic() - t0 < 300:
            time.sleep(0.02)
        assert p.poll() is None, p.stderr.read().decode()[-2000:]
        os.killpg(p.pid, signal.SIGKILL)
    finally:
        p.wait(timeout=60)
    done = {f: f.stat().st_mtime_ns for f in stored.glob("*.json")}
    assert 1 <= len(done) < 12 and not (out / "sweep.json").exists()

    r = subprocess.run([sys.executable, *CMD, "--out", str(out), "--json"], capture_output=True, text=True,
                       timeout=600, check=False)
    assert r.returncode == 0, r.stderr[-3000:]
    assert f"12 runs, {len(done)} already done (reused), {12 - len(done)} to run" in r.stderr
    assert {f: f.stat().st_mtime_ns for f in done} == done  # the stored runs were not made again
    assert len(list(stored.glob("*.json"))) == 12

    res = json.loads((out / "sweep.json").read_text())
    assert json.loads(r.stdout) == res
    assert res["axes"] == ["instrument.for_off_nadir_deg", "scheduler.replan_period_s"]
    assert res["seeds"] == [1, 2, 3] and len(res["cells"]) == 4
    assert {"scenario_toml", "version", "git_commit", "command", "python", "dependencies"} <= set(res["provenance"])

    groups: dict[tuple[str, str], list[float]] = defaultdict(list)
    with open(out / "sweep.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    for row in rows:
        groups[(row["cell"], row["metric"])].append(float(row["value"]))
    assert {row["seed"] for row in rows} == {"1", "2", "3"}
    by_id = {c["cell"]: c for c in res["cells"]}
    for row in rows:  # each row's parameters are its cell's
        c = by_id[row["cell"]]
        assert float(row["instrument.for_off_nadir_deg"]) == c["params"]["instrument.for_off_nadir_deg"]
        assert float(row["scheduler.replan_period_s"]) == c["params"]["scheduler.replan_period_s"]
    n_checked = 0
    for (cell, metric), xs in groups.items():
        c = by_id[cell]
        assert c["n"][metric] == len(xs) and c["mean"][metric] == pytest.approx(statistics.mean(xs), abs=1e-9)
        if len(xs) > 1:
            sd = statistics.stdev(xs)
            assert c["sd"][metric] == pytest.approx(sd, abs=1e-9)
            if sd > 0:
                lo, hi = sps.t.interval(0.95, len(xs) - 1, loc=statistics.mean(xs), scale=sd / math.sqrt(len(xs)))
                assert c["ci95"][metric] == pytest.approx([lo, hi])
                n_checked += 1
    assert n_checked >= 2, "some figure must vary over the seeds"
    assert len(groups) == sum(1 for c in res["cells"] for m in res["metrics"] if c["n"][m])
    assert (out / "plots" / "value_cumulative.png").stat().st_size > 1000


def test_a_named_sweep_honours_seeds(tmp_path):
    """The ISL-rate preset with --seeds 2: each row a mean over two seeds, its CSV rows per seed."""
    out = tmp_path / "preset"
    r = subprocess.run([sys.executable, "-m", "bringup.cli", "sweep", "--only", "isl_rate_bps", "--isl-rate-bps",
                        "250,1000", "--seeds", "2", "--sats", "6", "--hours", "0.5", "--no-plots", "--out", str(out)],
                       capture_output=True, text=True, timeout=600, check=False)
    assert r.returncode == 0, r.stderr[-3000:]
    res = json.loads((out / "sweep.json").read_text())
    assert [(row["value"], row["baseline"], row["n_seeds"]) for row in res["rows"]] == [(250.0, False, 2),
                                                                                      (1000.0, True, 2)]
    with open(out / "sweep.csv", newline="") as fh:
        rows = [x for x in csv.DictReader(fh) if x["metric"] == "value.cumulative"]
    assert sorted((x["isl_rate_bps"], x["seed"]) for x in rows) == [("1000.0", "1"), ("1000.0", "2"),
                                                                    ("250.0", "1"), ("250.0", "2")]
    for row in res["rows"]:
        vals = [float(x["value"]) for x in rows if float(x["isl_rate_bps"]) == row["value"]]
        assert row["value_cumulative"] == pytest.approx(statistics.mean(vals))
    assert "seeds [1, 2], mean over them" in r.stdout and "| isl_rate_bps | 1000 * |" in r.stdout


@pytest.mark.ros
@pytest.mark.slow
def test_a_ros_engine_sweep_stores_run_folders_and_resumes(tmp_path):
    """--engine ros: each cell x seed a whole `constellation run --engine ros` folder (bag, report.json
    with its provenance) on the cell's resolved scenario; a second call reuses it."""
    out = tmp_path / "ros"
    cmd = [sys.executable, "-m", "bringup.cli", "sweep", "--grid", "isl.rate_bps=250", "--seeds", "1", "--sats",
           "3", "--hours", "0.05", "--engine", "ros", "--no-plots", "--set", "value.knowledge=observed",
           "--out", str(out)]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=900, check=False)
    assert r.returncode == 0, r.stderr[-3000:]
    (folder,) = [p for p in (out / "runs" / "ros").iterdir() if p.is_dir()]
    rep = json.loads((folder / "report.json").read_text())
    assert rep["engine"] == "ros" and (folder / "bag").is_dir()
    toml = rep["provenance"]["scenario_toml"]
    assert "rate_bps = 250.0" in toml and 'knowledge = "observed"' in toml
    again = subprocess.run(cmd, capture_output=True, text=True, timeout=300, check=False)
    assert again.returncode == 0 and "1 run, 1 already done (reused), 0 to run" in again.stderr
    assert json.loads((out / "sweep.json").read_text())["cells"][0]["n"]["value.cumulative"] == 1
