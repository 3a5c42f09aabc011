"""The ROS engine's participant factory for scenario runs.

A run spec (bringup/engine/ros/run_spec.py) names the factory every node process calls as
``"module:function"``; for a scenario run it is ``FACTORY`` here: ``build(spec, role)`` loads the
world pickle the launcher wrote (``spec.extra["world"]``) and returns the one participant ``role``
hosts, made by bringup/scenario/participants.py exactly as the local engine makes it, so both
engines run the same participants from the same inputs (tests/system/test_engines_equal.py).
"""

from __future__ import annotations

from pathlib import Path

from bringup.engine.ros.run_spec import RunSpec
from bringup.errors import UserError
from bringup.scenario.participants import make_participant
from bringup.scenario.world import World

__all__ = ["FACTORY", "build"]

FACTORY = "bringup.engine.ros.factory:build"


def build(spec: RunSpec, role: str) -> list:
    """The participants ``role`` hosts (one each)."""
    path = spec.extra.get("world")
    if not path:
        raise UserError("run spec: extra.world (path of the world pickle) is missing")
    world = World.load(Path(path), spec.extra.get("world_key"))
    store_dir = spec.extra.get("store_dir")
    return [make_participant(world, role, spec.mode, store_dir=Path(store_dir) if store_dir else None,
                             router_kw=spec.extra.get("router"))]
