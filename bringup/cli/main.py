"""The ``constellation`` command line (DESIGN.md section 6).

Each subcommand lives in its own module ``bringup/cli/<name>.py`` exposing::

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
import os
import sys

from bringup.errors import UserError
from bringup.scenario.config import ScenarioError

# subcommand name -> module under bringup.cli
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
        return importlib.import_module(f"bringup.cli.{module}")
    except ModuleNotFoundError as exc:
        if exc.name == f"bringup.cli.{module}":
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
        p.set_defaults(_run=mod.run, _fast_exit=getattr(mod, "FAST_EXIT", False))
    return parser


def _not_implemented(name: str):
    def run(args: argparse.Namespace) -> int:
        raise UserError(f"'{name}' is not implemented yet")

    return run


_fast_exit = False  # the last command that returned 0 said it left no file open (FAST_EXIT)


def main(argv: list[str] | None = None) -> int:
    global _fast_exit
    _fast_exit = False
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "command", None):
        parser.print_help()
        return 2
    try:
        code = int(args._run(args) or 0)
        _fast_exit = code == 0 and getattr(args, "_fast_exit", False)
        return code
    except (UserError, ScenarioError) as exc:
        print(f"constellation {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"constellation {args.command}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return 0


def entry() -> None:
    """The console script: ``main()``, then exit with its code. After a command whose module sets
    ``FAST_EXIT = True`` (it closes every file it writes before returning: ``run``) succeeded, the
    process leaves with ``os._exit`` once the atexit handlers have run and stdout/stderr are
    flushed: the interpreter's teardown after numba kernels were loaded (LLVM's) takes ~0.3-0.4 s
    and would only free memory. Not under a profiler or tracer (they write their results then)."""
    code = main()
    if _fast_exit and sys.getprofile() is None and sys.gettrace() is None:  # (profilers, coverage: their
        # results are written at interpreter exit)
        import atexit

        atexit._run_exitfuncs()
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError):
                pass
        os._exit(code)
    sys.exit(code)


if __name__ == "__main__":
    entry()
