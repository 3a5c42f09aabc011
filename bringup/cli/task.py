"""`constellation task --out RUN --lat .. --lon .. --priority P --by ISO [--sat NAME]`: a tasking
request to a running ROS run (bringup/cli/operator.py; sat_node/operations/tasking.py).

Checked by tests/system/test_operator_live.py.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from bringup.cli.operator import say_answer, send_request


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", type=Path, required=True, help="the running run's folder (constellation run --out)")
    p.add_argument("--lat", type=float, required=True, help="target latitude [deg]")
    p.add_argument("--lon", type=float, required=True, help="target longitude [deg]")
    p.add_argument("--priority", type=int, default=1, help="1 (most urgent) .. 3 (default 1)")
    p.add_argument("--by", required=True, help="deadline, UTC ISO 8601 ending in Z (e.g. 2000-01-01T12:30:00Z)")
    p.add_argument("--sat", default="all", help="the satellite to task (default: all)")
    p.add_argument("--wait-s", type=float, default=120.0, help="wait this long for the run's answer [s]")


def run(args: argparse.Namespace) -> int:
    req = {"request": "task", "sat": args.sat, "lat_deg": args.lat, "lon_deg": args.lon,
           "priority": args.priority, "by": args.by}
    say_answer("task", send_request(args.out, req, wait_s=args.wait_s))
    return 0
