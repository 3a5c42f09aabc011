"""96 satellites, 1 h: the ROS engine with 12 satellites per process equals the local engine.

Both through the CLI (`constellation run --sats 96`: the paper's 3 planes of 32, named
sat_PPPP_SSSS). The ROS run hosts the satellites 12 to a process (8 satellite processes, one
executor and one node per satellite each; bringup/scenario/participants.py process_groups) beside
the router, the contact announcer and the clock. Oracle: the local engine (one process, in-memory
bus) is the reference: identical observations (sat, gp, t_ns), identical bundle deliveries (bundle
id, receiver, t_ns), and the same report (engine and runtime aside).

Both runs plan as the scenario says (joint planning: a satellite plans with those whose fields of
regard overlap its own, groups of 3.5 on average at this density, README "Benchmarks"), so the
engines are compared on the same work a user's 96-satellite run does.

Marked ``scale``: minutes on 2 cores, outside the default suite (README, "Tests").
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = [pytest.mark.system, pytest.mark.ros, pytest.mark.scale]

SATS, HOURS, PER_PROCESS = 96, 1.0, 12


def _run(out: Path, *extra: str) -> Path:
    cmd = [sys.executable, "-m", "bringup.cli", "run", "--sats", str(SATS), "--hours", str(HOURS),
           "--out", str(out), "--no-plots", "--no-progress", *extra]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=3600, check=False)
    assert r.returncode == 0, r.stderr[-3000:]
    return out


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    base = tmp_path_factory.mktemp("scale")
    return {"local": _run(base / "local", "--engine", "local"),
            "ros": _run(base / "ros", "--engine", "ros", "--sats-per-process", str(PER_PROCESS))}


def test_ros_with_12_satellites_per_process_equals_local(runs):
    from bringup.analysis.trace import deliveries_from_bag, observations_from_bag
    from msgs_json.names import sat_names

    obs_l, obs_r = observations_from_bag(runs["local"] / "bag"), observations_from_bag(runs["ros"] / "bag")
    assert len(obs_l) > 500 and obs_r == obs_l
    assert {o[0] for o in obs_l} <= set(sat_names(3, 32))
    del_l, del_r = deliveries_from_bag(runs["local"] / "bag"), deliveries_from_bag(runs["ros"] / "bag")
    assert len(del_l) > 1000 and del_r == del_l
    rep_l, rep_r = (json.loads((runs[e] / "report.json").read_text()) for e in ("local", "ros"))
    for rep in (rep_l, rep_r):
        rep.pop("runtime")
        rep.pop("engine")
    prov_l, prov_r = rep_l.pop("provenance"), rep_r.pop("provenance")  # (the command lines differ)
    assert prov_l["scenario_toml"] == prov_r["scenario_toml"]
    assert rep_r == rep_l and rep_l["n_sats"] == SATS
    logs = sorted(p.name for p in (runs["ros"] / "logs").glob("sats_*.log"))
    assert logs == [f"sats_{k}.log" for k in range(1, SATS // PER_PROCESS + 1)]
