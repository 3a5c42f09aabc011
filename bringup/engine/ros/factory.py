"""The ROS engine's participant factory for scenario runs.

A run spec (bringup/engine/ros/run_spec.py) names the factory every node process calls as
``"module:function"``; for a scenario run it is ``FACTORY`` here: ``build(spec, role)`` loads the
world pickle the launcher wrote (``spec.extra["world"]``) and returns the participants process
``role`` hosts (one, or several satellites: ``spec.groups``), each built when its node is
configured (bringup/engine/lifecycle.py Deferred), made by
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

from functools import partial
from pathlib import Path

from bringup.engine.lifecycle import Deferred
from bringup.engine.ros.ground_gateway import gateway_for, report_at_finish
from bringup.engine.ros.run_spec import RunSpec
from bringup.errors import UserError
from bringup.scenario.participants import kernels_for, make_participant, participant_name
from bringup.scenario.world import World
from sat_node.kernels import warm_up

__all__ = ["FACTORY", "PREPARE", "build", "prepare"]

FACTORY = "bringup.engine.ros.factory:build"
PREPARE = "bringup.engine.ros.factory:prepare"


def build(spec: RunSpec, role: str) -> list[Deferred]:
    """The participants process ``role`` hosts (``spec.members(role)``: one, or a group of
    satellites), in that order, each as a :class:`Deferred` its node builds in ``on_configure``
    (bringup/engine/ros/host.py): the participant and its bundle store are made when the lifecycle
    manager configures the node. They share one world, loaded by the first one configured (one
    contact graph for all of them)."""
    path = spec.extra.get("world")
    if not path:
        raise UserError("run spec: extra.world (path of the world pickle) is missing")
    store_dir = spec.extra.get("store_dir")
    keys = spec.keys()
    op_dir = spec.extra.get("operator_dir")  # live operator requests (constellation run --live-commands)
    live = (Path(op_dir), keys.run) if op_dir else None
    loaded: list = []  # [world, the gateway keywords]: made by the first node configured

    def shared() -> list:
        if not loaded:
            loaded.append(World.load(Path(path), spec.extra.get("world_key")))
            # --ground-gateway (bringup/engine/ros/ground_gateway.py): the ground's gateway started
            loaded.append(gateway_for(spec.extra, spec.members(role)))
        return loaded

    def make(r: str):
        world, gw = shared()
        p = make_participant(world, r, spec.mode, store_dir=Path(store_dir) if store_dir else None,
                             router_kw=spec.extra.get("router"), bpsec_key=keys.bpsec,
                             command_key=keys.command or None, live=live, **gw)
        report_at_finish([p], spec.extra)
        return p

    return [Deferred(participant_name(r), partial(make, r)) for r in spec.members(role)]


def prepare(spec: RunSpec, role: str | None) -> dict[str, float]:
    """The numba kernels the participants of process ``role`` use (None: the whole run's), compiled
    or loaded in this process; returns the seconds each kernel group took."""
    if role is None:
        which = kernels_for(spec.mode, None)
    else:
        which = tuple(dict.fromkeys(k for r in spec.members(role) for k in kernels_for(spec.mode, r)))
    return warm_up(which) if which else {}
