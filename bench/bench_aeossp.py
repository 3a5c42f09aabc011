"""Benchmark: the scheduler on AstroReason-Bench ``aeossp_standard`` cases, scored by our own check.

Usage::

    nice .venv/bin/python bench/bench_aeossp.py CASES_ROOT [--split train] [--modes greedy,onboard,central]
        [--cases case_0001,...] [--time-limit 300] [--ablate] [--json OUT.json]
        [--external NAME --external-cmd 'CMD {case} {out}' --external-solution solution.json]

``CASES_ROOT`` is the benchmark's ``dataset/cases`` folder (a checkout of github.com/Mtrya/astro-reason,
not part of this repository). Develop on ``train`` only: the ``test*`` splits are held out.

For every case of the split and every mode (``greedy``: the greedy-by-weight baseline; ``onboard``:
the DP per satellite by rank with its neighbours' announced plans; ``central``: the onboard plans
improved by the joint assignment search, each satellite's part its DP), one plan in this process (bringup/benchmarks/aeossp/planner.py), then our
check (bringup/benchmarks/aeossp/check.py): validity, WCR, CR, TAT [s], PC [Wh], wall and CPU
seconds of planning (reading the case and its orbits, shared by our modes, printed apart as
``prep``), and the load average before the plan. With
``--ablate``: ``central`` again with the slew rule off and with the battery rule off (planned and
checked without it): the WCR each rule costs. Means per mode at the end; ``onboard/central`` is
the mean ratio of WCR case by case.

With ``--external``: before our modes on each case, another solver (e.g. the benchmark's own MWIS
baseline in its own virtual environment) runs as a subprocess, ``{case}`` and ``{out}`` (a fresh
folder) substituted in ``--external-cmd``; its solution (``{out}/<--external-solution>``) is scored
by the same check, its wall and CPU seconds (the subprocess and its children) measured the same way:
the two solvers alternate case by case in one session.

Nothing is asserted here; wall times on a shared machine are read with the load column.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shlex
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from bringup.benchmarks.aeossp.case import read_case, read_solution, write_solution
from bringup.benchmarks.aeossp.check import check
from bringup.benchmarks.aeossp.geometry import Orbits
from bringup.benchmarks.aeossp.planner import plan


def _external(a, case_dir: Path):
    """Run the external solver on one case: (its actions, wall s, CPU s of it and its children)."""
    case = read_case(case_dir)
    with tempfile.TemporaryDirectory(prefix="bench_aeossp_") as out:
        cmd = [part.format(case=str(case_dir), out=out) for part in shlex.split(a.external_cmd)]
        r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.monotonic()
        done = subprocess.run(cmd, check=False, capture_output=True, text=True)
        wall = time.monotonic() - t0
        r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        if done.returncode != 0:
            raise SystemExit(f"bench_aeossp: {a.external} failed on {case_dir} (exit {done.returncode}): "
                             f"{done.stderr.strip().splitlines()[-1:] or ''}")
        acts = read_solution(Path(out) / a.external_solution, case)
    return acts, wall, (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("root", help="the benchmark's dataset/cases folder")
    ap.add_argument("--split", default="train")
    ap.add_argument("--modes", default="greedy,onboard,central")
    ap.add_argument("--cases", default="", help="comma-separated case ids (default: all of the split)")
    ap.add_argument("--time-limit", type=float, default=300.0)
    ap.add_argument("--ablate", action="store_true", help="also central without the slew rule, without the battery")
    ap.add_argument("--json", default="", help="write every row as JSON here")
    ap.add_argument("--external", default="", help="name of another solver to run side by side")
    ap.add_argument("--external-cmd", default="", help="its command line, with {case} and {out}")
    ap.add_argument("--external-solution", default="solution.json", help="its solution file inside {out}")
    ap.add_argument("--keep", default="", help="write every solution here as SPLIT_CASE_MODE.json (for the "
                    "benchmark's own verifier)")
    a = ap.parse_args(argv)
    split = Path(a.root) / a.split
    if not split.is_dir():
        print(f"bench_aeossp: {split}: no such split folder", file=sys.stderr)
        return 2
    names = a.cases.split(",") if a.cases else sorted(p.name for p in split.iterdir() if p.is_dir())
    if bool(a.external) != bool(a.external_cmd):
        print("bench_aeossp: --external and --external-cmd go together", file=sys.stderr)
        return 2
    runs = [(m, True, True) for m in a.modes.split(",") if m]
    if a.ablate:
        runs += [("central", False, True), ("central", True, False)]
    rows = []
    print(f"{'case':10} {'mode':16} {'sats':>4} {'tasks':>5} {'valid':>5} {'WCR':>6} {'CR':>6} {'TAT_s':>7} "
          f"{'PC_Wh':>8} {'wall_s':>7} {'cpu_s':>7} {'load':>5}")
    for name in names:
        t0, c0 = time.monotonic(), time.process_time()
        case = read_case(split / name)
        orbits = Orbits(case.satellites, case.mission.start)
        # reading the case and setting up its orbits: once per case, shared by our modes (an end-to-end
        # wall of one of our modes is prep_wall_s + its wall_s; the external solver's wall is end to end)
        prep_wall, prep_cpu = time.monotonic() - t0, time.process_time() - c0
        for mode, slew, batt in ([(a.external, True, True)] if a.external else []) + runs:
            label = mode + ("" if slew else "-noslew") + ("" if batt else "-nobatt")
            load = os.getloadavg()[0]
            if mode == a.external:
                acts, wall, cpu = _external(a, split / name)
            else:
                t0, c0 = time.monotonic(), time.process_time()
                acts = plan(case, mode, a.time_limit, orbits, slew=slew, battery_rule=batt)
                wall, cpu = time.monotonic() - t0, time.process_time() - c0
            r = check(case, acts, orbits, slew=slew, battery_rule=batt)
            m = r.metrics
            row = {"case": name, "mode": label, "sats": len(case.satellites), "tasks": len(case.tasks),
                   "valid": r.valid, **m, "wall_s": wall, "cpu_s": cpu, "load": load, "actions": len(acts),
                   "prep_wall_s": 0.0 if mode == a.external else prep_wall,
                   "prep_cpu_s": 0.0 if mode == a.external else prep_cpu}
            if a.keep:
                Path(a.keep).mkdir(parents=True, exist_ok=True)
                write_solution(Path(a.keep) / f"{a.split}_{name}_{label}.json", case, acts)
            rows.append(row)
            tat = f"{m['TAT']:7.0f}" if m["TAT"] is not None else "      -"
            print(f"{name:10} {label:16} {row['sats']:4d} {row['tasks']:5d} {r.valid!s:>5} {m['WCR']:6.3f} "
                  f"{m['CR']:6.3f} {tat} {m['PC']:8.0f} {wall:7.1f} {cpu:7.1f} {load:5.1f}", flush=True)
    print("\nmeans over cases:")
    for label in dict.fromkeys(r["mode"] for r in rows):
        rs = [r for r in rows if r["mode"] == label]

        def mean(k, rs=rs):
            return statistics.fmean(r[k] for r in rs if r[k] is not None)
        print(f"  {label:16} n={len(rs)} valid={sum(r['valid'] for r in rs)} WCR={mean('WCR'):.3f} "
              f"CR={mean('CR'):.3f} TAT={mean('TAT'):.0f} s PC={mean('PC'):.0f} Wh wall={mean('wall_s'):.1f} s "
              f"cpu={mean('cpu_s'):.1f} s, +{mean('prep_wall_s'):.1f} s wall reading the case")
    by = {(r["case"], r["mode"]): r for r in rows}
    pairs = [(by[(c, "onboard")]["WCR"], by[(c, "central")]["WCR"]) for c in names
             if (c, "onboard") in by and (c, "central") in by and by[(c, "central")]["WCR"] > 0]
    if pairs:
        print(f"  onboard/central WCR: {statistics.fmean(o / c for o, c in pairs):.4f} (mean of per-case ratios)")
    if a.json:
        Path(a.json).write_text(json.dumps(rows, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
