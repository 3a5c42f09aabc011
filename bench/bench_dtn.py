"""Benchmark: CGR query time on the study's 1384-contact plan, and the whole DTN run on the study's
traffic (case4, case1) at 1 kb/s with the study's TTLs. Prints one table row per case.

    .venv/bin/python bench/bench_dtn.py [--cases case4 case1]
"""

from __future__ import annotations

import argparse
import os
import random
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bringup.analysis.dtn_alone import run_dtn
from bringup.analysis.dtn_bounds import latency_lower_bounds, store_forward_bound_mean
from orbit_clock.contact_plan_io import read_contact_plan
from sat_node.dtn.agent import AgentConfig
from sat_node.dtn.cgr import ContactGraph
from sat_node.dtn.traffic import read_traffic

INPUTS = Path(os.environ.get("PAPER_INPUTS", Path(__file__).resolve().parents[2] / "shared" / "paper_inputs"))


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cases", nargs="+", default=["case4", "case1"])
    ap.add_argument("--queue", choices=["priority", "deadline"], default="priority",
                    help="send order (constellation dtn --queue)")
    ap.add_argument("--rate-bps", type=float, default=1000.0,
                    help="ISL rate (the study's link budget: 1000; its simulator's configuration: 1e6)")
    ap.add_argument("--hop-tolerance-s", type=float, default=0.0, help="constellation dtn --hop-tolerance-s")
    args = ap.parse_args()
    plan = read_contact_plan(INPUTS / "contact_plan_3p_8s.csv", rate_bps=args.rate_bps)
    g = ContactGraph(plan)
    g.route("sat_11", "sat_35", 0.0, 2000)  # compile / load the numba cache
    rng = random.Random(1)
    n = 2000
    t0 = time.perf_counter()
    for _ in range(n):
        a, b = rng.sample(g.node_names, 2)
        g.route(a, b, rng.uniform(0, 21000), 2000, backlog_bits=rng.choice([0, 20000]))
    print(f"CGR query on {len(plan)} contacts: {(time.perf_counter() - t0) / n * 1e3:.3f} ms mean over {n}")
    print("case   created delivered ratio  mean_s  bound_s  ratio_to_bound median_s p95_s  max_s  "
          "drop_ttl drop_other copies_disc wall_s")
    for case in args.cases:
        traffic = read_traffic(INPUTS / f"traffic_{case}.csv")
        t0 = time.perf_counter()
        cfg = AgentConfig.for_policy(args.queue, args.hop_tolerance_s)
        run = run_dtn(plan, traffic, config=cfg)
        lb = latency_lower_bounds(plan, traffic, 2000, run.created_ids)
        wall = time.perf_counter() - t0
        r = run.report(lb)
        print(f"{case:6s} {r['dtn.bundles_created']:7d} {r['dtn.bundles_delivered']:9d} {r['dtn.delivery_ratio']:.4f} "
              f"{r['dtn.latency_s.mean']:7.4g} {r['dtn.latency_s.lower_bound_mean']:8.4g} "
              f"{r['dtn.latency_s.mean'] / r['dtn.latency_s.lower_bound_mean']:14.2f} {r['dtn.latency_s.median']:8.4g} "
              f"{r['dtn.latency_s.p95']:6.4g} {r['dtn.latency_s.max']:6.4g} {r['dtn.dropped.ttl']:8d} "
              f"{r['dtn.dropped.other']:10d} {r['dtn.copies_discarded']:11d} {wall:6.1f}  conservation="
              f"{r['dtn.conservation_ok']}")
        sf = store_forward_bound_mean(plan, traffic, 2000, cfg.ttl_s_by_priority)
        print(f"   store-and-forward bound on the mean (any routing, any order): {sf:.4g} s; "
              f"measured / it = {r['dtn.latency_s.mean'] / sf:.2f}; the issue's bound / it = "
              f"{r['dtn.latency_s.lower_bound_mean'] / sf:.2f}")
        print("   drops by reason:", {k.split(".")[-1]: v for k, v in r.items() if k.startswith("dtn.dropped_detail.")},
              " transmissions:", r["dtn.transmissions"], f"({r['dtn.transmissions_per_bundle']:.3f} per bundle)",
              " failed:", r["dtn.tx_failed"], " steps:", run.steps,
              " sim wall s:", round(run.wall_s, 1))
        print("   prio created delivered median_s  p95_s  max_s")
        for p in range(1, 16):
            c = r[f"dtn.latency_s_by_priority.{p}.created"]
            if c:
                vals = [r[f"dtn.latency_s_by_priority.{p}.{k}"] for k in ("median", "p95", "max")]
                print(f"   {p:4d} {c:7d} {r[f'dtn.latency_s_by_priority.{p}.count']:9d} "
                      + " ".join(f"{'-' if v is None else f'{v:.4g}':>7s}" for v in vals))
    return 0


if __name__ == "__main__":
    sys.exit(main())
