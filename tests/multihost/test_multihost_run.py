"""A real reduced scenario with every process on its own emulated host (issue 7 part B).

12 satellites + the DTN router + the clock/recorder, 1 h, distributed: 14 network namespaces on one
bridge (tests/multihost/netns.py), DDS over the lab's network with static peers (unicast
discovery, ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` + ``ROS_STATIC_PEERS``). The launcher runs
each child through its ``wrap`` hook (``ip netns exec NS ...`` and that host's environment).

Oracle: the single-host local-engine run of the same scenario and seed: observations
(sat, gp, t_ns) and bundle deliveries (bundle id, receiver, t_ns) identical; every host really sent
traffic on its interface; the namespaces are gone afterwards.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from netns import _NAME_ROOT, list_netns, netns_lab, ros_env

pytestmark = [pytest.mark.multihost, pytest.mark.system]

REPO = Path(__file__).resolve().parents[2]
SATS, HOURS = 12, 1.0
sys.path.insert(0, str(REPO / "tests" / "faults"))


def _local(out: Path) -> Path:
    cmd = [sys.executable, "-m", "bringup.cli", "run", "--engine", "local", "--sats", str(SATS), "--hours",
           str(HOURS), "--out", str(out), "--no-plots", "--no-progress"]
    r = subprocess.run(cmd, check=False, capture_output=True, text=True, timeout=600, cwd=REPO)
    assert r.returncode == 0, r.stderr[-3000:]
    return out


def test_scenario_across_namespace_hosts_equals_single_host(tmp_path):
    from test_restart_ros import _deliveries, _observations

    from bringup.engine.ros.launcher import CLOCK_ROLE, launch
    from bringup.engine.ros.factory import FACTORY
    from bringup.scenario.participants import roles_for
    from bringup.analysis.report import RunMeta
    from bringup.engine.ros.run_spec import RunSpec
    from bringup.scenario.world import World

    def own() -> list[str]:  # this process's namespaces: other runs on the machine (podman) make theirs
        return [n for n in list_netns() if n.startswith(f"{_NAME_ROOT}{os.getpid()}x")]

    before = own()
    ref = _local(tmp_path / "local")
    world_path = next((ref / "cache").glob("world-*.pkl"))
    world = World.load(world_path)
    sc = world.scenario
    out = tmp_path / "multi"
    (out / "store").mkdir(parents=True)
    meta = RunMeta(scenario=sc.name, mode="distributed", engine="ros", seed=sc.scenario.seed,
                   horizon_s=sc.scenario.horizon_s, n_sats=len(world.sat_names), n_gp=world.n_gp,
                   revisit_zero_s=sc.value.revisit_zero_s)
    roles = roles_for(world, "distributed")
    spec = RunSpec(factory=FACTORY, roles=roles, scenario=str(Path(sc.source_path).resolve()),
                   overrides={"sats": SATS, "hours": HOURS}, mode="distributed", bag_dir=str(out / "bag"),
                   ack_timeout_s=30.0, startup_timeout_s=90.0,
                   extra={"world": str(world_path.resolve()), "world_key": world.key,
                          "store_dir": str((out / "store").resolve()), "meta": meta.__dict__})
    all_roles = [CLOCK_ROLE, *roles]
    with netns_lab(len(all_roles)) as lab:
        host_of = dict(zip(all_roles, lab.hosts, strict=True))

        def wrap(role, argv, env):
            h = host_of[role]
            e = ros_env(lab, h, int(env["ROS_DOMAIN_ID"]), discovery="static", base=env)
            return h.wrap(argv), e

        res = launch(spec, out, wrap=wrap)
        sent = {r: lab.link_bytes(h)[1] for r, h in host_of.items()}
    logs = {p.name: p.read_text(errors="replace")[-800:] for p in (out / "logs").glob("*.log")}
    assert res.ok, (res.message, logs)
    assert all(n > 0 for n in sent.values()), sent
    assert own() == before
    obs_ref, obs = _observations(ref / "bag"), _observations(out / "bag")
    dl_ref, dl = _deliveries(ref / "bag"), _deliveries(out / "bag")
    print(f"MULTIHOST hosts={len(all_roles)} observations={len(obs)} deliveries={len(dl)} "
          f"bytes_sent_min={min(sent.values())}")
    assert len(obs_ref) > 50 and len(dl_ref) > 10
    assert obs == obs_ref
    assert dl == dl_ref
