"""`constellation aeossp`: the scheduler on AstroReason-Bench ``aeossp_standard`` cases.

- ``aeossp solve CASE_DIR --out SOLUTION.json [--time-limit S] [--planning onboard|central|greedy]``
  plans the case (bringup/benchmarks/aeossp/planner.py), asserts the plan passes our own check and
  writes the benchmark's solution JSON; prints one JSON line of WCR, CR, TAT, PC and wall time.
- ``aeossp check CASE_DIR SOLUTION.json [--no-slew] [--no-battery]`` runs our own check
  (bringup/benchmarks/aeossp/check.py) and prints validity, the first violations and the metrics;
  exit 1 when the solution is invalid.

The user's page is docs/guide/aeossp.md. Checked by tests/unit/test_aeossp_planner.py (solve, check,
a bad case folder as one line with exit 2).
"""

from __future__ import annotations

import argparse
import json
import sys
import time

from bringup.benchmarks.aeossp.case import read_case, read_solution, write_solution
from bringup.benchmarks.aeossp.check import check
from bringup.benchmarks.aeossp.planner import plan
from bringup.errors import UserError


def add_arguments(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="action", metavar="ACTION", required=True,
                           help="solve CASE_DIR: plan and write a solution; check CASE_DIR SOLUTION: our own check")
    s = sub.add_parser("solve", help="plan a case and write the benchmark's solution JSON")
    s.add_argument("case_dir", help="the case folder (mission.yaml, satellites.yaml, tasks.yaml)")
    s.add_argument("--out", required=True, help="where to write the solution JSON")
    s.add_argument("--time-limit", type=float, default=300.0,
                   help="seconds the central planner may spend on its joint search (default 300)")
    s.add_argument("--planning", choices=("onboard", "central", "greedy"), default="central",
                   help="onboard: each satellite by rank with its neighbours' announced plans; central: one "
                        "planner for all (the joint assignment search); greedy: the greedy-by-weight baseline")
    c = sub.add_parser("check", help="check a solution with our own rules; print validity and metrics")
    c.add_argument("case_dir", help="the case folder")
    c.add_argument("solution", help="the solution JSON")
    c.add_argument("--no-slew", action="store_true", help="switch the slew+settle gap rule off")
    c.add_argument("--no-battery", action="store_true", help="switch the battery rule off")


def run(args: argparse.Namespace) -> int:
    case = read_case(args.case_dir)
    if args.action == "solve":
        if not args.time_limit > 0:
            raise UserError(f"--time-limit must be > 0, got {args.time_limit:g}")
        t0 = time.monotonic()
        cpu0 = time.process_time()
        acts = plan(case, args.planning, args.time_limit)
        wall, cpu = time.monotonic() - t0, time.process_time() - cpu0
        write_solution(args.out, case, acts)
        m = check(case, acts).metrics
        print(json.dumps({"case": case.mission.case_id, "planning": args.planning, "actions": len(acts), **m,
                          "wall_s": round(wall, 2), "cpu_s": round(cpu, 2), "out": str(args.out)}))
        return 0
    acts = read_solution(args.solution, case)
    r = check(case, acts, slew=not args.no_slew, battery_rule=not args.no_battery)
    print(json.dumps({"valid": r.valid, "violations": len(r.violations),
                      "first": [v.text for v in r.violations[:5]], **r.metrics}))
    if not r.valid:
        print(f"aeossp check: invalid: {r.violations[0].text}", file=sys.stderr)
    return 0 if r.valid else 1
