"""Every way a run is stopped leaves a true state (bringup/stop_signals.py).

Against main 8408404, SIGHUP to a ROS run's launcher (a closed terminal) ended it with exit 129,
``run_status.json`` "running" forever and ``run.keys`` left on disk; SIGTERM to a local run
(``timeout``, systemd, ``docker stop``) left "running" and no report although the bag was whole.

Oracles, for SIGTERM, SIGHUP and SIGQUIT to a local run and SIGHUP (the launcher alone) and SIGQUIT
(its whole process group, as a terminal sends Ctrl-\\) to a ROS run:

* the exit code is 128 + the signal's number, stderr says "interrupted by SIG...";
* ``run_status.json`` says ``interrupted`` with the signal's name and ``partial``: true, and
  ``report.json`` is a partial report whose reached time is the bag's;
* no ``run.keys`` is left, and no process of the run is alive (ROS: by pid from logs/*.pid);
* the same ``--out`` takes the next run at once (the local runs share one folder in turn).
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

from bringup.recording.bag import BagReader

pytestmark = [pytest.mark.faults]

REPO = Path(__file__).resolve().parents[2]


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as fh:
            state = fh.read().rsplit(")", 1)[1].split()[0]
    except (FileNotFoundError, ProcessLookupError, IndexError):
        return False
    return state not in ("Z", "X")


def _running(out: Path, proc: subprocess.Popen) -> bool:
    """This run holds the folder (the earlier run's outputs are gone)."""
    try:
        st = json.loads((out / "run_status.json").read_text())
    except (OSError, ValueError):
        return False
    return st.get("pid") == proc.pid and st.get("status") == "running"


def _start(cmd: list[str]) -> subprocess.Popen:
    env = dict(os.environ, PYTHONPATH=str(REPO), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    return subprocess.Popen([sys.executable, "-m", "bringup.cli", *cmd], cwd=str(REPO), env=env,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)


def _check_stopped(out: Path, proc: subprocess.Popen, sig: signal.Signals, err: str) -> dict:
    assert proc.returncode == 128 + sig, err[-3000:]
    assert f"interrupted by {sig.name}" in err, err[-3000:]
    st = json.loads((out / "run_status.json").read_text())
    assert st["status"] == "interrupted" and st["signal"] == sig.name and st["partial"] is True, st
    assert not (out / "run.keys").exists()
    rep = json.loads((out / "report.json").read_text())
    assert rep["partial"] is True
    with BagReader(out / "bag") as bag:
        assert rep["horizon_reached_s"] == pytest.approx(bag.end_ns / 1e9)
    assert rep["horizon_reached_s"] < rep["horizon_s"]
    return rep


def test_local_run_stopped_by_each_signal(tmp_path):
    out = tmp_path / "run"
    cmd = ["run", "--engine", "local", "--sats", "12", "--hours", "24", "--no-plots", "--no-progress",
           "--out", str(out)]
    for sig in (signal.SIGTERM, signal.SIGHUP, signal.SIGQUIT):
        proc = _start(cmd)
        try:
            deadline = time.monotonic() + 120
            while not (_running(out, proc) and (out / "bag").exists()) and time.monotonic() < deadline:
                assert proc.poll() is None, proc.stderr.read()  # (the bag is made as the engine starts)
                time.sleep(0.05)
            time.sleep(1.0)  # stepping
            assert proc.poll() is None, proc.stderr.read()
            proc.send_signal(sig)  # the main process alone (timeout, docker stop)
            err = proc.communicate(timeout=600)[1]  # (a loaded machine: minutes)
        finally:
            if proc.poll() is None:
                proc.kill()
        _check_stopped(out, proc, sig, err)


@pytest.mark.ros
@pytest.mark.timeout(1200)
@pytest.mark.parametrize("sig, group", [(signal.SIGHUP, False),
                                        pytest.param(signal.SIGQUIT, True, marks=pytest.mark.slow)])
def test_ros_run_stopped_by_a_signal(tmp_path, sig, group):
    out = tmp_path / "run"
    proc = _start(["run", "--engine", "ros", "--sats", "2", "--hours", "6", "--real-time-factor", "200",
                   "--out", str(out), "--no-plots", "--no-progress"])
    pids: dict[str, int] = {}
    try:
        roles: list[str] = []
        deadline = time.monotonic() + 240
        while time.monotonic() < deadline and proc.poll() is None:
            if not roles and (out / "run_spec.json").exists():
                roles = json.loads((out / "run_spec.json").read_text())["roles"]
            pids = {p.stem: int(p.read_text()) for p in (out / "logs").glob("*.pid")}
            if roles and len(pids) == len(roles) + 1 and (out / "bag").exists() and _running(out, proc):
                break
            time.sleep(0.2)
        time.sleep(3.0)  # stepping
        assert proc.poll() is None, proc.stderr.read()
        assert (out / "run.keys").exists()
        if group:  # a terminal's signal reaches every process of the foreground job
            os.killpg(proc.pid, sig)
        else:
            proc.send_signal(sig)
        err = proc.communicate(timeout=600)[1]
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    _check_stopped(out, proc, sig, err)
    time.sleep(1.0)
    assert not [r for r, p in pids.items() if _alive(p)], pids
    assert "clock: interrupted" in (out / "logs" / "clock.log").read_text(errors="replace")
