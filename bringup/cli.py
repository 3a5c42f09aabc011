"""The ``constellation`` command line (DESIGN.md section 6).

Each subcommand lives in its own module ``bringup/commands/<name>.py`` exposing::

    HELP: str                                  # one line for `constellation --help`
    def add_arguments(p: argparse.ArgumentParser) -> None
    def run(args: argparse.Namespace) -> int   # exit code

The registry below names every subcommand of the contract. One whose module is missing still shows
in the help and fails loudly when called. Errors the user can fix (bad scenario, missing bag, bad
file) are raised as :class:`bringup.errors.UserError` (or ScenarioError) and printed as one line
``constellation <cmd>: error: ...`` with exit code 2, no traceback.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from bringup.errors import UserError
from bringup.scenario import ScenarioError

# subcommand name -> module under bringup.commands
COMMANDS: dict[str, str] = {
    "run": "run",
    "constellation": "constellation",
    "access": "access",
    "contacts": "contacts",
    "bench-scheduler": "bench_scheduler",
    "dtn": "dtn",
    "report": "report",
    "replay": "replay",
    "bag-info": "bag_info",
    "compare": "compare",
    "sweep": "sweep",
    "node": "node",
    "compose": "compose",
}


def _load(module: str):
    try:
        return importlib.import_module(f"bringup.commands.{module}")
    except ModuleNotFoundError as exc:
        if exc.name == f"bringup.commands.{module}":
            return None
        raise


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="constellation",
        description="Agile Earth-observing constellation with onboard scheduling over DTN (ROS 2 Jazzy).",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, module in COMMANDS.items():
        mod = _load(module)
        if mod is None:
            p = sub.add_parser(name, help="(not implemented yet)")
            p.set_defaults(_run=_not_implemented(name))
            continue
        p = sub.add_parser(name, help=mod.HELP, description=mod.HELP)
        mod.add_arguments(p)
        p.set_defaults(_run=mod.run)
    return parser


def _not_implemented(name: str):
    def run(args: argparse.Namespace) -> int:
        raise UserError(f"'{name}' is not implemented yet")

    return run


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "command", None):
        parser.print_help()
        return 2
    try:
        return int(args._run(args) or 0)
    except (UserError, ScenarioError) as exc:
        print(f"constellation {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"constellation {args.command}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return 0


if __name__ == "__main__":
    sys.exit(main())
