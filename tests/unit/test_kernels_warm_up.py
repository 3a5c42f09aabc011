"""sat_node/kernels.py warm_up compiles exactly what a run uses, and a second process loads it.

Oracles (each in a fresh process with its own empty NUMBA_CACHE_DIR, as on a fresh clone):
* after ``warm_up()`` a 20-minute paper run on the local engine (24 satellites replanning and routing
  bundles: it calls the three top-level kernels, counted) adds no signature to any kernel: nothing a
  satellite does after it reports ready compiles;
* a second process with the same cache directory finds every top-level kernel there (numba's cache
  hits for each signature, no misses), in a fraction of the cold compile time.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]

_RUN = r"""
import json
from sat_node import kernels
from sat_node.scheduler import dp_kernels
from sat_node.dtn import cgr

took = kernels.warm_up()
disp = kernels.dispatchers()
sigs = lambda: {k: sorted(str(s) for s in d.signatures) for k, d in disp.items()}
before = sigs()
calls = {"dp_forward": 0, "_dijkstra": 0, "for_codes": 0}

def counted(mod, name):
    f = getattr(mod, name)
    def wrapper(*a):
        calls[name] += 1
        return f(*a)
    setattr(mod, name, wrapper)

counted(dp_kernels, "dp_forward")  # sat_node/scheduler/dp.py calls dp_kernels.dp_forward
counted(cgr, "_dijkstra")  # ContactGraph._run looks the global up at each call
from orbit_clock import access_kernels
counted(access_kernels, "for_codes")  # orbit_clock/access.py for_mask calls access_kernels.for_codes
from bringup.engine.local import run_local
from bringup.scenario.config import load_scenario
from bringup.scenario.participants import all_participants
from bringup.scenario.world import World

sc = load_scenario("paper").with_overrides(hours=1 / 3)
world = World.build(sc)
run_local(all_participants(world, "distributed", bpsec_key=bytes(32)), horizon_ns=sc.horizon_ns,
          max_step_ns=int(sc.scenario.lockstep_max_step_s * 1e9))
print(json.dumps({"took": took, "before": before, "after": sigs(), "calls": calls}))
"""

_LOAD = r"""
import json
from sat_node import kernels
took = kernels.warm_up()
out = {}
for k, d in kernels.dispatchers().items():
    out[k] = {"hits": sum(d.stats.cache_hits.values()), "misses": sum(d.stats.cache_misses.values()),
              "signatures": len(d.signatures)}
print(json.dumps({"took": took, "stats": out}))
"""


def _py(code: str, cache: Path) -> dict:
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache), PYTHONPATH=str(REPO))
    env.pop("NUMBA_DISABLE_JIT", None)
    r = subprocess.run([sys.executable, "-c", code], env=env, cwd=str(REPO), capture_output=True, text=True,
                       timeout=600, check=False)
    assert r.returncode == 0, r.stderr[-3000:]
    return json.loads(r.stdout.strip().splitlines()[-1])


def test_warm_up_covers_a_run_and_the_next_process_loads_it(tmp_path):
    cache = tmp_path / "numba"
    cache.mkdir()
    run = _py(_RUN, cache)
    assert min(run["calls"].values()) > 0, run["calls"]
    assert run["before"] == run["after"], "a run compiled a kernel signature warm_up did not"
    top = ("sat_node.scheduler.dp_kernels.dp_forward", "sat_node.dtn.cgr._dijkstra",
           "orbit_clock.access_kernels.for_codes")
    for k in top:
        assert len(run["before"][k]) == 1, run["before"][k]
    assert sorted(p.suffix for p in cache.rglob("*.nbi"))  # the cache is where we pointed it
    load = _py(_LOAD, cache)
    for k in top:
        st = load["stats"][k]
        assert st["misses"] == 0 and st["hits"] == 1 and st["signatures"] == 1, (k, st)
    # loading is much cheaper than compiling (the cold process compiled the same kernels)
    assert sum(load["took"].values()) < sum(run["took"].values())
