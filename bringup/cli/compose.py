"""`constellation compose`: write a Docker Compose file (with its run spec, world and keys) for N satellites.

See bringup/deploy/compose.py for what the file holds and docker/README.md for how to run it
(`docker compose`, `podman-compose`, or `constellation containers up`).

Checked by tests/unit/test_docker_files.py and tests/containers/test_container_run.py.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from bringup.analysis.report import RunMeta
from bringup.cli.common import add_key_args, add_scenario_args, keys_from_args
from bringup.cli.run import parse_cut
from bringup.deploy.compose import IMAGE, compose_project, repo_root, write_project
from bringup.errors import UserError
from bringup.scenario.provenance import provenance


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_scenario_args(p, sets=False)
    p.add_argument("--mode", default="distributed", choices=["distributed", "centralized", "nonagile"],
                   help="scheduling mode (default: distributed)")
    p.add_argument("--out", type=Path, default=Path("docker-compose.yml"),
                   help="compose file to write; run_spec.json and world.pkl go beside it (default: ./docker-compose.yml)")
    p.add_argument("--name", default=None, help="compose project name (default: <scenario>-<mode>-<N>sats)")
    p.add_argument("--domain-id", type=int, default=7, help="ROS_DOMAIN_ID of every service, 0..232 (default: 7)")
    p.add_argument("--subnet", default="10.231.0.0/24",
                   help="IPv4 subnet of the compose network; fixed service addresses come from it")
    p.add_argument("--image", default=IMAGE, help=f"image of every service (default: {IMAGE})")
    p.add_argument("--restart", type=int, default=0, metavar="N",
                   help="restart policy on-failure:N for every service; processes checkpoint every step and a "
                        "restarted one resumes (default 0: a crash ends the run)")
    p.add_argument("--real-time-factor", type=float, default=None,
                   help="pace the clock at this many sim seconds per wall second (default: as fast as possible)")
    p.add_argument("--isl-delay-s", type=float, default=0.0, help="extra one-way ISL delay [s] added by the router")
    p.add_argument("--cut", action="append", default=[], metavar="A-B@T1-T2",
                   help="cut the ISL between satellites A and B from T1 to T2 [s] (repeatable)")
    p.add_argument("--factory", default=None,
                   help="participant factory 'module:function' (default: the ROS engine's, "
                        "bringup.engine.ros.factory:build)")
    add_key_args(p)
    p.add_argument("--context", type=Path, default=None,
                   help="repository root to build the image from (default: this checkout)")


def run(args: argparse.Namespace) -> int:
    if getattr(args, "regions", None) is not None:
        raise UserError("--regions: compose takes the scenario's regions only (put regions.geojson_file or "
                        "bbox_deg in the scenario file)")
    context = (args.context or repo_root()).resolve()
    if not (context / "docker" / "Dockerfile").is_file() or not (context / "pyproject.toml").is_file():
        raise UserError(f"--context {context}: no docker/Dockerfile and pyproject.toml there")
    cuts = [parse_cut(c) for c in args.cut]
    router_kw = {"extra_delay_s": args.isl_delay_s, "cuts": cuts} if (args.isl_delay_s or cuts) else None
    out = args.out.resolve()

    def meta(world, mode: str) -> dict:  # the one path `run` takes too: the same report keys and provenance
        m = RunMeta.for_world(world, mode, "ros")
        m.provenance = provenance(world.scenario, getattr(args, "_argv", None))
        return m.__dict__

    project = compose_project(scenario=args.scenario, sats=args.sats, hours=args.hours, seed=args.seed,
                              mode=args.mode, domain_id=args.domain_id, subnet=args.subnet,
                              factory=args.factory, build_context=os.path.relpath(context, out.parent),
                              project_name=args.name, image=args.image, restart=args.restart, router_kw=router_kw,
                              meta=meta, real_time_factor=args.real_time_factor, keys=keys_from_args(args))
    for a, b, _, _ in cuts:
        for n in (a, b):
            if n not in project.world.sat_names:
                raise UserError(f"--cut: {n!r} is not a satellite of the scenario ({project.world.sat_names[0]}..)")
    for path in write_project(project, out):
        print(path)
    return 0
