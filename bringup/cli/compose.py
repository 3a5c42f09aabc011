"""`constellation compose`: write a Docker Compose file (and its run spec) for N satellites.

See bringup/deploy/compose.py for what the file holds and docker/README.md for how to run it.

Checked by tests/unit/test_docker_files.py.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from bringup.cli.common import add_scenario_args
from bringup.deploy.compose import compose_project, repo_root, write_project
from bringup.errors import UserError


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_scenario_args(p)
    p.add_argument("--mode", default="distributed", choices=["distributed", "centralized", "nonagile"],
                   help="scheduling mode (default: distributed)")
    p.add_argument("--out", type=Path, default=Path("docker-compose.yml"),
                   help="compose file to write; run_spec.json goes beside it (default: ./docker-compose.yml)")
    p.add_argument("--domain-id", type=int, default=7, help="ROS_DOMAIN_ID of every service, 0..101 (default: 7)")
    p.add_argument("--subnet", default="10.231.0.0/24",
                   help="IPv4 subnet of the compose network; fixed service addresses come from it")
    p.add_argument("--factory", default=None,
                   help="participant factory 'module:function' (default: the ROS engine's)")
    p.add_argument("--context", type=Path, default=None,
                   help="repository root to build the image from (default: this checkout)")


def run(args: argparse.Namespace) -> int:
    context = (args.context or repo_root()).resolve()
    if not (context / "docker" / "Dockerfile").is_file() or not (context / "pyproject.toml").is_file():
        raise UserError(f"--context {context}: no docker/Dockerfile and pyproject.toml there")
    out = args.out.resolve()
    project = compose_project(scenario=args.scenario, sats=args.sats, hours=args.hours, seed=args.seed,
                              mode=args.mode, domain_id=args.domain_id, subnet=args.subnet,
                              factory=args.factory, build_context=os.path.relpath(context, out.parent))
    for path in write_project(project, out):
        print(path)
    return 0
