"""`constellation command --out RUN SAT mode safe|nominal`: a mode command to one satellite of a
running ROS run (bringup/cli/operator.py; sat_node/operations/commands.py).

Checked by tests/unit/test_operator_requests.py.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from bringup.cli.operator import say_answer, send_request


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", type=Path, required=True, help="the running run's folder (constellation run --out)")
    p.add_argument("sat", help="the satellite, e.g. sat_12")
    p.add_argument("what", choices=["mode"], help="what to command (mode)")
    p.add_argument("value", choices=["safe", "nominal"], help="the mode")
    p.add_argument("--wait-s", type=float, default=120.0, help="wait this long for the run's answer [s]")


def run(args: argparse.Namespace) -> int:
    say_answer("command", send_request(args.out, {"request": "mode", "sat": args.sat, "mode": args.value},
                                       wait_s=args.wait_s))
    return 0
