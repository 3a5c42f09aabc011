"""`constellation node --run-spec FILE --role ROLE`: one process of a ROS-engine run.

The launcher (bringup/engine/ros/launcher.py) and the compose files (bringup/deploy/compose.py)
start every process with it: role ``clock`` runs the lockstep clock and recorder
(bringup/engine/ros/clock_node.py) and, when the spec names ``extra.report_dir`` (a container
run), writes report.json / report.md there from the bag once it is closed; any other role hosts
the participants the run spec's factory returns for it (bringup/engine/ros/host.py; its nodes
named, parametrised and shown live as the spec says: namespace, ros_args, the run settings). With the
spec's ``state_dir`` a host checkpoints every step and, started again after a crash, resumes from
its checkpoint (bringup/engine/checkpoint.py).
A process started by a launcher ends with it (bringup/engine/ros/lifeline.py).
Before a host says hello (ready) it runs the spec's prepare hook for its role (e.g. loads the
numba kernels its participants use) and waits until the run's lifecycle manager has configured
and activated its nodes (bringup/engine/ros/host_lifecycle.py); ``--prepare`` runs the hook once for the whole run, as the
launcher does before it starts any process.

Checked by tests/ros/test_launcher.py (launched runs of toy participants) and
tests/system/test_engines_equal.py.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from bringup.engine.ros.lifeline import hold
from bringup.engine.ros.profiling import start as start_profile
from bringup.engine.ros.run_spec import CLOCK_ROLE, RunSpec, load_factory
from bringup.errors import UserError


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--run-spec", type=Path, required=True, help="run spec JSON written by the launcher")
    p.add_argument("--role", help=f"'{CLOCK_ROLE}' or one of the run spec's roles")
    p.add_argument("--prepare", action="store_true",
                   help="only run the spec's prepare hook for the whole run (the launcher does, before any process)")


def _write_report(spec: RunSpec, rc: int) -> None:
    """After a complete run: ``report.json`` and ``report.md`` rebuilt from the bag (as `constellation
    report BAG` does) into the spec's ``extra.report_dir`` (a container's run folder)."""
    if rc != 0 or not spec.bag_dir:
        return
    from bringup.analysis.report import report_from_bag
    from bringup.analysis.report_md import report_md
    from bringup.cli.run_folder import json_text, write_text_atomic

    out = Path(spec.extra["report_dir"])
    rep = report_from_bag(Path(spec.bag_dir), warn=lambda line: print(f"clock: warning: {line}", file=sys.stderr))
    write_text_atomic(out / "report.md", report_md(rep, [], base=out))
    write_text_atomic(out / "report.json", json_text(rep, indent=2, sort_keys=True) + "\n")


def run(args: argparse.Namespace) -> int:
    # started by a launcher: die with it (bringup/engine/ros/lifeline.py)
    hold(args.role or "prepare")
    spec = RunSpec.from_file(args.run_spec)
    if args.prepare:
        if args.role is not None:
            raise UserError("--prepare readies the whole run: give no --role")
        _prepare(spec, None)
        return 0
    if args.role is None:
        raise UserError("give --role (or --prepare)")
    start_profile(args.role)  # only with AGILE_DTN_PROFILE_DIR set (bringup/engine/ros/profiling.py)
    # each process imports only its side (a host never loads the recorder, the clock no participant)
    if args.role == CLOCK_ROLE:
        from bringup.engine.ros.clock_node import run_clock

        report = spec.extra.get("report_dir")
        return run_clock(spec, on_closed=(lambda rc: _write_report(spec, rc)) if report else None)
    if args.role not in spec.roles:
        raise UserError(f"--role {args.role!r} is not in the run spec's roles {spec.roles}")
    from bringup.engine.ros.host import run_host

    participants = load_factory(spec.factory)(spec, args.role)
    if not participants:
        raise UserError(f"participant factory {spec.factory} returned no participants for role {args.role}")
    # ready = participants built and what they need loaded (the hello run_host sends first)
    _prepare(spec, args.role)

    idle = max(300.0, 10 * spec.ack_timeout_s, 2 * spec.restart_wait_s)
    bounded = spec.startup_timeout_s is not None
    # an unbounded start: this host waits for step 0 as long as the clock waits for the others
    return run_host(args.role, participants, run_key=spec.keys().run, ack_timeout_s=spec.ack_timeout_s,
                    startup_timeout_s=spec.startup_timeout_s if bounded else 60.0,
                    idle_timeout_s=idle, first_step_timeout_s=idle if bounded else None,
                    state_path=str(Path(spec.state_dir) / f"{args.role}.state.sqlite") if spec.state_dir else None,
                    namespace=spec.namespace, ros_args=spec.ros_args, epoch_ns=spec.epoch_ns(),
                    parameters=lambda name: spec.parameters(name, process=args.role), live_period_s=spec.live_period_s())


def _prepare(spec: RunSpec, role: str | None) -> None:
    """The spec's prepare hook for ``role`` (None: the whole run), its time on stderr (the log)."""
    if spec.prepare is None:
        return
    t0 = time.perf_counter()
    load_factory(spec.prepare)(spec, role)
    print(f"node {role or 'prepare'}: ready ({spec.prepare} took {time.perf_counter() - t0:.2f} s)",
          file=sys.stderr, flush=True)
