"""Faults in containers: a satellite's process killed inside its container, and a satellite's whole
container killed, each brought back by the container's restart policy (marker ``containers``).

The 12-satellite, 1-h compose run with ``--restart 2``: every service has the restart policy
``on-failure:2`` and checkpoints every step on the run's volume. During the run (at seeded times; the clock paced at 100x)
``kill -9`` hits sat_21's node process (the child of the container's init: the container exits and
podman restarts it) and then sat_32's container init itself (the whole container dies). Each
restarted satellite resumes from its checkpoint and the clock waits for it by name. Oracles (as
tests/faults/test_restart_ros.py on the host): the uninterrupted local-engine run's observations and
bundle deliveries, identical (nothing lost, nothing twice); the bag's bundle accounting equal to the
local run's and closed (created = delivered + dropped + held); each victim restarted exactly once.
"""

from __future__ import annotations

import json
import os
import random
import signal

import pytest
from conftest import accounting, traces

pytestmark = [pytest.mark.containers, pytest.mark.faults, pytest.mark.system, pytest.mark.timeout(1800)]


def test_killed_satellite_containers_restart_and_lose_nothing(lab, local_ref, tmp_path):
    from bringup.deploy.containers import ContainerRun

    rng = random.Random("containers-kill")
    # sim seconds of the kills; the clock is paced (100x: 36 s for the hour) so that each kill lands
    # mid-run whatever the lag of the progress lines it is triggered by
    plan = [("sat_21", rng.randrange(300, 1200), True), ("sat_32", rng.randrange(1800, 3000), False)]
    cr = ContainerRun(lab.compose("faults", "--restart", "2", "--real-time-factor", "100"))
    done: list[dict] = []

    def progress(p: dict) -> None:
        for victim, step, child in plan:
            if p["t_ns"] >= step * 1e9 and all(d["victim"] != victim for d in done):
                pid = cr.host_pid(victim, child=child)
                os.kill(pid, signal.SIGKILL)
                done.append({"victim": victim, "what": "node process" if child else "container init",
                             "step": p["steps"], "t_s": p["t_ns"] / 1e9})

    try:
        cr.up()
        res = cr.wait(timeout_s=1200, progress=progress)
        logs = {s: cr.logs(s)[-1500:] for s in ("clock", "sat_21", "sat_32")} if not res.ok else {}
        assert res.ok, (res.message, res.exit_codes, logs)
        out = cr.copy_out(tmp_path / "run")
    finally:
        cr.down()
    obs_ref, dl_ref = traces(local_ref)
    obs, dl = traces(out)
    acc_ref, acc = accounting(local_ref), accounting(out)
    lost = len(set(dl_ref) - set(dl))
    print(f"CONTAINERS faults {json.dumps(done)} restarts={res.restarts} wall_s={res.wall_s:.1f} "
          f"observations={len(obs)} deliveries={len(dl)} bundles_lost={lost} accounting={json.dumps(acc)}")
    assert [d["victim"] for d in done] == ["sat_21", "sat_32"], "the run ended before every fault"
    assert res.restarts == {"sat_21": 1, "sat_32": 1}
    assert obs == obs_ref
    assert dl == dl_ref and lost == 0
    assert acc == acc_ref
    assert acc["created"] == acc["delivered"] + acc["dropped"] + acc["held"], acc
