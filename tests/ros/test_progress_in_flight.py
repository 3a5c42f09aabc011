"""Progress of a ROS-engine run shows the bundles in flight in the DTN router (issue 5).

Reduced paper scenario (9 satellites, 45 min, distributed) with 30 s of extra ISL delay, so that
bundle copies stay in the router across steps (without it every copy arrives before the next
10 s step and the figure is 0 throughout). Oracles:

* the local engine (bringup/engine/local.py) is the reference: its progress records, one after
  every step, carry the router's ``StepResult.in_flight`` (what ``constellation run --engine local``
  displays), which must equal ``len(router.pending)``. The ROS run's progress records (clock ->
  launcher, one per step here) must carry the same figure at every sim time, be > 0 at some step
  and 0 at the end;
* ``constellation run --engine ros`` through the CLI with stderr not a terminal, with and without
  ``--no-progress``: both complete; only the former prints the display (its last frame, on stdout:
  "0 bundles in flight").
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from tests.keys import TEST_BPSEC_KEY

pytestmark = [pytest.mark.ros, pytest.mark.system, pytest.mark.timeout(600)]

REPO = Path(__file__).resolve().parents[2]
SATS, HOURS, DELAY_S = 9, 0.75, 30.0
S = 10**9


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    from bringup.scenario.config import load_scenario
    from bringup.scenario.world import World

    base = tmp_path_factory.mktemp("inflight")
    sc = load_scenario("paper").with_overrides(sats=SATS, hours=HOURS)
    w = World.cached(sc, base / "cache")
    path = base / "cache" / f"world-{w.key}.pkl"
    if not path.exists():
        w.save(path)
    return w, path, base


def _local_in_flight(world, store: Path) -> dict[int, int]:
    from bringup.engine.local import run_local
    from bringup.scenario.participants import all_participants
    from dtn_router.router import ROUTER_NAME

    sc = world.scenario
    store.mkdir()
    parts = all_participants(world, "distributed", store_dir=store, router_kw={"extra_delay_s": DELAY_S},
                             bpsec_key=TEST_BPSEC_KEY)
    router = next(p for p in parts if p.name == ROUTER_NAME)
    seen: dict[int, int] = {}

    def progress(p) -> None:
        assert p.in_flight == len(router.pending)
        seen[p.t_ns] = p.in_flight

    run_local(parts, horizon_ns=sc.horizon_ns, max_step_ns=round(sc.scenario.lockstep_max_step_s * S),
              progress=progress, progress_interval_s=0.0)
    return seen


def test_ros_progress_in_flight_equals_local_engine_step_by_step(world, tmp_path):
    from bringup.engine.ros.factory import FACTORY
    from bringup.engine.ros.launcher import launch
    from bringup.engine.ros.run_spec import RunSpec
    from bringup.scenario.participants import roles_for

    w, world_path, _ = world
    sc = w.scenario
    ref = _local_in_flight(w, tmp_path / "store_local")
    assert max(ref.values()) > 0, "the scenario must keep bundles in flight across steps"
    (tmp_path / "store").mkdir()
    spec = RunSpec(factory=FACTORY, roles=roles_for(w, "distributed"), scenario=str(Path(sc.source_path).resolve()),
                   overrides={"sats": SATS, "hours": HOURS}, mode="distributed", progress_period_s=0.0,
                   extra={"world": str(world_path.resolve()), "world_key": w.key,
                          "store_dir": str((tmp_path / "store").resolve()), "router": {"extra_delay_s": DELAY_S}})
    recs = []
    res = launch(spec, tmp_path / "ros", progress=recs.append)
    assert res.ok, res.message
    assert recs and all(p.in_flight is not None for p in recs)
    got: dict[int, int] = {}
    for p in recs:
        got[p.t_ns] = p.in_flight
    assert got == ref  # every step, same figure
    assert max(p.in_flight for p in recs) > 0
    assert recs[-1] == res.last and res.last.t_ns == sc.horizon_ns and res.last.in_flight == 0


@pytest.mark.parametrize("flag", ["", "--no-progress"])
def test_cli_ros_run_with_and_without_progress_off_a_terminal(tmp_path, flag):
    cmd = [sys.executable, "-m", "bringup.cli", "run", "--engine", "ros", "--sats", str(SATS), "--hours", str(HOURS),
           "--isl-delay-s", str(DELAY_S), "--out", str(tmp_path / "run"), "--no-plots", *([flag] if flag else [])]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=500, check=False, cwd=REPO)  # stderr: a pipe
    assert r.returncode == 0, r.stderr[-3000:]
    assert "run: done" in r.stderr and (tmp_path / "run" / "report.json").is_file()
    # off a terminal the progress is a line on stderr every 10 s and every tenth of the horizon (the
    # last one at the horizon: 0 in flight), and none with --no-progress
    lines = [ln for ln in r.stderr.splitlines() if ln.startswith("run: sim ")]
    assert bool(lines) == (flag == ""), r.stderr[-3000:]
    if lines:
        assert "(100.0 %)" in lines[-1] and "0 bundles in flight" in lines[-1], lines[-3:]
