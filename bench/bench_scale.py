"""Benchmark: how a whole run's cost grows with the constellation (local engine).

Usage::

    .venv/bin/python bench/bench_scale.py [--sats 24,48,96,240,480] [--hours 6] [--planes 3]
        [--regions paper|global] [--planning joint|alone] [--joint-max-partners K] [--json]

A run of minutes: ``--sats 24,48,96 --hours 1``. ``--force`` passes ``--force`` to every run (sizes past
the run's work limit, bringup/scenario/limits.py, e.g. ``--sats 1000 --planes 25``).

Each size is one `constellation run --engine local --sats N --planes P` (a Walker star over the
paper scenario's orbits; `--planes 3` keeps the paper's planes, as `--sats` alone does), run as a
child process from this checkout. Printed per size: wall time, CPU time of the process tree (the
run and its recorder), peak memory (sum of the tree's PSS, sampled every 0.25 s from /proc, as
bench/bench_run.py does), the run's own figures (observations, bundles created / delivered, envelopes
on the bus, CGR queries: report.json ``runtime.cgr_queries``, the bundle agents' route searches;
plans: ``schedules.count``, per satellite-hour, and the planners' own CPU seconds,
``runtime.scheduler_cpu_s_per_sat`` x N)
and the ratios to the first size, which is the baseline of the same call (24 satellites unless
``--sats`` says otherwise). Then the fitted growth exponent b of wall = a * N^b (least squares in
log-log over every size) and the exponent between the baseline and each size.

``--planning alone`` plans every satellite by itself instead of jointly with the satellites whose
fields of regard overlap (the scenario's default, sat_node/scheduler/joint.py): a satellite's group
grows with the constellation's density, so joint planning's cost grows faster than N; ``alone``
measures the rest (orbits, contacts, routing, bundles) without it. ``--joint-max-partners K`` bounds
the group to the K partners that may first see one of the planned satellite's GPs earliest (scenario key
``scheduler.joint_max_partners``, sat_node/scheduler/planner.py ``Planner.group``; default 0: every
overlapping satellite, the scenario's).

The run is started through this file (``_counted_run``), which counts in the run's process the DP
solves (every ``solve_dp`` call: plans alone, joint members, dive and search re-solves) and the
joint plans with their members: printed as ``dp_solves``, ``dp_per_sat_h``, ``joint_plans``,
``mean_group`` (members, the planned satellite included) and ``dp_per_joint`` (DP solves spent by
``solve_joint`` per joint plan). Plans whose group is empty are planned alone and are not joint plans.

``--regions global`` replaces the paper's five regions by a global grid of 80 km regions (every
30 deg of latitude from -60 to 60, every 45 deg of longitude: 40 regions, 4000 ground points), so
that observations and bundles are not limited by five cities.

Targets (the issue's, measured here, never asserted in tests): 240 satellites x 6 h in <= 10 min
with <= 8 GiB; exponent 24 -> 240 <= 1.5. The load of the machine (``os.getloadavg``) is printed
before and after each run: wall times on a loaded 2-core machine are not comparable; CPU times are
less sensitive.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "bench"))

import msgspec
from bench_run import _mem_mib, _tree

from bringup.scenario.config import load_scenario
from bringup.scenario.toml_text import to_toml


def global_regions() -> list[dict]:
    return [{"name": f"g{lat:+03d}{lon:+04d}", "lat_deg": float(lat), "lon_deg": float(lon), "size_km": 80.0}
            for lat in range(-60, 61, 30) for lon in range(-180, 180, 45)]


def scenario_file(regions: str, folder: Path) -> str:
    """The scenario the runs use: ``paper``, or a copy of it with the global grid of regions."""
    if regions == "paper":
        return "paper"
    raw = msgspec.to_builtins(load_scenario("paper"))
    raw.pop("source_path", None)
    raw["scenario"]["name"] = "paper-global"
    raw["regions"]["list"] = global_regions()
    path = folder / "paper-global.toml"
    path.write_text(to_toml(raw))
    load_scenario(path)  # validated like any scenario file
    return str(path)


def run_size(n: int, planes: int, args, scenario: str, out: Path) -> dict:
    p = max(1, min(planes, n))
    while n % p:
        p -= 1
    counts_path = out.parent / f"counts{n}.json"
    cmd = [sys.executable, str(Path(__file__).resolve()), "_counted_run", str(counts_path),
           "run", "--engine", "local", "--scenario", scenario, "--sats", str(n),
           "--planes", str(p), "--hours", str(args.hours), "--planning", args.planning, "--out", str(out), "--no-plots", "--no-progress"]
    if args.joint_max_partners is not None:
        cmd += ["--joint-max-partners", str(args.joint_max_partners)]
    if args.force:
        cmd += ["--force"]
    load0 = os.getloadavg()[0]
    c0 = os.times()
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, cwd=str(REPO))
    peak = 0.0
    while proc.poll() is None:
        peak = max(peak, _mem_mib(_tree(proc.pid))[1])
        time.sleep(0.25)
    wall = time.perf_counter() - t0
    c1 = os.times()
    err = proc.stderr.read()
    if proc.returncode != 0:
        raise SystemExit(f"{n} satellites: run failed: {err[-2000:]}")
    rep = json.loads((out / "report.json").read_text())
    rt = rep["runtime"]
    cnt = json.loads(counts_path.read_text())
    return {"sats": n, "planes": p, "wall_s": round(wall, 1),
            "cpu_s": round((c1.children_user - c0.children_user) + (c1.children_system - c0.children_system), 1),
            "peak_pss_mib": round(peak), "observations": rep["observations"]["count"],
            "bundles_created": rep["dtn"]["bundles_created"], "bundles_delivered": rep["dtn"]["bundles_delivered"],
            "envelopes": rt.get("envelopes"), "cgr_queries": rt.get("cgr_queries"),
            "plans": rep["schedules"]["count"],
            "plans_per_sat_h": round(rep["schedules"]["count"] / (n * args.hours), 1),
            "planning_cpu_s": round(rt["scheduler_cpu_s_per_sat"] * n, 1),
            "dp_solves": cnt["dp_solves"], "dp_per_sat_h": round(cnt["dp_solves"] / (n * args.hours), 1),
            "joint_plans": cnt["joint_plans"],
            "mean_group": round(cnt["group_members"] / cnt["joint_plans"], 2) if cnt["joint_plans"] else None,
            "dp_per_joint": round(cnt["joint_dp_solves"] / cnt["joint_plans"], 1) if cnt["joint_plans"] else None,
            "value": round(rep["value"]["cumulative"]), "load_before": round(load0, 1),
            "load_after": round(os.getloadavg()[0], 1)}


def _counted_run(counts_path: str, run_argv: list[str]) -> int:
    """``constellation run`` in this process with the planners' DP solves and joint plans counted
    (module docstring); the counts written to ``counts_path`` as JSON."""
    from bringup.cli.main import main as cli_main
    from sat_node.scheduler import dp, joint, planner

    counts = {"dp_solves": 0, "joint_plans": 0, "group_members": 0, "joint_dp_solves": 0}
    solve_dp, solve_joint = dp.solve_dp, planner.solve_joint

    def counted_dp(p, *a, **kw):
        counts["dp_solves"] += 1
        return solve_dp(p, *a, **kw)

    def counted_joint(problems, **kw):
        res = solve_joint(problems, **kw)
        counts["joint_plans"] += 1
        counts["group_members"] += len(problems)
        counts["joint_dp_solves"] += res.dp_solves
        return res

    dp.solve_dp = joint.solve_dp = planner.solve_dp = counted_dp
    planner.solve_joint = counted_joint
    code = cli_main(run_argv)
    Path(counts_path).write_text(json.dumps(counts))
    return code


def exponent(ns, ys) -> float:
    """b of y = a * n^b, least squares in log-log."""
    return float(np.polyfit(np.log(ns), np.log(ys), 1)[0])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sats", default="24,48,96,240,480", help="constellation sizes; the first is the baseline")
    ap.add_argument("--hours", type=float, default=6.0)
    ap.add_argument("--planes", type=int, default=3, help="planes (the largest <= this that divides each size)")
    ap.add_argument("--regions", choices=("paper", "global"), default="paper")
    ap.add_argument("--planning", choices=("joint", "alone"), default="joint",
                    help="joint (the scenario's) or alone: each satellite plans by itself")
    ap.add_argument("--joint-max-partners", type=int, default=None, metavar="K",
                    help="joint planning with at most K partners (0: all, the scenario's default)")
    ap.add_argument("--force", action="store_true",
                    help="pass --force to the runs (sizes past the run's work limit: 1000 satellites x 25 planes)")
    ap.add_argument("--json", action="store_true", help="one JSON document at the end instead of the table")
    args = ap.parse_args()
    sizes = [int(x) for x in args.sats.split(",")]
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench_scale_") as d:
        scenario = scenario_file(args.regions, Path(d))
        for n in sizes:
            row = run_size(n, args.planes, args, scenario, Path(d) / f"run{n}")
            rows.append(row)
            if not args.json:
                print(json.dumps(row), flush=True)
    base = rows[0]
    for r in rows:
        r["wall_x"] = round(r["wall_s"] / base["wall_s"], 2)
        r["cpu_x"] = round(r["cpu_s"] / base["cpu_s"], 2)
        r["exp_wall_from_base"] = (round(math.log(r["wall_s"] / base["wall_s"]) / math.log(r["sats"] / base["sats"]), 2)
                                   if r is not base else None)
        r["exp_cpu_from_base"] = (round(math.log(r["cpu_s"] / base["cpu_s"]) / math.log(r["sats"] / base["sats"]), 2)
                                  if r is not base else None)
    fit = {}
    if len(rows) >= 2:
        ns = [r["sats"] for r in rows]
        fit = {"wall": round(exponent(ns, [r["wall_s"] for r in rows]), 2),
               "cpu": round(exponent(ns, [r["cpu_s"] for r in rows]), 2)}
        for k in ("bundles_created", "cgr_queries", "envelopes", "plans", "planning_cpu_s", "dp_solves"):
            if all(r.get(k) for r in rows):
                fit[k] = round(exponent(ns, [r[k] for r in rows]), 2)
    doc = {"hours": args.hours, "regions": args.regions, "planning": args.planning,
           "joint_max_partners": args.joint_max_partners, "rows": rows, "fitted_exponent": fit}
    if args.json:
        print(json.dumps(doc, indent=2))
        return 0
    print(f"\n{'sats':>5} {'planes':>6} {'wall s':>8} {'x':>6} {'cpu s':>8} {'PSS MiB':>8} {'obs':>6} {'bundles':>8} "
          f"{'cgr':>9} {'env':>10} {'plans/sat-h':>11} {'plan cpu s':>10} {'exp(wall)':>9} {'exp(cpu)':>8} {'load':>9}")
    for r in rows:
        print(f"{r['sats']:>5} {r['planes']:>6} {r['wall_s']:>8.1f} {r['wall_x']:>6.2f} {r['cpu_s']:>8.1f} "
              f"{r['peak_pss_mib']:>8} {r['observations']:>6} {r['bundles_created']:>8} {r['cgr_queries'] or 0:>9} "
              f"{r['envelopes'] or 0:>10} {r['plans_per_sat_h']:>11.1f} {r['planning_cpu_s']:>10.1f} "
              f"{r['exp_wall_from_base'] or 0:>9.2f} {r['exp_cpu_from_base'] or 0:>8.2f} "
              f"{r['load_before']:>4}/{r['load_after']:<4}")
    print(f"\n{'sats':>5} {'dp solves':>10} {'dp/sat-h':>9} {'joint plans':>11} {'mean group':>10} {'dp/joint':>8}")
    for r in rows:
        print(f"{r['sats']:>5} {r['dp_solves']:>10} {r['dp_per_sat_h']:>9.1f} {r['joint_plans']:>11} "
              f"{r['mean_group'] or 0:>10.2f} {r['dp_per_joint'] or 0:>8.1f}")
    k = args.joint_max_partners
    print(f"{args.hours:g} h, regions {args.regions}, planning {args.planning}"
          + (f", at most {k} partner{'s' if k > 1 else ''}" if args.planning == "joint" and k else ""))
    print(f"fitted growth exponents (y = a N^b over {', '.join(str(r['sats']) for r in rows)}): {fit}")
    return 0


if __name__ == "__main__":
    if sys.argv[1:2] == ["_counted_run"]:
        sys.exit(_counted_run(sys.argv[2], sys.argv[3:]))
    sys.exit(main())
