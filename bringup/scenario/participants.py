"""Which participants a run has, and which process (role) hosts each (DESIGN.md section 2).

Roles: one per satellite (``sat_PS``, one OS process each under the ROS engine), ``router`` (the
ISL medium; distributed mode only), ``ground`` (the ground segment; centralized mode only) and
``contacts`` (the contact-window announcer, orbit_clock/contact_announcer.py; every mode). The
router and the announcer share one truth ISL plan: the world's, with the run's faults
(``router_kw``: ``cuts``, ``extra_delay_s``; orbit_clock/contact_faults.py).
``make_participant(world, role, mode)`` makes one; the ROS engine's processes call it through
their run spec's factory (bringup/engine/ros/factory.py), one role each; ``all_participants(world,
mode)`` gives the same participants, in the same order, for the local engine. Both build the
satellites from the same World pickle, so every process sees identical inputs.

Checked by tests/unit/test_ground_segment.py and tests/unit/test_contact_announcer.py (who is
made for each mode) and tests/system/test_engines_equal.py (the same participants under both
engines).
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from bringup.errors import UserError
from bringup.scenario.world import World
from dtn_router.router import RouterLogic
from ground_station.ground_segment import GroundLogic
from orbit_clock.contact_announcer import ContactAnnouncer
from orbit_clock.contact_faults import truth_plan
from sat_node.dtn.store import BundleStore
from sat_node.satellite import SatelliteLogic

__all__ = ["MODES", "all_participants", "kernels_for", "make_participant", "roles_for"]

MODES = ("distributed", "centralized", "nonagile")
ROUTER_ROLE = "router"
GROUND_ROLE = "ground"
CONTACTS_ROLE = "contacts"


def roles_for(world_or_sats, mode: str) -> list[str]:
    sats = list(world_or_sats.sat_names) if hasattr(world_or_sats, "sat_names") else list(world_or_sats)
    if mode not in MODES:
        raise UserError(f"--mode {mode!r}: expected one of {', '.join(MODES)}")
    roles = list(sats)
    if mode == "distributed":
        roles.append(ROUTER_ROLE)
    if mode == "centralized":
        roles.append(GROUND_ROLE)
    roles.append(CONTACTS_ROLE)
    return roles


def kernels_for(mode: str, role: str | None) -> tuple[str, ...]:
    """Numba kernel groups (sat_node/kernels.py) the participants of ``role`` use in ``mode`` (role
    None: the whole run's): the DP scheduler for a distributed satellite and the centralized ground
    segment, CGR for a distributed satellite."""
    if mode == "distributed" and role not in (ROUTER_ROLE, CONTACTS_ROLE, GROUND_ROLE):
        return ("dp", "cgr")
    if mode == "centralized" and role in (None, GROUND_ROLE):
        return ("dp",)
    return ()


def make_participant(world: World, role: str, mode: str, *, store_dir: Path | None, router_kw: dict | None):
    if role == ROUTER_ROLE:
        return RouterLogic.for_world(world, **(router_kw or {}))
    if role == CONTACTS_ROLE:
        return ContactAnnouncer(truth_plan(world.isl_plan, **(router_kw or {})), world.ground_plan)
    if role == GROUND_ROLE:
        return GroundLogic(world)
    if role in world.sat_names:
        store = str(store_path(store_dir, role)) if store_dir is not None and mode == "distributed" else None
        return SatelliteLogic(world, role, mode, store_path=store)
    raise UserError(f"role {role!r}: not a satellite of the scenario, nor "
                    f"'{ROUTER_ROLE}'/'{GROUND_ROLE}'/'{CONTACTS_ROLE}'")


def store_path(store_dir: Path, sat: str) -> Path:
    """The bundle store file of satellite ``sat`` in a run's store folder."""
    return Path(store_dir) / f"{sat}.sqlite"


def create_stores(store_dir: Path, sats: list[str]):
    """Start creating the satellites' empty bundle stores (SQLite files in WAL mode) in worker
    threads; returns ``wait()``, which returns when they are all made (their worker threads ended)
    and raises the first failure. Making one takes ~25 ms, nearly all of it waiting for the disk (the
    WAL switch syncs the file), so the local run starts them before it builds the world and they
    overlap with it; the satellites then open files that are ready (sat_node/dtn/store.py)."""

    ex = ThreadPoolExecutor(max_workers=8, thread_name_prefix="store")
    futs = [ex.submit(lambda p: BundleStore(p).close(), store_path(store_dir, s)) for s in sats]

    def wait() -> None:
        ex.shutdown(wait=True)
        for f in futs:
            f.result()

    return wait


def all_participants(world: World, mode: str, *, store_dir: Path | None = None,
                     router_kw: dict | None = None) -> list:
    return [make_participant(world, r, mode, store_dir=store_dir, router_kw=router_kw) for r in roles_for(world, mode)]

