"""The ``constellation`` command line (docs/design.md section 6).

Each subcommand lives in its own module ``bringup/cli/<name>.py`` exposing::

    def add_arguments(p: argparse.ArgumentParser) -> None
    def run(args: argparse.Namespace) -> int   # exit code

The registry below names every subcommand of the contract with its help line. One whose module is missing still shows
in the help and fails loudly when called. Errors the user can fix (bad scenario, missing bag, bad
file) are raised as :class:`bringup.errors.UserError` (or ScenarioError) and printed as one line
``constellation <cmd>: error: ...`` with exit code 2; ``constellation --version`` prints the project's
version (bringup/scenario/provenance.py), no traceback; so are a number option that is
not finite (``--hours inf``: checked here for every command), an OSError (a full disk, an unwritable
folder: :func:`bringup.errors.os_error_line` names it and the file) and running out of memory.

Checked by tests/unit/test_cli_exit.py (exit codes, one-line errors, the fast exit),
tests/faults/test_hostile_inputs.py (every class of bad input: one line, exit 2) and
tests/unit/test_docker_files.py (every compose service's command parses).
"""

from __future__ import annotations

import argparse
import atexit
import importlib
import math
import sys
from collections.abc import Iterable

from bringup.errors import UserError, os_error_line
from bringup.process_end import exit_now
from bringup.scenario.config import ScenarioError
from bringup.scenario.provenance import version
from bringup.stop_signals import exit_code, signal_name

# subcommand name -> (module under bringup.cli, one line for `constellation --help`). Only the
# chosen command's module is imported: each imports what it needs at its top, and `--help` or one
# command does not pay for the others' (all of them: rclpy, matplotlib, numba, scipy, ~0.5 s).
COMMANDS: dict[str, tuple[str, str]] = {
    "run": ("run",
            "run a scenario (ROS 2 processes or the local engine), record an MCAP bag, write the report"),
    "constellation": ("constellation",
                      "print the constellation's orbital elements at epoch (Walker pattern, SGP4 mean elements)"),
    "access": ("access",
               "list GP access windows (off-nadir <= field of regard) of every satellite over the horizon"),
    "contacts": ("contacts",
                 "write the contact plan (ISL + ground passes) as the study's CSV, ION ionrc lines or HDTN JSON"),
    "bench-scheduler": ("bench_scheduler",
                        "benchmark the onboard DP scheduler: runtime over the horizon and value against the MILP optimum"),
    "dtn": ("dtn",
            "run the DTN alone (BPv7 agents, CGR, the ISL medium) on a contact plan and traffic; print dtn.* figures"),
    "report": ("report", "rebuild report.json from a run's MCAP bag alone"),
    "ops": ("ops", "the operations dictionary (commands, events, telemetry) and a run's event log"),
    "task": ("task", "task a running ROS run (--live-commands): image lat, lon with priority P before a deadline"),
    "command": ("command", "command a satellite of a running ROS run (--live-commands): mode safe|nominal"),
    "replay": ("replay",
               "republish a recorded bag (raw CDR, with /clock) onto a live ROS 2 graph at a chosen rate"),
    "bag-info": ("bag_info", "print a recorded bag's topics, message types, counts and time span"),
    "czml": ("czml", "the run on a globe: a CZML document of a bag and a CesiumJS page to view it"),
    "compare": ("compare",
                "run distributed, centralized and non-agile on the same scenario and seeds; Table 2 with ratios"),
    "sweep": ("sweep",
              "the figures over a grid of any scenario keys x seeds (--grid; resumable; CSV, JSON with 95 %% CIs, "
              "plots), or the named presets"),
    "node": ("node",
             "run one process of a ROS-engine run (the clock or one participant group) from a run spec"),
    "compose": ("compose",
                "write docker-compose.yml (+ run_spec.json, world.pkl beside it): one container per process of a run"),
    "bundles": ("bundles",
                "exchange BPv7 bundle files with another DTN node: send FILES / listen --out DIR over TCPCLv4, TCPCLv3 or UDP"),
    "aeossp": ("aeossp",
               "AstroReason-Bench aeossp_standard: solve a case (DP onboard/central, greedy) or check a solution"),
    "containers": ("containers",
                   "container images and runs with podman: build, up COMPOSE (run to the end), down, ls"),
}


def _load(module: str):
    try:
        return importlib.import_module(f"bringup.cli.{module}")
    except ModuleNotFoundError as exc:
        if exc.name == f"bringup.cli.{module}":
            return None
        raise


def build_parser(load: Iterable[str] | None = None) -> argparse.ArgumentParser:
    """The parser; the arguments of the commands in ``load`` (default: every command), the others by
    name and help line only."""
    parser = argparse.ArgumentParser(
        prog="constellation",
        description="Agile Earth-observing constellation with onboard scheduling over DTN (ROS 2 Jazzy).",
    )
    parser.add_argument("--version", action="version", version=f"constellation {version()}",
                        help="print the version and exit")
    wanted = set(COMMANDS) if load is None else set(load)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, (module, help_line) in COMMANDS.items():
        mod = _load(module) if name in wanted else None
        if mod is None and name in wanted:
            p = sub.add_parser(name, help="(not implemented yet)")
            p.set_defaults(_run=_not_implemented(name))
            continue
        p = sub.add_parser(name, help=help_line, description=help_line)
        if mod is not None:
            mod.add_arguments(p)
            p.set_defaults(_run=mod.run, _fast_exit=getattr(mod, "FAST_EXIT", False))
    return parser


def _not_implemented(name: str):
    def run(args: argparse.Namespace) -> int:
        raise UserError(f"'{name}' is not implemented yet")

    return run


_fast_exit = False  # the last command that returned 0 said it left no file open (FAST_EXIT)


_PACKAGES = ("bringup", "msgs_json", "orbit_clock", "sat_node", "dtn_router", "ground_station")


def _project_error(exc: BaseException) -> bool:
    """An error class the project defines (a ValueError subclass raised for bad input), not a
    ValueError of Python or a library (a bug: its traceback is kept)."""
    return type(exc).__module__.split(".")[0] in _PACKAGES


def _non_finite(args: argparse.Namespace) -> str | None:
    """The first option holding a number that is not finite (nan, inf: float() accepts them, no
    command can use them), as one phrase; None if all are finite."""
    for k, v in vars(args).items():
        for x in (v if isinstance(v, (list, tuple)) else [v]):
            if isinstance(x, float) and not math.isfinite(x):
                return f"--{k.replace('_', '-')} {x}: must be a finite number"
    return None


def main(argv: list[str] | None = None) -> int:
    global _fast_exit
    _fast_exit = False
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser(argv[:1] if argv[:1] and argv[0] in COMMANDS else ())
    args = parser.parse_args(argv)
    args._argv = list(argv)  # the command line as typed: each output's provenance (command)
    if not getattr(args, "command", None):
        parser.print_help()
        return 2
    bad = _non_finite(args)
    if bad:
        print(f"constellation {args.command}: error: {bad}", file=sys.stderr)
        return 2
    try:
        code = int(args._run(args) or 0)
        _fast_exit = code == 0 and getattr(args, "_fast_exit", False)
        return code
    except (UserError, ScenarioError) as exc:
        print(f"constellation {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except ValueError as exc:
        if not _project_error(exc):
            raise
        # the project's own errors about its inputs (OsseError, SlewModelError, ContactPlanError,
        # PropagationError, ...): ValueErrors whose message names what is wrong and where
        print(f"constellation {args.command}: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:  # (Ctrl-C, or a stop signal a command turned into one: stop_signals.py)
        sig = getattr(exc, "signum", None)
        print(f"constellation {args.command}: interrupted" + (f" by {signal_name(sig)}" if sig else ""),
              file=sys.stderr)
        return exit_code(exc)
    except BrokenPipeError:
        return 0
    except OSError as exc:  # a full disk, an unwritable folder: named, with the file
        print(f"constellation {args.command}: error: {os_error_line(exc)}", file=sys.stderr)
        return 2
    except MemoryError:
        print(f"constellation {args.command}: error: out of memory", file=sys.stderr)
        return 2


def entry() -> None:
    """The console script: ``main()``, then exit with its code. After a command whose module sets
    ``FAST_EXIT = True`` (it closes every file it writes before returning: ``run``, ``dtn``) succeeded, the
    process leaves with ``os._exit`` once the atexit handlers have run and stdout/stderr are
    flushed: the interpreter's teardown after numba kernels were loaded (LLVM's) takes ~0.3-0.4 s
    and would only free memory. Not under a profiler or tracer (they write their results then)."""
    code = main()
    if _fast_exit and sys.getprofile() is None and sys.gettrace() is None:  # (profilers, coverage: their
        # results are written at interpreter exit)
        atexit._run_exitfuncs()
        exit_now(code)
    sys.exit(code)


if __name__ == "__main__":
    entry()
