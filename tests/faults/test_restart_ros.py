"""Kill -9 and restart under the ROS engine (issue 7 part B: a satellite, the router, the clock): the run completes, nothing is lost.

Reduced paper scenario (12 satellites, 1 h, distributed; the same as the engine-equivalence test).
One process is killed with SIGKILL at a random (seeded) lockstep step while the run goes on; the
launcher restarts it (``max_restarts``), it resumes from its checkpoint (satellites: their SQLite
bundle store plus what the scheduler knows, one transaction per step; sat_node/persist.py), the
clock waits for it by name and re-sends what it missed. The clock itself is killed too: it restarts
from its per-step checkpoint and journal (bringup/engine/ros/clock_node.py), the hosts wait, answer again
the step they had run (never running it twice) and the bag is exported whole. Oracles:

* the uninterrupted local-engine run of the same scenario and seed: observations (sat, gp, t_ns)
  and bundle deliveries (bundle id, receiver, t_ns) must be identical - no observation executed
  twice or lost, no bundle lost or delivered twice;
* bundle accounting from the bag alone: created = delivered + dropped (by reason) + held at end.

Figures (faults injected, runs completed, bundles lost) are printed in one ``FAULTS`` line per run.
"""

from __future__ import annotations

import json
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytestmark = [pytest.mark.faults, pytest.mark.ros, pytest.mark.system]

REPO = Path(__file__).resolve().parents[2]
SATS, HOURS = 12, 1.0


def _observations(bag: Path):
    from bringup.analysis.trace import observations_from_bag

    return observations_from_bag(bag)


def _deliveries(bag: Path):
    from bringup.analysis.trace import deliveries_from_bag

    return deliveries_from_bag(bag)


def _accounting(bag: Path) -> dict:
    from bringup.analysis.report import report_from_bag

    d = report_from_bag(bag)["dtn"]
    dropped = sum(v for v in d.get("dropped", {}).values() if isinstance(v, int))
    return {"created": d["bundles_created"], "delivered": d["bundles_delivered"], "dropped": dropped,
            "held": d.get("held_at_end", 0)}


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    out = tmp_path_factory.mktemp("restart") / "local"
    cmd = [sys.executable, "-m", "bringup.cli", "run", "--engine", "local", "--sats", str(SATS), "--hours",
           str(HOURS), "--out", str(out), "--no-plots", "--no-progress"]
    r = subprocess.run(cmd, check=False, capture_output=True, text=True, timeout=600, cwd=REPO)
    assert r.returncode == 0, r.stderr[-3000:]
    return out


def _ros_run_with_kill(reference: Path, out: Path, victim: str, kill_step: int):
    from bringup.engine.ros.launcher import launch
    from bringup.engine.ros.factory import FACTORY
    from bringup.scenario.participants import roles_for
    from bringup.analysis.report import RunMeta
    from bringup.engine.ros.run_spec import RunSpec
    from bringup.scenario.world import World

    world_path = next((reference / "cache").glob("world-*.pkl"))
    world = World.load(world_path)
    sc = world.scenario
    (out / "store").mkdir(parents=True)
    meta = RunMeta(scenario=sc.name, mode="distributed", engine="ros", seed=sc.scenario.seed,
                   horizon_s=sc.scenario.horizon_s, n_sats=len(world.sat_names), n_gp=world.n_gp,
                   revisit_zero_s=sc.value.revisit_zero_s)
    spec = RunSpec(factory=FACTORY, roles=roles_for(world, "distributed"),
                   scenario=str(Path(sc.source_path).resolve()),
                   overrides={"sats": SATS, "hours": HOURS}, mode="distributed", bag_dir=str(out / "bag"),
                   ack_timeout_s=5.0, restart_wait_s=120.0, max_restarts=2, state_dir=str(out / "state"),
                   extra={"world": str(world_path.resolve()), "world_key": world.key,
                          "store_dir": str((out / "store").resolve()), "meta": meta.__dict__})
    killed: dict = {}

    def progress(p) -> None:
        if not killed and p.steps >= kill_step:
            pid = int((out / "logs" / f"{victim}.pid").read_text())
            os.kill(pid, signal.SIGKILL)
            killed.update(pid=pid, step=p.steps, t_ns=p.t_ns)

    t0 = time.monotonic()
    res = launch(spec, out, progress=progress)
    return res, killed, time.monotonic() - t0


@pytest.mark.parametrize("victim", ["sat_21", "router", "clock"])
def test_kill9_restart_run_completes_and_equals_uninterrupted(reference, tmp_path, victim):
    kill_step = random.Random(f"kill-{victim}").randrange(20, 200)
    res, killed, wall = _ros_run_with_kill(reference, tmp_path / "ros", victim, kill_step)
    logs = {p.name: p.read_text(errors="replace")[-1500:] for p in (tmp_path / "ros" / "logs").glob("*.log")}
    assert killed, f"the run ended before step {kill_step}"
    assert res.ok, (res.message, logs)
    assert res.restarts == {victim: 1}, logs
    bag_ref, bag = reference / "bag", tmp_path / "ros" / "bag"
    obs_ref, obs = _observations(bag_ref), _observations(bag)
    dl_ref, dl = _deliveries(bag_ref), _deliveries(bag)
    acc_ref, acc = _accounting(bag_ref), _accounting(bag)
    lost = len(set(dl_ref) - set(dl))
    print(f"FAULTS victim={victim} kill_step={killed['step']} t={killed['t_ns'] / 1e9:.0f}s faults_injected=1 "
          f"runs_completed={int(res.ok)} restarts={res.restarts} observations={len(obs)} "
          f"deliveries={len(dl)} bundles_lost={lost} accounting={json.dumps(acc)} wall_s={wall:.0f}")
    assert len(dl_ref) > 10
    assert obs == obs_ref
    assert dl == dl_ref
    assert acc == acc_ref
    assert acc["created"] == acc["delivered"] + acc["dropped"] + acc["held"], acc
