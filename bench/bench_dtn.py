"""Benchmark: CGR query time on the study's 1384-contact plan, and the whole DTN run on the study's
traffic (case4, case1) at 1 kb/s with the study's TTLs, for each forwarding mode side by side
(unicast: one bundle per (observation, recipient), the study simulator's model - the baseline of the
same run; multicast: one bundle per observation). Prints one block per (case, mode): figures per
(observation, recipient) pair beside the any-policy floor and the store-and-forward bound, and the
issue's targets (>= 99.5 % of pairs within TTL, mean <= 10 s, priority 1 p95 <= 10 s, no priority
1-6 drop).

    .venv/bin/python bench/bench_dtn.py [--cases case4 case1] [--forwarding multicast unicast]
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
from bringup.analysis.dtn_bounds import floor_mean, latency_lower_bounds, store_forward_bound_mean
from bringup.engine.keys import resolve_bpsec_key
from orbit_clock.contact_plan_io import read_contact_plan
from sat_node.dtn.agent import AgentConfig
from sat_node.dtn.cgr import ContactGraph
from sat_node.dtn.traffic import read_traffic

INPUTS = Path(os.environ.get("PAPER_INPUTS",
                            Path(__file__).resolve().parents[1] / "tests" / "fixtures" / "paper_inputs"))


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cases", nargs="+", default=["case4", "case1"])
    ap.add_argument("--queue", choices=["priority", "deadline"], default="priority",
                    help="send order (constellation dtn --queue)")
    ap.add_argument("--rate-bps", type=float, default=1000.0,
                    help="ISL rate (the study's link budget: 1000; its simulator's configuration: 1e6)")
    ap.add_argument("--hop-tolerance-s", type=float, default=0.0, help="constellation dtn --hop-tolerance-s")
    ap.add_argument("--forwarding", nargs="+", default=["unicast", "multicast"], choices=["unicast", "multicast"])
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
    for case in args.cases:
        traffic = read_traffic(INPUTS / f"traffic_{case}.csv")
        for fwd in args.forwarding:
            _run_case(case, fwd, plan, traffic, args)
    return 0


def _run_case(case, fwd, plan, traffic, args) -> None:
    t0 = time.perf_counter()
    cfg = AgentConfig.for_policy(args.queue, args.hop_tolerance_s, forwarding=fwd, key=resolve_bpsec_key()[0])
    run = run_dtn(plan, traffic, config=cfg)
    wall = time.perf_counter() - t0
    per_obs = fwd == "multicast"
    r = run.report(latency_lower_bounds(plan, traffic, 2000, run.created_ids, per_observation=per_obs))
    sf = store_forward_bound_mean(plan, traffic, 2000, cfg.ttl_s_by_priority, per_observation=per_obs)
    fl = floor_mean(plan, traffic, 2000, cfg.ttl_s_by_priority)
    p16_drop = sum(r[f"dtn.latency_s_by_priority.{p}.created"] - r[f"dtn.latency_s_by_priority.{p}.count"]
                   for p in range(1, 7))
    print(f"\n{case} {fwd} ({args.queue}): {r['dtn.observations']} observations, {r['dtn.bundles_originated']} bundles, "
          f"{r['dtn.bundles_created']} pairs; simulation {run.wall_s:.1f} s, with bounds {wall:.1f} s wall")
    print(f"   pairs delivered {r['dtn.delivery_ratio']:.4f}, within TTL {r['dtn.delivered_within_ttl_ratio']:.4f}; "
          f"conservation {r['dtn.conservation_ok']} (held at end {r['dtn.bundles_held_at_end']})")
    print(f"   latency mean {r['dtn.latency_s.mean']:.4g} s (floor {fl:.4g} s, store-and-forward bound {sf:.4g} s, "
          f"per-pair bound {r['dtn.latency_s.lower_bound_mean']:.4g} s); median {r['dtn.latency_s.median']:.4g} "
          f"p95 {r['dtn.latency_s.p95']:.4g} max {r['dtn.latency_s.max']:.4g}")
    print(f"   transmissions {r['dtn.transmissions']} ({r['dtn.transmissions_per_observation']:.3f} per observation, "
          f"{r['dtn.transmissions_per_bundle']:.3f} per pair); radios busy mean "
          f"{r['dtn.radio_busy_fraction.mean']:.3f} max {r['dtn.radio_busy_fraction.max']:.3f}; "
          f"{r['dtn.bits_on_air']} bits on air; failed {r['dtn.tx_failed']}; copies discarded {r['dtn.copies_discarded']}")
    print("   drops by reason:", {k.split(".")[-1]: v for k, v in r.items() if k.startswith("dtn.dropped_detail.")})
    p1 = r["dtn.latency_s_by_priority.1.p95"]
    print(f"   targets: within TTL >= 0.995: {r['dtn.delivered_within_ttl_ratio'] >= 0.995}; mean <= 10 s: "
          f"{r['dtn.latency_s.mean'] <= 10}; P1 p95 <= 10 s: {p1 is not None and p1 <= 10}; "
          f"no P1-6 drop: {p16_drop == 0} ({p16_drop} lost); wall <= 30 s: {wall <= 30}")
    print("   prio created delivered median_s  p95_s  max_s")
    for p in range(1, 16):
        c = r[f"dtn.latency_s_by_priority.{p}.created"]
        if c:
            vals = [r[f"dtn.latency_s_by_priority.{p}.{k}"] for k in ("median", "p95", "max")]
            print(f"   {p:4d} {c:7d} {r[f'dtn.latency_s_by_priority.{p}.count']:9d} "
                  + " ".join(f"{'-' if v is None else f'{v:.4g}':>7s}" for v in vals))


if __name__ == "__main__":
    sys.exit(main())
