"""`constellation task` on a live 12-satellite ROS run (``constellation run --live-commands``), and the
same request scripted in the scenario on the local engine.

The run: the paper's scenario, 12 satellites, 0.5 h, stations Svalbard and Troll, paced at 20x so
the CLI can reach it while it runs; the test waits until the run is 50 s in (its ``now.json``). The
CLI tasks sat_12 with a ground point of Dallas (priority 1,
deadline 1500 s; sat_12 flies over Dallas from ~760 s) and prints the issue time the run's ground
gateway gave it. Oracles: the target is observed, in time, by the satellite that received and
executed the command, and the report gives the command's uplink and execution latency; then the same
request scripted as ``[[commands]]`` at that issue time on the local engine gives the same task
result and latencies (the engines' equality, tests/system/test_engines_equal.py).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time

import pytest

from tests.system.test_operations_tasking_run import run as run_engine
from tests.system.test_operations_tasking_run import scenario

pytestmark = [pytest.mark.system, pytest.mark.ros]

TASK = {"lat_deg": 32.7767, "lon_deg": -96.797, "priority": 1, "by": "2000-01-01T12:24:28Z"}


def _cli(*a: str) -> list[str]:
    return [sys.executable, "-m", "bringup.cli", *a]


def test_live_task_on_a_ros_run_and_the_same_scripted_on_the_local_engine(tmp_path):
    sc = scenario(tmp_path / "live.toml", commands=[])
    out = tmp_path / "live"
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    runp = subprocess.Popen(_cli("run", "--engine", "ros", "--live-commands", "--real-time-factor", "20",
                                 "--scenario", str(sc), "--sats", "12", "--hours", "0.5", "--out", str(out),
                                 "--no-plots", "--no-progress"),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        t_end = time.monotonic() + 600
        now = out / "operator" / "now.json"  # the run's time at its latest step
        while not (now.exists() and json.loads(now.read_text())["t_s"] >= 50.0):
            assert runp.poll() is None, runp.stderr.read()[-3000:]
            assert time.monotonic() < t_end, "the run never started stepping"
            time.sleep(0.2)
        r = subprocess.run(_cli("task", "--out", str(out), "--lat", str(TASK["lat_deg"]), "--lon", str(TASK["lon_deg"]),
                                "--priority", "1", "--by", TASK["by"], "--sat", "sat_12", "--wait-s", "600"),
                           capture_output=True, text=True, timeout=700, env=env, check=False)
        assert r.returncode == 0, r.stderr
        print(r.stdout.strip())
        answer = json.loads(next(p for p in (out / "operator").glob("*.reply")).read_text())
        assert answer["ok"] and answer["commands"] == ["op1"] and answer["issued_s"] >= 50.0  # while it ran
        _so, se = runp.communicate(timeout=1500)
        assert runp.returncode == 0, se[-3000:]
    finally:
        if runp.poll() is None:
            runp.kill()
            runp.wait()
    ops = json.loads((out / "report.json").read_text())["operations"]
    task, cmd = ops["tasks"]["op1"], ops["commands"]["by_command"]["op1"]
    assert task["sat"] == "sat_12" and task["observed_by"] == "sat_12" and task["in_time"], task
    assert task["observer_was_tasked"]
    assert cmd["issued_s"] == answer["issued_s"] and cmd["uplink_latency_s"] >= 0 and cmd["execution_latency_s"] >= 0
    print("live:", task, cmd)
    # the same request scripted at the same issue time, on the local engine
    local = tmp_path / "local"
    scripted = [{"sat": "sat_12", "kind": "task", "at_s": answer["issued_s"], **TASK}]
    ref = json.loads((run_engine("local", local, scripted) / "report.json").read_text())["operations"]
    assert ref["tasks"]["c1"] == task
    assert ref["commands"]["by_command"]["c1"] == cmd
