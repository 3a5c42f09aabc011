"""One run per output folder, no stale outputs, the run's state on disk, --out where the user meant.

Oracles:
* two runs into one --out: the second is refused at once (exit 2, one line naming the first's pid)
  and the first's report is its own - equal to the same run made alone in another folder (before,
  both exited 0 and the first printed the second's result);
* the outputs of an earlier run are gone when a run starts (a report.json, plots, a bag), files the
  run does not write stay; a run that fails leaves ``run_status.json`` = failed and no report of
  another run;
* a run killed with SIGKILL leaves no lock behind: the next run into the folder goes ahead;
* ``run --engine ros --out REL`` from another working folder writes into that folder's REL (the
  ROS processes run in the repository's folder).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from bringup.cli.main import main

pytestmark = [pytest.mark.faults]

REPO = Path(__file__).resolve().parents[2]
RUN = ["run", "--engine", "local", "--sats", "6", "--no-plots", "--no-progress"]


def _start(out: Path, *extra: str, cwd: Path = REPO) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "bringup.cli", *RUN, *extra, "--out", str(out)], cwd=cwd,
                            stderr=subprocess.PIPE, text=True, env={**os.environ, "PYTHONPATH": str(REPO)})


def _wait_running(out: Path, proc: subprocess.Popen, timeout_s: float = 120.0) -> dict:
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout_s:
        assert proc.poll() is None, proc.stderr.read()
        try:
            st = json.loads((out / "run_status.json").read_text())
            if st.get("status") == "running" and st.get("pid") == proc.pid:
                return st
        except (OSError, ValueError):
            pass
        time.sleep(0.005)
    raise AssertionError("the run did not start")


def _figures(rep: dict) -> dict:
    return {k: rep[k] for k in ("seed", "value", "observations", "dtn", "coverage", "partial")}


def test_two_runs_into_one_out(tmp_path, capsys):
    alone = tmp_path / "alone"
    assert main([*RUN, "--hours", "3", "--out", str(alone)]) == 0
    capsys.readouterr()
    out = tmp_path / "shared"
    first = _start(out, "--hours", "3")
    try:
        _wait_running(out, first)
        code = main([*RUN, "--hours", "3", "--seed", "2", "--out", str(out)])
        err = capsys.readouterr().err.strip().splitlines()
        assert code == 2 and len(err) == 1
        assert "another run is writing into this folder" in err[0] and f"pid {first.pid}" in err[0]
        _, ferr = first.communicate(timeout=600)
        assert first.returncode == 0, ferr
    finally:
        if first.poll() is None:
            first.kill()
            first.wait()
    rep = json.loads((out / "report.json").read_text())
    assert _figures(rep) == _figures(json.loads((alone / "report.json").read_text()))  # its own result
    assert json.loads((out / "run_status.json").read_text())["status"] == "complete"
    assert main(["report", str(out / "bag")]) == 0
    assert _figures(json.loads(capsys.readouterr().out)) == _figures(rep)  # its own bag


def test_stale_outputs_are_removed_and_a_failed_run_says_so(tmp_path, capsys):
    out = tmp_path / "r"
    (out / "plots").mkdir(parents=True)
    (out / "plots" / "old.png").write_bytes(b"png")
    (out / "bag").mkdir()
    (out / "bag" / "bag.mcap").write_bytes(b"an earlier run's bag")
    (out / "report.json").write_text('{"value": {"cumulative": 99999}}')
    (out / "notes.txt").write_text("mine")
    assert main([*RUN, "--hours", "0.25", "--out", str(out)]) == 0
    assert not (out / "plots").exists() and json.loads((out / "report.json").read_text())["value"]["cumulative"] != 99999
    assert (out / "notes.txt").read_text() == "mine" and (out / "cache").is_dir()
    # a run that fails after it started (an OSSE file that is not one): the earlier report is gone
    junk = tmp_path / "field.nc"
    junk.write_bytes(b"not netcdf" * 10)
    from scenario_edit import raw_scenario, to_toml

    from bringup.scenario.config import load_scenario

    raw = raw_scenario(load_scenario("paper"))
    raw["value"].update(osse_source="file", osse_file=str(junk))
    bad = tmp_path / "bad.toml"
    bad.write_text(to_toml(raw))
    capsys.readouterr()
    assert main([*RUN, "--hours", "0.25", "--scenario", str(bad), "--out", str(out)]) == 2
    assert "field.nc" in capsys.readouterr().err
    status = json.loads((out / "run_status.json").read_text())
    assert status["status"] == "failed" and "field.nc" in status["error"]
    assert not (out / "report.json").exists() and not (out / "bag").exists()
    assert (out / "notes.txt").exists()


def test_a_killed_run_leaves_no_lock(tmp_path, capsys):
    out = tmp_path / "r"
    proc = _start(out, "--hours", "6")
    try:
        _wait_running(out, proc)
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert json.loads((out / "run_status.json").read_text())["status"] == "running"  # it never ended
    time.sleep(0.5)  # (its recorder child reads end-of-file and leaves)
    assert main([*RUN, "--hours", "0.25", "--out", str(out)]) == 0
    assert json.loads((out / "run_status.json").read_text())["status"] == "complete"


@pytest.mark.ros
def test_relative_out_from_another_folder_ros(tmp_path):
    here = tmp_path / "elsewhere"
    here.mkdir()
    r = subprocess.run([sys.executable, "-m", "bringup.cli", "run", "--engine", "ros", "--sats", "6", "--hours",
                        "0.25", "--no-plots", "--no-progress", "--out", "rel/out"], cwd=here, capture_output=True,
                       text=True, timeout=600,
                       env={**os.environ, "PYTHONPATH": str(REPO), "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"})
    assert r.returncode == 0, r.stderr
    out = here / "rel" / "out"
    assert json.loads((out / "report.json").read_text())["engine"] == "ros"
    assert (out / "bag" / "bag.mcap").exists() and (out / "logs" / "clock.log").exists()
    assert json.loads((out / "run_spec.json").read_text())["bag_dir"] == str(out / "bag")
    assert not (REPO / "rel").exists()
