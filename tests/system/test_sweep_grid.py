"""`constellation sweep --grid`: a real 2 keys x 2 values x 3 seeds sweep (6 satellites, 0.5 h, local
engine), killed (SIGKILL) after its first stored runs and started again: the stored runs are not
rerun (their files untouched), the missing ones are made; its tidy CSV, grouped by cell and metric
with the csv module, statistics.stdev and scipy's t interval (not the project's code), gives
sweep.json's means, sample standard deviations and 95 % intervals; the plots are written."""

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
