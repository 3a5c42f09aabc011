"""Benchmark: what bounding joint planning's group costs in value, and what it saves in CPU.

Usage::

    nice .venv/bin/python bench/bench_joint_bound.py [--sats 24] [--hours 6] [--seeds 1,2,3]
        [--variants 0,1,2,alone] [--json]

Each (variant, seed) is one `constellation run --engine local` of the paper scenario as a child
process from this checkout, one after the other: variant ``0`` is the scenario's joint planning with
every overlapping satellite (the study's, Nag et al. 2019 Table 1 lines 9-20), ``K`` >= 1 joint
planning with at most K partners (``--joint-max-partners K``: those that may first see one of the
planned satellite's GPs earliest, sat_node/scheduler/planner.py ``Planner.group``), ``alone`` every satellite
planning by itself (``--planning alone``). Printed per run: report.json ``value.cumulative``,
``coverage.gp_observed_fraction``, ``observations.count``, ``observations.duplicates_15min``,
``value.assumed_error_mean``, the plans made (``schedules.count``: periodic and for news), the planners' CPU (``runtime.scheduler_cpu_s_per_sat`` x N), the
process tree's CPU (user + system of the child and its recorder) and the load average before the
run; then per variant the mean and sample standard deviation over the seeds, and the ratio of the
mean to the unbounded variant's and to ``alone``'s (when they ran). Seeds change the field, the
belief noise and the ISL draws alike for every variant, so the variants are compared seed by seed
too (the mean of the per-seed ratios is printed beside the ratio of means).

Nothing here is asserted: it measures a science choice (which partners a plan predicts) that the
default (``0``, unbounded) does not make. CPU figures on a shared machine: run it with ``nice`` and
read the load column.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

KEYS = {  # column -> report.json path
    "value": ("value", "cumulative"),
    "coverage": ("coverage", "gp_observed_fraction"),
    "observations": ("observations", "count"),
    "duplicates": ("observations", "duplicates_15min"),
    "assumed_error": ("value", "assumed_error_mean"),
    "plans": ("schedules", "count"),
}


def _variant_args(v: str) -> list[str]:
    if v == "alone":
        return ["--planning", "alone"]
    k = int(v)
    if k < 0:
        raise SystemExit(f"--variants: {v!r}: a number of partners >= 0 (0: unbounded) or 'alone'")
    return ["--planning", "joint", "--joint-max-partners", str(k)]


def run_one(variant: str, seed: int, args, out: Path) -> dict:
    cmd = [sys.executable, "-m", "bringup.cli", "run", "--engine", "local", "--scenario", args.scenario,
           "--sats", str(args.sats), "--hours", str(args.hours), "--seed", str(seed), *_variant_args(variant),
           "--out", str(out), "--no-plots", "--no-progress"]
    load0 = os.getloadavg()[0]
    c0 = os.times()
    proc = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, cwd=str(REPO), check=False)
    c1 = os.times()
    if proc.returncode != 0:
        raise SystemExit(f"{variant} seed {seed}: run failed: {proc.stderr[-2000:]}")
    rep = json.loads((out / "report.json").read_text())
    row = {"variant": variant, "seed": seed}
    for col, (a, b) in KEYS.items():
        row[col] = rep[a][b]
    row["planning_cpu_s"] = round(rep["runtime"]["scheduler_cpu_s_per_sat"] * rep["n_sats"], 1)
    row["cpu_s"] = round((c1.children_user - c0.children_user) + (c1.children_system - c0.children_system), 1)
    row["load"] = round(load0, 1)
    return row


def summarize(rows: list[dict], variants: list[str]) -> list[dict]:
    by = {v: {r["seed"]: r for r in rows if r["variant"] == v} for v in variants}
    out = []
    for v in variants:
        s = {"variant": v, "seeds": sorted(by[v])}
        for col in (*KEYS, "planning_cpu_s", "cpu_s"):
            xs = [by[v][k][col] for k in sorted(by[v])]
            s[col] = statistics.fmean(xs)
            s[col + "_sd"] = statistics.stdev(xs) if len(xs) > 1 else 0.0
            for ref in ("0", "alone"):
                if ref in by and ref != v and by[ref]:
                    ys = [by[ref][k][col] for k in sorted(by[v]) if k in by[ref]]
                    base = statistics.fmean(ys) if ys else 0.0
                    s[f"{col}_over_{ref}"] = s[col] / base if base else None
                    per = [by[v][k][col] / by[ref][k][col] for k in sorted(by[v]) if k in by[ref] and by[ref][k][col]]
                    s[f"{col}_over_{ref}_per_seed"] = statistics.fmean(per) if per else None
        out.append(s)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenario", default="paper")
    ap.add_argument("--sats", type=int, default=24)
    ap.add_argument("--hours", type=float, default=6.0)
    ap.add_argument("--seeds", default="1,2,3")
    ap.add_argument("--variants", default="0,1,2,alone", help="0 (unbounded), K >= 1 partners, alone")
    ap.add_argument("--json", action="store_true", help="one JSON document at the end instead of the tables")
    args = ap.parse_args()
    seeds = [int(x) for x in args.seeds.split(",")]
    variants = [v.strip() for v in args.variants.split(",")]
    for v in variants:
        _variant_args(v)
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench_joint_bound_") as d:
        for seed in seeds:  # seed-major: a drifting machine load spreads over every variant alike
            for v in variants:
                row = run_one(v, seed, args, Path(d) / f"{v}-s{seed}")
                rows.append(row)
                if not args.json:
                    print(json.dumps(row), flush=True)
    summary = summarize(rows, variants)
    doc = {"scenario": args.scenario, "sats": args.sats, "hours": args.hours, "seeds": seeds, "rows": rows,
           "summary": summary}
    if args.json:
        print(json.dumps(doc, indent=2))
        return 0
    print(f"\n{args.scenario}, {args.sats} satellites, {args.hours:g} h, local engine, seeds {seeds}: mean +- sd")
    print(f"{'variant':>8} {'value':>17} {'coverage':>15} {'obs':>13} {'dup':>11} {'assumed err':>15} "
          f"{'plans':>13} {'plan cpu s':>13} {'cpu s':>13} {'v/unb':>6} {'v/alone':>7}")
    for s in summary:
        def f(c, fmt, s=s):
            return f"{format(s[c], fmt)} +- {format(s[c + '_sd'], fmt)}"

        r0 = s.get("value_over_0")
        ra = s.get("value_over_alone")
        print(f"{s['variant']:>8} {f('value', '.0f'):>17} {f('coverage', '.4f'):>15} {f('observations', '.0f'):>13} "
              f"{f('duplicates', '.1f'):>11} {f('assumed_error', '.4f'):>15} {f('plans', '.0f'):>13} "
              f"{f('planning_cpu_s', '.1f'):>13} "
              f"{f('cpu_s', '.1f'):>13} {'-' if r0 is None else format(r0, '.4f'):>6} "
              f"{'-' if ra is None else format(ra, '.4f'):>7}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
