"""The process that records a run is SIGKILLed mid-run: the bag it leaves reads back, up to its last
closed chunk, and the run says it failed and leaves a report marked partial.

Both engines: the local engine's recorder process (bringup/recording/recorder_process.py, a child
of the ``constellation run`` process) and the ROS engine's clock process (it records the run;
bringup/engine/ros/clock_node.py), killed once the bag holds a few closed chunks.

Oracles: the run exits 2 with one error line; ``run_status.json`` says ``failed``; ``report.json``
has ``partial: true`` and a horizon reached short of the horizon; the bag opens (BagReader,
``bag-info``, ``report``) and is not complete; and what it holds is a prefix of the clean run's
recording: its observations are exactly the clean (local-engine, same seed) run's observations
up to the last one recovered (the engines record the same observations:
tests/system/test_engines_equal.py).
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
from bringup.recording.bag import BagReader
from bringup.recording.mcap_file import scan_mcap

REPO = Path(__file__).resolve().parents[2]
ARGS = ["--sats", "6", "--hours", "2", "--no-plots", "--no-progress"]


def _observations(bag: Path) -> list[tuple]:
    with BagReader(bag) as r:
        return sorted((e.t_ns, e.topic, e.data) for e in r.envelopes([t.topic for t in r.topics()
                                                                       if t.topic.endswith("/observations")]))


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    out = tmp_path_factory.mktemp("clean") / "r"
    assert main(["run", "--engine", "local", *ARGS, "--out", str(out)]) == 0
    return _observations(out / "bag")


def _children(pid: int) -> list[int]:
    try:
        text = Path(f"/proc/{pid}/task/{pid}/children").read_text()
    except OSError:
        return []
    return [int(x) for x in text.split()]


def _wait_for_chunks(mcap: Path, proc: subprocess.Popen, n: int, timeout_s: float = 300.0) -> None:
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout_s:
        assert proc.poll() is None, "the run ended before the kill"
        if mcap.exists():
            try:
                if len(scan_mcap(mcap).chunks) >= n:
                    return
            except ValueError:
                pass
        time.sleep(0.01)
    raise AssertionError(f"{mcap}: fewer than {n} chunks after {timeout_s} s")


def _check_partial_run(out: Path, proc: subprocess.Popen, clean: list, what: str) -> None:
    _, err = proc.communicate(timeout=300)
    assert proc.returncode == 2, err
    assert "Traceback" not in err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert lines[-1].startswith("constellation run: error: ") and what in lines[-1], lines[-1]
    status = json.loads((out / "run_status.json").read_text())
    assert status["status"] == "failed" and status["partial"] is True
    rep = json.loads((out / "report.json").read_text())
    assert rep["partial"] is True and 0 < rep["horizon_reached_s"] < rep["horizon_s"] == 7200.0
    with BagReader(out / "bag") as r:
        assert not r.complete and r.count > 0 and "was not closed by its writer" in r.recovery
    assert main(["bag-info", str(out / "bag")]) == 0
    assert main(["report", str(out / "bag")]) == 0
    got = _observations(out / "bag")
    assert 0 < len(got) < len(clean) and got == clean[:len(got)]  # a prefix of the clean recording
    assert rep["observations"]["count"] == len(got)


@pytest.mark.faults
def test_local_recorder_killed(tmp_path, clean):
    out = tmp_path / "r"
    proc = subprocess.Popen([sys.executable, "-m", "bringup.cli", "run", "--engine", "local", *ARGS,
                             "--out", str(out)], cwd=REPO, stderr=subprocess.PIPE, text=True)
    try:
        _wait_for_chunks(out / "bag" / "bag.mcap", proc, 15)
        (recorder,) = _children(proc.pid)  # the one child process: the recorder
        os.kill(recorder, signal.SIGKILL)
        _check_partial_run(out, proc, clean, "killed by SIGKILL")
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


@pytest.mark.faults
@pytest.mark.ros
def test_ros_clock_killed(tmp_path, clean):
    out = tmp_path / "r"
    # paced (400 sim s per wall s: 18 s for the 2 h) so the kill comes mid-run on any machine; 15
    # chunks of 2 min: 30 min of sim time, past the first observation (21 min)
    proc = subprocess.Popen([sys.executable, "-m", "bringup.cli", "run", "--engine", "ros", *ARGS,
                             "--real-time-factor", "400", "--out", str(out)],
                            cwd=REPO, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"})
    try:
        _wait_for_chunks(out / "bag" / "bag.mcap", proc, 15)
        clock = int((out / "logs" / "clock.pid").read_text())
        os.kill(clock, signal.SIGKILL)
        _check_partial_run(out, proc, clean, "clock")
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(timeout=60)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
