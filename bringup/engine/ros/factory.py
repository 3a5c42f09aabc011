"""The ROS engine's participant factory for scenario runs.

A run spec (bringup/engine/ros/run_spec.py) names the factory every node process calls as
``"module:function"``; for a scenario run it is ``FACTORY`` here: ``build(spec, role)`` loads the
world pickle the launcher wrote (``spec.extra["world"]``) and returns the participants process
``role`` hosts (one, or several satellites: ``spec.groups``), made by
bringup/scenario/participants.py exactly as the local engine makes them, so both engines run the
same participants from the same inputs (tests/system/test_engines_equal.py); the satellites' BPSec
key comes from the run's keys file (bringup/engine/keys.py).

``PREPARE`` is the same runs' prepare hook: ``prepare(spec, role)`` compiles (cold numba cache) or
loads the numba kernels the role's participants use (bringup/scenario/participants.py kernels_for,
sat_node/kernels.py); the launcher calls it once before it starts the processes (role None), so they
load the kernels from the cache, and each process before it reports ready
(tests/system/test_cold_start.py).
"""

from __future__ import annotations

from pathlib import Path

from bringup.engine.ros.ground_gateway import gateway_for, report_at_finish
from bringup.engine.ros.run_spec import RunSpec
from bringup.errors import UserError
from bringup.scenario.participants import kernels_for, make_participant
from bringup.scenario.world import World
from sat_node.kernels import warm_up

__all__ = ["FACTORY", "PREPARE", "build", "prepare"]

FACTORY = "bringup.engine.ros.factory:build"
PREPARE = "bringup.engine.ros.factory:prepare"


def build(spec: RunSpec, role: str) -> list:
    """The participants process ``role`` hosts (``spec.members(role)``: one, or a group of
    satellites), in that order, built from one world (one contact graph for all of them)."""
    path = spec.extra.get("world")
    if not path:
        raise UserError("run spec: extra.world (path of the world pickle) is missing")
    world = World.load(Path(path), spec.extra.get("world_key"))
    store_dir = spec.extra.get("store_dir")
    keys = spec.keys()
    op_dir = spec.extra.get("operator_dir")  # live operator requests (constellation run --live-commands)
    live = (Path(op_dir), keys.run) if op_dir else None
    gw = gateway_for(spec.extra, spec.members(role))  # --ground-gateway (bringup/engine/ros/ground_gateway.py)
    parts = [make_participant(world, r, spec.mode, store_dir=Path(store_dir) if store_dir else None,
                              router_kw=spec.extra.get("router"), bpsec_key=keys.bpsec,
                              command_key=keys.command or None, live=live, **gw) for r in spec.members(role)]
    report_at_finish(parts, spec.extra)
    return parts


def prepare(spec: RunSpec, role: str | None) -> dict[str, float]:
    """The numba kernels the participants of process ``role`` use (None: the whole run's), compiled
    or loaded in this process; returns the seconds each kernel group took."""
    if role is None:
        which = kernels_for(spec.mode, None)
    else:
        which = tuple(dict.fromkeys(k for r in spec.members(role) for k in kernels_for(spec.mode, r)))
    return warm_up(which) if which else {}
