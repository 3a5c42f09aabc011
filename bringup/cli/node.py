"""`constellation node --run-spec FILE --role ROLE`: one process of a ROS-engine run.

The launcher (bringup/engine/ros/launcher.py), and later the docker compose files, start every process with
it: role ``clock`` runs the lockstep clock and recorder (bringup/engine/ros/clock_node.py); any other role
hosts the participants the run spec's factory returns for it (bringup/engine/ros/host.py). With the
spec's ``state_dir`` a host checkpoints every step and, started again after a crash, resumes from
its checkpoint (bringup/engine/checkpoint.py).

Checked by tests/ros/test_launcher.py (launched runs of toy participants) and
tests/system/test_engines_equal.py.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from bringup.engine.ros.clock_node import run_clock
from bringup.engine.ros.host import run_host
from bringup.engine.ros.run_spec import CLOCK_ROLE, RunSpec, load_factory
from bringup.errors import UserError


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--run-spec", type=Path, required=True, help="run spec JSON written by the launcher")
    p.add_argument("--role", required=True, help=f"'{CLOCK_ROLE}' or one of the run spec's roles")


def run(args: argparse.Namespace) -> int:
    spec = RunSpec.from_file(args.run_spec)
    if args.role == CLOCK_ROLE:
        return run_clock(spec)
    if args.role not in spec.roles:
        raise UserError(f"--role {args.role!r} is not in the run spec's roles {spec.roles}")
    participants = load_factory(spec.factory)(spec, args.role)
    if not participants:
        raise UserError(f"participant factory {spec.factory} returned no participants for role {args.role}")

    return run_host(args.role, participants, ack_timeout_s=spec.ack_timeout_s,
                    startup_timeout_s=spec.startup_timeout_s,
                    idle_timeout_s=max(300.0, 10 * spec.ack_timeout_s, 2 * spec.restart_wait_s),
                    state_path=str(Path(spec.state_dir) / f"{args.role}.state.sqlite") if spec.state_dir else None)
