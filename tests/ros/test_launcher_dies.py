"""A run's processes end with their launcher, and Ctrl-C is exit code 130 everywhere.

Oracles:
* SIGKILL the launcher of a toy run while it steps: a few seconds later no process it started is
  alive (checked by pid from the run's logs/*.pid; a zombie counts as dead), the clock's log says
  its launcher ended, and the bag the clock closed on its way out opens (bringup/engine/ros/lifeline.py);
* Ctrl-C on `constellation run --engine ros` (SIGINT to its process group, as a terminal sends
  it): exit code 130 with "interrupted" on stderr, every child leaves, and the run's
  ROS_DOMAIN_ID was printed at the start and is the one in run_spec.json.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from bringup.engine.ros.launcher import REPO, child_env
from bringup.recording.bag import BagReader

pytestmark = [pytest.mark.ros, pytest.mark.timeout(300)]
S = 10**9


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as fh:
            state = fh.read().rsplit(")", 1)[1].split()[0]
    except (FileNotFoundError, ProcessLookupError, IndexError):
        return False
    return state not in ("Z", "X")


def _pids(run: Path) -> dict[str, int]:
    return {p.stem: int(p.read_text()) for p in (run / "logs").glob("*.pid")}


def test_children_die_with_a_sigkilled_launcher(tmp_path):
    run = tmp_path / "run"
    script = f"""
from bringup.engine.ros.launcher import launch
from bringup.engine.ros.run_spec import RunSpec
spec = RunSpec(factory="tests.ros.toy_participants:make", roles=["pingpong", "c0", "c1", "c2"],
               horizon_ns=3600 * 10**9, max_step_ns=10**10, real_time_factor=50.0,
               bag_dir={str(tmp_path / "bag")!r}, progress_period_s=0.2, extra={{"n_counters": 3}})
launch(spec, {str(run)!r}, progress=lambda p: print("steps", p.steps, flush=True))
"""
    proc = subprocess.Popen([sys.executable, "-c", script], cwd=str(REPO), env=child_env(0), stdout=subprocess.PIPE,
                            text=True)
    try:
        for line in proc.stdout:  # stepping (bounded by the test timeout)
            if line.startswith("steps") and int(line.split()[1]) >= 5:
                break
        pids = _pids(run)
        assert set(pids) == {"clock", "pingpong", "c0", "c1", "c2"} and all(map(_alive, pids.values())), pids
        proc.kill()
        proc.wait(timeout=10)
        deadline = time.monotonic() + 10.0
        while any(map(_alive, pids.values())) and time.monotonic() < deadline:
            time.sleep(0.1)
        left = {r: p for r, p in pids.items() if _alive(p)}
    finally:
        if proc.poll() is None:
            proc.kill()
        for p in _pids(run).values():
            if _alive(p):
                os.kill(p, signal.SIGKILL)
    assert not left, f"still alive 10 s after the launcher was killed: {left}"
    took = time.monotonic() - (deadline - 10.0)
    clock_log = (run / "logs" / "clock.log").read_text(errors="replace")
    assert "launcher" in clock_log and "interrupted" in clock_log, clock_log[-2000:]
    with BagReader(tmp_path / "bag") as bag:  # closed by the clock on its way out
        assert {t.topic: t.count for t in bag.topics()}["/clock"] >= 5
    print(f"every process gone {took:.1f} s after SIGKILL of the launcher")


def test_ctrl_c_exits_130_and_the_domain_is_printed(tmp_path):
    out = tmp_path / "run"
    cmd = [sys.executable, "-m", "bringup.cli", "run", "--engine", "ros", "--sats", "2", "--hours", "6",
           "--real-time-factor", "100", "--out", str(out), "--no-plots", "--no-progress"]
    # a new session: SIGINT to its process group is what Ctrl-C in a terminal does to a foreground job
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    # (SIGINT default in the child: a pytest started in the background passes it on ignored; this
    # test starts no thread, so preexec_fn is safe here)
    proc = subprocess.Popen(cmd, cwd=str(REPO), env=env, stderr=subprocess.PIPE, text=True, start_new_session=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))  # noqa: PLW1509
    pids: dict[str, int] = {}
    roles: list[str] = []
    try:
        deadline = time.monotonic() + 240
        while time.monotonic() < deadline and proc.poll() is None:
            if not roles and (out / "run_spec.json").exists():
                roles = json.loads((out / "run_spec.json").read_text())["roles"]
            pids = _pids(out)
            if roles and len(pids) == len(roles) + 1 and (out / "bag").exists():
                break
            time.sleep(0.2)
        time.sleep(3.0)  # stepping
        assert proc.poll() is None, proc.stderr.read()
        os.killpg(proc.pid, signal.SIGINT)
        err = proc.communicate(timeout=120)[1]
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 130, err[-3000:]
    assert "constellation run: interrupted" in err, err[-3000:]
    m = re.search(r"ROS_DOMAIN_ID=(\d+)", err)
    assert m and int(m.group(1)) == json.loads((out / "run_spec.json").read_text())["domain_id"]
    time.sleep(1.0)
    assert not [r for r, p in pids.items() if _alive(p)], pids
    assert "clock: interrupted" in (out / "logs" / "clock.log").read_text(errors="replace")
    for role in roles:
        log = (out / "logs" / f"{role}.log").read_text(errors="replace")
        assert "interrupted" in log, (role, log[-1500:])
