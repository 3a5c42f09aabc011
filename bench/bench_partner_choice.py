"""Benchmark: joint planning's partner choice (``Planner.group``) with and without the region pass index.

Usage::

    nice .venv/bin/python bench/bench_partner_choice.py [--sats 96,240,480] [--ks 0,1] [--cases 60]
        [--json]

For each size, the paper scenario's orbits and ground points with a Walker star of N satellites in
3 planes (as ``bench_scale.py``), and ``--cases`` replans spread evenly over the satellites' passes
over a region in the first 50 minutes, each 30 s before its pass starts (a plan that has partners to
choose from). Each replan's group is chosen twice in this process, in alternating order: by the
scenario's planner, which asks the pass index (orbit_clock/access.py ``RegionPrefilter.passing`` /
``first_pass_s``; for K >= 1 best-first), and by the same planner without it (``passes=None``: every
other satellite asked one by one and, for K >= 1, every passing one looked at and sorted - the
choice as first written). Printed per size and K: the CPU seconds (``time.process_time``) of each,
their ratio, the mean group size, and whether every group was the same (the same partners in the
same order with the same instances; a difference stops the benchmark).

Only the partner choice is timed - not the joint DP solve that follows it, nor the rest of a run
(``bench_scale.py`` measures whole runs). Nothing is asserted on times.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from bringup.scenario.config import load_scenario
from bringup.scenario.world import OrbitContext
from sat_node.scheduler import Knowledge, PersistenceView, Planner


def cases(planner: Planner, n_cases: int) -> list[tuple[str, float]]:
    """``n_cases`` (satellite, time) pairs evenly spread over the satellites' passes of the first 50
    minutes, in satellite order: 30 s before a pass starts."""
    every = [(sat, max(0.0, float(s) - 30.0)) for sat in planner.constellation.names
             for s in planner.pass_starts_s(sat, 0.0, 3000.0)]
    pick = np.unique(np.linspace(0, len(every) - 1, num=min(n_cases, len(every))).round().astype(int))
    return [every[i] for i in pick]


def same(ga, gb) -> bool:
    return [q.sat_name for q in ga] == [q.sat_name for q in gb] and all(
        np.array_equal(a.gp_ids, b.gp_ids) and np.array_equal(a.in_for, b.in_for) and np.array_equal(a.absval, b.absval)
        for a, b in zip(ga, gb))


def measure(n: int, ks: list[int], n_cases: int) -> list[dict]:
    sc = load_scenario("paper").with_overrides(sats=n, planes=3, hours=1)
    ctx = OrbitContext.from_scenario(sc)
    base = ctx.planner()
    todo = cases(base, n_cases)
    rows = []
    for k in ks:
        st = dataclasses.replace(base.settings, joint_max_partners=k)
        index = Planner(base.constellation, base.gp_ecef_km, base.slew, st, candidates=base.candidates,
                        own=base.own, passes=base.passes)
        one_by_one = Planner(base.constellation, base.gp_ecef_km, base.slew, st, candidates=base.candidates,
                             own=base.own)
        index.group(*_args(index, ctx, *todo[0]))  # the index and the kernels built before timing
        cpu = {"index": 0.0, "one_by_one": 0.0}
        members = 0
        for j, (sat, t0) in enumerate(todo):
            args = _args(index, ctx, sat, t0)
            got = {}
            pair = (("index", index), ("one_by_one", one_by_one))
            for name, p in pair if j % 2 == 0 else pair[::-1]:
                c0 = time.process_time()
                got[name] = p.group(*args)
                cpu[name] += time.process_time() - c0
            if not same(got["index"], got["one_by_one"]):
                raise SystemExit(f"{n} satellites, K = {k}: {sat} at {t0} s: the groups differ")
            members += len(got["index"])
        rows.append({"sats": n, "k": k, "cases": len(todo), "cpu_index_s": round(cpu["index"], 3),
                     "cpu_one_by_one_s": round(cpu["one_by_one"], 3),
                     "ratio": round(cpu["one_by_one"] / max(cpu["index"], 1e-9), 2),
                     "mean_group": round(members / max(1, len(todo)), 2), "same_groups": True,
                     "load": round(os.getloadavg()[0], 1)})
    return rows


def _args(planner: Planner, ctx, sat: str, t0: float):
    know = Knowledge(PersistenceView(ctx.osse, t0))
    window = planner.settings.plan_lookahead_s
    mine = planner.instance(sat, t0, know, window_s=window, gp_ids=planner.candidates(sat, t0, t0 + window))
    return sat, t0, window, know, mine


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sats", default="96,240,480")
    ap.add_argument("--ks", default="0,1", help="bounds to time (0: unbounded, the study's)")
    ap.add_argument("--cases", type=int, default=60)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    rows = []
    for n in (int(x) for x in args.sats.split(",")):
        for row in measure(n, [int(x) for x in args.ks.split(",")], args.cases):
            rows.append(row)
            if not args.json:
                print(json.dumps(row), flush=True)
    if args.json:
        print(json.dumps({"rows": rows}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
