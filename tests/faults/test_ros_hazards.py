"""Two ROS hazards tried: a host stopped (SIGSTOP) past every deadline, and two runs on one --domain-id.

* SIGSTOP of a satellite's process while the run steps: it neither acks nor dies. The clock's ack
  deadline names it, the run fails (exit 2) in one line naming sat_11, the stopped process is killed
  (a stopped process does not act on SIGTERM: the launcher's SIGKILL after 5 s ends it), no process
  is left, no run.keys, run_status.json failed, report.json partial.
* Two runs started at once with the same ``--domain-id`` (the id leased by the test, so no other run
  on this machine uses it). Tried: each run's MACs kept the other's messages out, but one run failed
  with "recorder is missing envelopes" - the other run's subscriptions on the same topic names
  counted as matched, so a host published before its own recorder had matched. Now the clock
  refuses to start beside another run's clock (bringup/engine/ros/clock_node.py ``_alone_on_domain``):
  a refused run exits 2 in one line naming the domain; a run that got going first (if any) completes
  and its observations and deliveries equal the local engine's; never both complete.

Slow (a minute or two each on a loaded machine).
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

pytestmark = [pytest.mark.faults, pytest.mark.ros, pytest.mark.slow, pytest.mark.timeout(900)]

REPO = Path(__file__).resolve().parents[2]


def _env() -> dict[str, str]:
    return dict(os.environ, PYTHONPATH=str(REPO), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")


def _run(engine: str, out: Path, *extra: str) -> list[str]:
    return [sys.executable, "-m", "bringup.cli", "run", "--engine", engine, "--sats", "4", "--planes", "2",
            "--hours", "1", "--no-plots", "--no-progress", "--out", str(out), *extra]


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] not in ("Z", "X")
    except (FileNotFoundError, IndexError):
        return False


def test_stopped_host_fails_the_run_by_name(tmp_path):
    out = tmp_path / "run"
    proc = subprocess.Popen(_run("ros", out, "--real-time-factor", "200"), cwd=REPO, env=_env(),
                            stderr=subprocess.PIPE, text=True)
    pid = None
    try:
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline:
            assert proc.poll() is None, proc.stderr.read()[-3000:]
            mcap = out / "bag" / "bag.mcap"
            if (out / "logs" / "sat_11.pid").exists() and mcap.exists() and mcap.stat().st_size > 50_000:
                break  # (stepping: the clock's bag has closed chunks)
            time.sleep(0.2)
        pids = {p.stem: int(p.read_text()) for p in (out / "logs").glob("*.pid")}
        pid = pids["sat_11"]
        os.kill(pid, signal.SIGSTOP)
        err = proc.communicate(timeout=300)[1]
    finally:
        if pid is not None and _alive(pid):
            os.kill(pid, signal.SIGKILL)
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    lines = [ln for ln in err.splitlines() if "error" in ln]
    assert proc.returncode == 2 and len(lines) == 1, err[-3000:]
    assert "sat_11" in lines[0] and "no ack" in lines[0], lines[0]
    st = json.loads((out / "run_status.json").read_text())
    assert st["status"] == "failed" and "sat_11" in st["error"]
    assert not (out / "run.keys").exists()
    time.sleep(1.0)
    assert not [r for r, p in pids.items() if _alive(p)], pids
    assert json.loads((out / "report.json").read_text())["partial"] is True


def test_two_runs_on_one_domain_id_keep_apart(tmp_path):
    from bringup.analysis.trace import deliveries_from_bag, observations_from_bag
    from bringup.engine.ros.launcher import lease_domain_id

    local = tmp_path / "local"
    r = subprocess.run(_run("local", local), cwd=REPO, env=_env(), capture_output=True, text=True, timeout=600, check=False)
    assert r.returncode == 0, r.stderr[-3000:]
    with lease_domain_id() as lease:
        outs = [tmp_path / "a", tmp_path / "b"]
        procs = [subprocess.Popen(_run("ros", o, "--domain-id", str(lease.domain_id), "--real-time-factor", "100"),
                                  cwd=REPO, env=_env(), stderr=subprocess.PIPE, text=True) for o in outs]
        try:
            errs = [p.communicate(timeout=800)[1] for p in procs]
        finally:
            for p in procs:
                if p.poll() is None:
                    p.kill()
                    p.wait()
    ref = (observations_from_bag(local / "bag"), deliveries_from_bag(local / "bag"))
    codes = [p.returncode for p in procs]
    print(f"DOMAIN {lease.domain_id}: exit codes {codes}; " + " | ".join(e.strip().splitlines()[-1] for e in errs))
    assert codes != [0, 0], "two runs shared a domain and neither was refused"
    for p, o, err in zip(procs, outs, errs, strict=True):
        if p.returncode == 0:  # (one may have started its steps before the other's clock was up)
            assert (observations_from_bag(o / "bag"), deliveries_from_bag(o / "bag")) == ref
            continue
        lines = [ln for ln in err.splitlines() if "error" in ln]
        assert p.returncode == 2 and len(lines) == 1, err[-3000:]
        assert f"another run is on ROS_DOMAIN_ID {lease.domain_id}" in lines[0], lines[0]
