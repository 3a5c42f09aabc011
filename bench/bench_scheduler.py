"""Benchmark the onboard DP scheduler on the paper scenario (issue 3).

Runs ``constellation bench-scheduler`` logic (bringup/cli/bench_scheduler.py): one satellite
scheduled over the whole 6 h horizon (replanning every 10 min, all its passes) for the DP runtime,
and DP against the exact MILP on small instances cut from the scenario's passes for the value ratio.
Prints a summary, then the figures as one JSON object.

    .venv/bin/python bench/bench_scheduler.py [--scenario paper] [--sat sat_11] [--instances 8] [--json]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bringup.cli import bench_scheduler as bs
from bringup.cli.common import scenario_from_args
from bringup.cli.main import COMMANDS


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=COMMANDS["bench-scheduler"][1])
    bs.add_arguments(p)
    args = p.parse_args(argv)
    r = bs.run_benchmark(scenario_from_args(args), sat=args.sat, instances=args.instances, n_gps=args.milp_gps,
                         window_s=args.milp_window_s, time_limit_s=args.milp_time_limit_s)
    if not args.json:
        print(bs.format_summary(r))
        for row in r["milp_instances"]:
            print(f"    {row['sat']} t0={row['t0_s']:7.0f} s  vars={row['n_vars']:5d}  DP {row['dp']:7.1f}  "
                  f"MILP {row['milp']:7.1f}  ratio {row['dp'] / row['milp'] if row['milp'] else 1:.4f}  "
                  f"MILP {row['milp_s']:.2f} s")
    print(json.dumps({k: v for k, v in r.items() if k != "milp_instances"}, sort_keys=True))
    return 0


if __name__ == "__main__":
    sys.exit(main())
