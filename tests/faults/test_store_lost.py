"""A satellite's SQLite store deleted or corrupted between a crash and its restart (``--restart 1``).

The store holds the satellite's bundles and its per-step checkpoint (bringup/engine/ros/host.py). Tried
on main 8408404 + this branch: with the store deleted, the restarted process found no checkpoint,
said hello with ``resume_k = -1`` and the clock let it rejoin a run at step k > 0 with a fresh
state - bundles and knowledge gone, the run going on as if nothing happened. Now the clock refuses a
host that resumes before the last step it acked (bringup/engine/ros/clock_node.py ``_serve_rejoins``).

Oracles (a 2-satellite ROS run paced at 300x, the store of sat_11 unlinked or overwritten with junk,
then sat_11 killed with SIGKILL while the run steps):

* deleted: the run fails (exit 2) with one line naming sat_11 and its lost state (the clock refuses
  its rejoin, or - when a step reaches it first - the restarted host refuses a step after steps it
  never ran);
* corrupted: the restarted process cannot open its store, the run fails (exit 2) in one line naming
  the process;
* either way run_status.json says failed, no run.keys is left, every process of the run has ended
  and report.json is a partial report of the bag.
"""

from __future__ import annotations

import json
import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytestmark = [pytest.mark.faults, pytest.mark.ros, pytest.mark.slow, pytest.mark.timeout(600)]

REPO = Path(__file__).resolve().parents[2]


def _checkpointed_step(store: Path) -> int:
    """The step sat_11's store holds its checkpoint of (-1: none yet)."""
    try:
        with sqlite3.connect(f"file:{store}?mode=ro", uri=True, timeout=1.0) as db:
            row = db.execute("SELECT k FROM lockstep_checkpoint WHERE id = 0").fetchone()
    except sqlite3.Error:
        return -1
    return -1 if row is None else int(row[0])


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] not in ("Z", "X")
    except (FileNotFoundError, IndexError):
        return False


@pytest.mark.parametrize("damage", ["deleted", "corrupted"])
def test_store_lost_between_restarts_fails_the_run_by_name(tmp_path, damage):
    out = tmp_path / "run"
    env = dict(os.environ, PYTHONPATH=str(REPO), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    proc = subprocess.Popen([sys.executable, "-m", "bringup.cli", "run", "--engine", "ros", "--sats", "2", "--hours",
                             "1", "--restart", "1", "--real-time-factor", "300", "--no-plots", "--no-progress",
                             "--out", str(out)], cwd=REPO, env=env, stderr=subprocess.PIPE, text=True)
    store = out / "store" / "sat_11.sqlite"
    try:
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline:
            assert proc.poll() is None, proc.stderr.read()[-3000:]
            if (out / "logs" / "sat_11.pid").exists() and store.exists() and _checkpointed_step(store) >= 5:
                break  # (stepping: sat_11 has acked step 5)
            time.sleep(0.2)
        if damage == "deleted":
            for suffix in ("", "-wal", "-shm"):
                Path(f"{store}{suffix}").unlink(missing_ok=True)
        else:
            with open(store, "r+b") as fh:
                fh.write(b"not a database " * 300)
            Path(f"{store}-wal").unlink(missing_ok=True)
        pids = {p.stem: int(p.read_text()) for p in (out / "logs").glob("*.pid")}
        os.kill(pids["sat_11"], signal.SIGKILL)
        err = proc.communicate(timeout=400)[1]
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    lines = [ln for ln in err.splitlines() if "error" in ln]
    assert proc.returncode == 2, err[-3000:]
    assert len(lines) == 1 and "sat_11" in lines[0], err[-3000:]
    if damage == "deleted":  # (the clock refuses its hello, or the host itself the step it cannot have run)
        assert "saved state was lost" in lines[0] or "were never received" in lines[0], lines[0]
    st = json.loads((out / "run_status.json").read_text())
    assert st["status"] == "failed" and "sat_11" in st["error"]
    assert not (out / "run.keys").exists()
    time.sleep(1.0)
    pids = {p.stem: int(p.read_text()) for p in (out / "logs").glob("*.pid")}
    assert not [r for r, p in pids.items() if _alive(p)], pids
    assert json.loads((out / "report.json").read_text())["partial"] is True
