"""Benchmark: CGR query time on the study's 1384-contact plan, and the whole DTN run on the study's
traffic (case4, case1) at 1 kb/s with the study's TTLs, for each forwarding mode side by side
(unicast: one bundle per (observation, recipient), the study simulator's model - the baseline of the
same run; multicast: one bundle per observation). Prints one block per (case, mode): figures per
(observation, recipient) pair beside the any-policy floor and the store-and-forward bound, and the
issue's targets (>= 99.5 % of pairs within TTL, mean <= 10 s, priority 1 p95 <= 10 s, no priority
1-6 drop).

    .venv/bin/python bench/bench_dtn.py [--cases case4 case1] [--forwarding multicast unicast]

``--side-by-side --dtnsim-src DIR --dtnsim-python PY``: the authors' simulator (dtnsim, a checkout
the caller provides; bench/dtnsim_side.py says how to set it up) on the same inputs - its walker
scenario edited to 21600 s, 1 kb/s and the study's TTLs - against ``constellation dtn`` of this
checkout (and of ``--baseline-src DIR``, another checkout, when given), each a whole process, run
alternately per case: prints every wall and CPU time with the machine's load, and the ratio dtnsim /
ours per case and forwarding (``--repeat N`` rounds; ratios of the medians).
"""

from __future__ import annotations

import argparse
import json
import os
import random
import resource
import statistics
import subprocess
import sys
import tempfile
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
    ap.add_argument("--side-by-side", action="store_true",
                    help="time dtnsim (--dtnsim-src, --dtnsim-python) against constellation dtn, alternately")
    ap.add_argument("--dtnsim-src", type=Path, help="a checkout of github msancheznet/dtnsim")
    ap.add_argument("--dtnsim-python", help="a Python 3.7 with dtnsim's dependencies (bench/dtnsim_side.py)")
    ap.add_argument("--baseline-src", type=Path, help="--side-by-side: another checkout's constellation dtn too")
    ap.add_argument("--repeat", type=int, default=1, help="--side-by-side rounds")
    args = ap.parse_args()
    if args.side_by_side:
        return side_by_side(args)
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


def _load() -> str:
    return "load " + "/".join(f"{x:.1f}" for x in os.getloadavg())


def _timed(cmd: list[str], cwd: Path, env: dict) -> tuple[float, float, str]:
    """Run ``cmd``: (wall [s], CPU of the process and its children [s], stdout)."""
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    p = subprocess.run(cmd, cwd=cwd, env=env, check=False, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if p.returncode != 0:
        raise SystemExit(f"{' '.join(cmd[:4])}... failed (exit {p.returncode}): {p.stderr.strip()[-400:]}")
    return wall, (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime), p.stdout


def _ours(src: Path, case: str, fwd: str) -> tuple[float, float, dict]:
    """``constellation dtn`` of checkout ``src`` on the study's inputs, as the issue times it (a
    checkout from before multicast forwarding has no --forwarding: unicast is what it runs)."""
    cmd = [sys.executable, "-m", "bringup.cli", "dtn", "--contact-plan", str(INPUTS / "contact_plan_3p_8s.csv"),
           "--traffic", str(INPUTS / f"traffic_{case}.csv"), "--rate-bps", "1000", "--bundle-bits", "2000", "--json"]
    if _has_forwarding(src):
        cmd += ["--forwarding", fwd]
    env = dict(os.environ, PYTHONPATH=str(src))
    wall, cpu, out = _timed(cmd, src, env)
    return wall, cpu, json.loads(out)


def _has_forwarding(src: Path) -> bool:
    return (src / "sat_node" / "dtn" / "multicast.py").is_file()


def side_by_side(args) -> int:
    import dtnsim_side  # bench/, beside this file

    if args.dtnsim_src is None or args.dtnsim_python is None:
        raise SystemExit("--side-by-side needs --dtnsim-src DIR and --dtnsim-python PY (bench/dtnsim_side.py)")
    ttl = AgentConfig(key=b"\0" * 32).ttl_s_by_priority  # the study's TTLs, as constellation dtn's default
    here = Path(__file__).resolve().parents[1]
    checkouts = [("ours", here)] + ([("baseline", args.baseline_src.resolve())] if args.baseline_src else [])
    walls: dict[tuple, list[float]] = {}
    cpus: dict[tuple, list[float]] = {}
    with tempfile.TemporaryDirectory(prefix="dtnsim-side-") as tmp:
        configs = {case: dtnsim_side.write_inputs(args.dtnsim_src, INPUTS / f"traffic_{case}.csv", Path(tmp) / case)
                   for case in args.cases}
        for rnd in range(args.repeat):
            for case in args.cases:
                load0 = _load()
                d = dtnsim_side.run_dtnsim(args.dtnsim_python, args.dtnsim_src, configs[case], ttl)
                walls.setdefault((case, "dtnsim"), []).append(d["wall_s"])
                cpus.setdefault((case, "dtnsim"), []).append(d["cpu_s"])
                print(f"[{rnd + 1}] {case} dtnsim: wall {d['wall_s']:.1f} s, CPU {d['cpu_s']:.1f} s "
                      f"(simulation {d['sim_wall_s']:.1f} s wall); "
                      f"bundles sent {d['sent']}, arrived {d['arrived']}, dropped {d['dropped']}; {load0} -> {_load()}",
                      flush=True)
                for label, src in checkouts:
                    for fwd in args.forwarding if _has_forwarding(src) else ["unicast"]:
                        load0 = _load()
                        wall, cpu, rep = _ours(src, case, fwd)
                        walls.setdefault((case, f"{label} {fwd}"), []).append(wall)
                        cpus.setdefault((case, f"{label} {fwd}"), []).append(cpu)
                        print(f"[{rnd + 1}] {case} {label} {fwd}: wall {wall:.1f} s, CPU {cpu:.1f} s; pairs delivered "
                              f"{rep['dtn.bundles_delivered']} of {rep['dtn.bundles_created']}, mean latency "
                              f"{rep['dtn.latency_s.mean']:.4f} s; {load0} -> {_load()}", flush=True)
    print("\nmedians (wall, CPU) and dtnsim / ours (on a loaded machine the CPU ratio says more):")
    for case in args.cases:
        ref, ref_cpu = statistics.median(walls[(case, "dtnsim")]), statistics.median(cpus[(case, "dtnsim")])
        print(f"  {case} dtnsim: wall {ref:.1f} s, CPU {ref_cpu:.1f} s")
        for (c, who), w in walls.items():
            if c == case and who != "dtnsim":
                m, mc = statistics.median(w), statistics.median(cpus[(c, who)])
                print(f"  {case} {who}: wall {m:.1f} s, CPU {mc:.1f} s; dtnsim / ours: wall {ref / m:.2f}x, "
                      f"CPU {ref_cpu / mc:.2f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
