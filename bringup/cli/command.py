"""`constellation command --out RUN SAT mode safe|nominal` and `constellation command --out RUN SAT set
NAME VALUE`: a mode or parameter command to one satellite of a running ROS run (bringup/cli/operator.py;
sat_node/operations/commands.py: the settable parameters, ``SETTABLE``, with their types and bounds).

Checked by tests/unit/test_operator_requests.py.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from bringup.cli.operator import say_answer, send_request
from bringup.errors import UserError
from sat_node.operations.commands import SETTABLE


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", type=Path, required=True, help="the running run's folder (constellation run --out)")
    p.add_argument("sat", help="the satellite, e.g. sat_12")
    p.add_argument("what", choices=["mode", "set"], help="what to command: mode (safe or nominal) or set "
                   f"(a parameter: {', '.join(SETTABLE)})")
    p.add_argument("args", nargs="+", metavar="ARG", help="mode: safe|nominal; set: NAME VALUE")
    p.add_argument("--wait-s", type=float, default=120.0, help="wait this long for the run's answer [s]")


def request_of(sat: str, what: str, args: list[str]) -> dict:
    """The operator request for ``what`` with ``args`` (UserError, one line, when they do not fit)."""
    if what == "mode":
        if len(args) != 1 or args[0] not in ("safe", "nominal"):
            raise UserError(f"command mode: expected safe or nominal, got {' '.join(args)!r}")
        return {"request": "mode", "sat": sat, "mode": args[0]}
    if len(args) != 2:
        raise UserError(f"command set: expected NAME VALUE, got {' '.join(args)!r}")
    name, text = args
    if name not in SETTABLE:
        raise UserError(f"command set: {name!r} is not settable in flight (settable: {', '.join(SETTABLE)})")
    tp, lo, hi = SETTABLE[name]
    try:
        value = tp(text)
    except ValueError:
        raise UserError(f"command set {name}: {text!r} is not {'an integer' if tp is int else 'a number'}") from None
    if not lo <= value <= hi:
        raise UserError(f"command set {name}: {value:g} is outside [{lo}, {hi}]")
    return {"request": "set", "sat": sat, "name": name, "value": value}


def run(args: argparse.Namespace) -> int:
    req = request_of(args.sat, args.what, args.args)
    say_answer("command", send_request(args.out, req, wait_s=args.wait_s))
    return 0
