"""The reference scenario's first ROS run on a fresh machine: 24 satellites from an empty numba cache.

On a fresh clone numba's cache is empty; 24 satellite processes that each compile the scheduler's
and the router's kernels at once on 2 cores missed the first step's ack deadline. The launcher now
compiles them once before the processes start (bringup/scenario/participants.py prepare,
sat_node/kernels.py) and each process loads them before it reports ready; the clock waits for
ready without the per-step deadline (bringup/engine/ros/clock_node.py).

Oracle: ``constellation run`` (the README's command, ROS engine, the paper's 24 satellites, a short
horizon, all on one CPU) with NUMBA_CACHE_DIR pointing at a new empty folder exits 0 with a report of 24
satellites; the kernels were compiled into that folder by the launcher's prepare step, once
(one cache entry per kernel), and every satellite process logged that it was ready.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = [pytest.mark.system, pytest.mark.ros]


def test_paper_ros_run_starts_from_an_empty_numba_cache(tmp_path):
    cache = tmp_path / "numba-cache"
    cache.mkdir()
    out = tmp_path / "run"
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache))
    env.pop("NUMBA_DISABLE_JIT", None)
    cmd = [sys.executable, "-m", "bringup.cli", "run", "--scenario", "paper", "--engine", "ros", "--hours", "0.1",
           "--out", str(out), "--no-plots", "--no-progress"]
    # on one CPU (of the 2 CI has): before the prepare step the run failed there at step 0 every
    # time; on 2 CPUs it failed or passed depending on the machine's load
    cpu = min(os.sched_getaffinity(0))
    r = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=900, check=False,
                       preexec_fn=lambda: os.sched_setaffinity(0, {cpu}))
    logs = {p.name: p.read_text(errors="replace")[-400:] for p in (out / "logs").glob("*.log")} \
        if (out / "logs").exists() else {}
    assert r.returncode == 0, (r.stderr[-3000:], logs.get("clock.log"))
    rep = json.loads((out / "report.json").read_text())
    assert rep["n_sats"] == 24 and rep["engine"] == "ros"
    assert rep["runtime"]["steps"] > 30
    # compiled into the empty cache by the launcher's prepare step, one entry per kernel
    for kernel in ("dp_kernels.dp_forward", "cgr._dijkstra"):
        entries = sorted(cache.rglob(f"{kernel}-*.nbc"))
        assert len(entries) == 1, (kernel, entries)
    assert "node prepare: ready" in (out / "logs" / "prepare.log").read_text()
    sats = [f"sat_{p}{s}" for p in (1, 2, 3) for s in range(1, 9)]
    for sat in sats:
        assert f"node {sat}: ready" in (out / "logs" / f"{sat}.log").read_text(), sat
