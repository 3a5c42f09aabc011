"""Benchmark: a planner's replanning cost as the looks it knows grow (the observed knowledge model).

Usage::

    .venv/bin/python bench/bench_replan.py [--known 0,3000,10000,30000] [--plans-per-sat 12] [--json]

Each plan's observed view sums over the known looks of the regions it plans over
(sat_node/knowledge.py ``ObservedView``), so its cost grows with the looks the planner knows. How
many that is depends on the run: a satellite of the distributed paper scenario knows its own looks
and those sent to it (each observation goes to the 15 satellites next over its region: 1000
satellites x 1 h, 10 118 observations, 147 255 bundles delivered - ~160 looks per satellite), the
ground segment (centralized) every look downlinked to it. This benchmark
builds the paper scenario's world once (its 24 satellites' orbits, GPs, OSSE field and planner: a
plan alone costs the same in a larger constellation), gives one planner ``--known`` N synthetic
looks - at the paper regions' GPs (a few hundred per region, looked at again and again), made over
the memory the model keeps (7 e-folding times before the planning time), with random inferred values
and region insights, and the same looks as the observations Eq. 1's prior state counts - and times,
in CPU seconds, what a satellite's replan does: ``KnowledgeState.knowledge`` and ``Planner.plan``
(alone), for every satellite at ``--plans-per-sat`` planning times 5 min apart from 4 h on. The
first N is the baseline of the same call. Printed per N: plans, plans with GPs (DP solves), CPU s
per plan, and its ratio to the baseline.

To compare two checkouts, run this file from each (the figures are CPU seconds, less sensitive to
the machine's load than wall time; note the load, printed before and after). bringup is imported
before numpy, as the ``constellation`` command does (its OpenBLAS set-up, bringup/__init__.py).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

# isort: off
import bringup  # noqa: F401  (first, as in the constellation command: its process set-up precedes numpy)

# isort: on
import numpy as np

from bringup.scenario.config import load_scenario
from bringup.scenario.world import OrbitContext
from sat_node.inference import Inference
from sat_node.knowledge import KnowledgeParams, KnowledgeState
from sat_node.value import KnownLog, KnownObservation


def known_state(ctx, params: KnowledgeParams, n: int, t_now_s: float, seed: int = 1):
    """A planner's KnowledgeState and KnownLog holding ``n`` synthetic looks (module docstring)."""
    rng = np.random.default_rng(seed)
    ks = KnowledgeState(params, "sat_bench")
    known = KnownLog()
    region = ctx.gps.region_index
    gp = rng.integers(0, len(region), n)
    t = np.sort(rng.uniform(t_now_s - 7.0 * params.memory_s, t_now_s, n))
    for i in range(n):
        t_ns = int(t[i] * 1e9)
        src = f"sat_{int(rng.integers(11, 99))}"
        ks.learn(Inference(src, int(gp[i]), t_ns, float(rng.uniform(1.0, 256.0)), int(region[gp[i]]),
                           float(rng.normal(0.0, 0.5)), float(rng.normal(0.0, 0.1))))
        known.append(KnownObservation(t_ns / 1e9, int(gp[i]), src))
    return ks, known


def measure(ctx, planner, n: int, plans_per_sat: int) -> dict:
    sc = ctx.scenario
    params = KnowledgeParams.from_scenario(sc)
    t0 = 4 * 3600.0
    ks, known = known_state(ctx, params, n, t0)
    names = list(ctx.constellation.names)
    window = float(sc.scheduler.plan_lookahead_s)
    plans = solved = 0
    c0 = time.process_time()
    for k in range(plans_per_sat):
        t = t0 + 300.0 * k
        for name in names:
            knowledge = ks.knowledge(ctx.osse, ctx.gps.region_index, ctx.gps.ecef_km, t, known, None)
            plan = planner.plan(name, t, window, knowledge)
            plans += 1
            solved += plan is not None and len(plan.steps) > 0
    cpu = time.process_time() - c0
    return {"known": n, "plans": plans, "plans_with_looks": solved, "cpu_s": round(cpu, 2),
            "cpu_ms_per_plan": round(1e3 * cpu / plans, 2)}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--known", default="0,3000,10000,30000", help="looks known; the first is the baseline")
    ap.add_argument("--plans-per-sat", type=int, default=12)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    sc = load_scenario("paper")
    ctx = OrbitContext.from_scenario(sc)
    planner = ctx.planner()
    load0 = os.getloadavg()[0]
    measure(ctx, planner, 100, 1)  # compiles the kernels
    rows = [measure(ctx, planner, int(n), args.plans_per_sat) for n in args.known.split(",")]
    base = rows[0]["cpu_ms_per_plan"]
    for r in rows:
        r["x_baseline"] = round(r["cpu_ms_per_plan"] / base, 2) if base else None
    doc = {"sats": len(ctx.constellation.names), "rows": rows, "load": [round(load0, 1), round(os.getloadavg()[0], 1)]}
    if args.json:
        print(json.dumps(doc, indent=2))
        return 0
    for r in rows:
        print(json.dumps(r))
    print(f"load {doc['load'][0]} -> {doc['load'][1]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
