"""`constellation containers build|up|down|ls`: the images and a compose project, driven with podman.

``build``: the base image from Debian packages (when missing) and the project image
(bringup/deploy/images.py). ``up COMPOSE``: run a `constellation compose` project to its end, one
container per process, optionally with a network impairment on every container
(bringup/deploy/impair.py), copy the run folder out (bag, report.json, report.md) and remove the
project's containers, network and volume (bringup/deploy/containers.py). ``down [PROJECT]``: remove
what a project (or every project, ``--all``) left. ``ls``: what is there.

Checked by tests/containers/test_container_run.py (``up`` of a 12-satellite run equals the local
engine; a run that cannot start leaves nothing).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from bringup.cli.run import _progress_display
from bringup.deploy.containers import ContainerRun, down, leftovers
from bringup.deploy.images import BASE_IMAGE, IMAGE, build_all
from bringup.deploy.impair import parse_impairment
from bringup.errors import UserError

HELP = "container images and runs with podman: build, up COMPOSE (run to the end), down, ls"


def add_arguments(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="action", metavar="ACTION", required=True,
                           help="build: the images; up COMPOSE: run to the end; down PROJECT: remove what a run left; ls")
    b = sub.add_parser("build", help="build the base image (debootstrap, when missing) and the project image")
    b.add_argument("--image", default=IMAGE, help=f"tag of the project image (default {IMAGE})")
    b.add_argument("--base", default=BASE_IMAGE,
                   help=f"base image; built from Debian packages when it is {BASE_IMAGE} and missing")
    b.add_argument("--rebuild-base", action="store_true", help="debootstrap the base again")
    b.add_argument("--online", action="store_true",
                   help="let the build reach the package index (default: offline, from the host-built wheelhouse)")
    u = sub.add_parser("up", help="run a compose project to its end with podman; results to --out")
    u.add_argument("compose", type=Path, help="docker-compose.yml written by `constellation compose`")
    u.add_argument("--out", type=Path, default=None, help="copy the run folder here (default: beside the compose file)")
    u.add_argument("--impair", default=None, metavar="SPEC",
                   help="network impairment on every container, e.g. delay=50ms,jitter=10ms,loss=1%%[,rate=10mbit]")
    u.add_argument("--seed", type=int, default=0, help="seed of the impairment's random draws")
    u.add_argument("--timeout", type=float, default=3600.0, help="wall seconds before the run is stopped")
    u.add_argument("--keep", action="store_true", help="leave the containers, network and volume (then `down`)")
    u.add_argument("--no-progress", action="store_true")
    d = sub.add_parser("down", help="remove a project's containers, network and volume")
    d.add_argument("project", nargs="?", default=None, help="project name (the compose file's 'name')")
    d.add_argument("--all", action="store_true", help="every project this command made")
    d.add_argument("--keep-volumes", action="store_true")
    sub.add_parser("ls", help="containers, networks and volumes of every project")


def run(args: argparse.Namespace) -> int:
    if args.action == "build":
        t = build_all(image=args.image, base=args.base, rebuild_base=args.rebuild_base, online=args.online,
                      log=lambda m: print(f"containers build: {m}", file=sys.stderr))
        print(json.dumps({"image": args.image, "base": args.base, **t.__dict__}))
        return 0
    if args.action == "ls":
        print(json.dumps(leftovers(None), indent=2))
        return 0
    if args.action == "down":
        if not args.project and not args.all:
            raise UserError("down: name a project or pass --all")
        removed = down(None if args.all else args.project, volumes=not args.keep_volumes)
        print(json.dumps(removed))
        return 0
    return _up(args)


def _up(args: argparse.Namespace) -> int:
    try:
        imp = parse_impairment(args.impair) if args.impair else None
    except ValueError as exc:
        raise UserError(str(exc)) from None
    cr = ContainerRun(args.compose, impair=imp, seed=args.seed)
    out = (args.out or args.compose.resolve().parent / cr.project).resolve()
    if out.exists():
        raise UserError(f"--out {out} exists: name a new folder for the run")
    say = lambda m: print(f"containers up: {m}", file=sys.stderr)
    say(f"project {cr.project}: {len(cr.containers)} containers on internal network {cr.network} ({cr.subnet})"
        + (f", impairment {imp} on every container" if imp else ""))
    prog = None
    update = None
    if not args.no_progress:
        sc_h = json.loads((args.compose.resolve().parent / "run_spec.json").read_text())
        prog, update = _progress_display(True, int(sc_h["extra"]["meta"]["horizon_s"] * 1e9))
    try:
        cr.up()
        if prog is not None:
            prog.start()

        def progress(body: dict) -> None:
            if update is not None:
                wall = float(body.get("wall_s") or 0)
                rtf = body["t_ns"] / 1e9 / wall if wall > 0 else None
                extra = f"{body.get('steps', 0):,} steps"
                if body.get("in_flight") is not None:
                    extra += f", {body['in_flight']} bundles in flight"
                update(t_ns=int(body["t_ns"]), rtf=rtf, extra=extra)

        res = cr.wait(timeout_s=args.timeout, progress=progress)
        if prog is not None:
            prog.stop()
            prog = None
        if res.returncode == 0:
            cr.copy_out(out)
        say(f"{'done' if res.ok else 'FAILED'} in {res.wall_s:.1f} s; restarts {res.restarts or 'none'}"
            + (f"; lingered {res.lingered}" if res.lingered else "") + (f": {res.message}" if res.message else ""))
        for svc, runs in sorted(res.impair_stats.items()):
            for st in runs:
                say(f"impairment {svc}: {st['packets']} packets, {st['dropped']} dropped, "
                    f"mean delay {1e3 * (st['mean_delay_s'] or 0):.1f} ms, {st['overruns']} overruns")
        if res.returncode == 0:
            say(f"run folder: {out}")
        return 0 if res.ok else (res.returncode or 1)
    finally:
        if prog is not None:
            prog.stop()
        if not args.keep:
            cr.down()
