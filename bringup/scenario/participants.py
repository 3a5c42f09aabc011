"""Which participants a run has, and which process (role) hosts each (docs/design.md section 2).

Roles: one per satellite (``sat_PS``, one OS process each under the ROS engine), ``router`` (the
ISL medium; distributed mode only), ``ground`` (the ground segment; centralized mode only),
``contacts`` (the contact-window announcer, orbit_clock/contact_announcer.py; every mode) and
``commander`` (the operator-command gateway, ground_station/commander.py; only with ``[[commands]]``). The
router and the announcer share one truth ISL plan: the world's, with the run's faults
(``router_kw``: ``cuts``, ``extra_delay_s``; orbit_clock/contact_faults.py).
``make_participant(world, role, mode)`` makes one; the ROS engine's processes call it through
their run spec's factory (bringup/engine/ros/factory.py), one role each, or several satellites each
(``process_groups``: ``constellation run --sats-per-process K``); ``all_participants(world,
mode)`` gives the same participants, in the same order, for the local engine. Both build the
satellites from the same World pickle, so every process sees identical inputs. The satellites'
BPSec key is an argument: it comes from the deployment (bringup/engine/keys.py), not the world.

Checked by tests/unit/test_ground_segment.py, tests/unit/test_contact_announcer.py (who is
made for each mode), tests/unit/test_process_groups.py (satellites grouped into processes) and
tests/system/test_engines_equal.py (the same participants under both engines, one or four
satellites per process).
"""

from __future__ import annotations

import secrets
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from bringup.errors import UserError
from bringup.scenario.world import World
from dtn_router.router import ROUTER_NAME, RouterLogic
from ground_station.commander import COMMANDER_NAME, CommanderLogic
from ground_station.ground_segment import GROUND_NAME, GroundLogic
from ground_station.operator_requests import RequestInbox, operator_key
from orbit_clock.contact_announcer import ANNOUNCER_NAME, ContactAnnouncer
from orbit_clock.contact_faults import truth_plan
from sat_node.dtn.store import BundleStore
from sat_node.operations.commands import satellite_command_key
from sat_node.satellite import SatelliteLogic

__all__ = ["AUTO_SAT_PROCESSES", "MODES", "all_participants", "kernels_for", "make_participant", "participant_name",
           "process_groups", "roles_for", "sats_per_process_auto"]

MODES = ("distributed", "centralized", "nonagile")
ROUTER_ROLE = "router"
GROUND_ROLE = "ground"
CONTACTS_ROLE = "contacts"
COMMANDER_ROLE = COMMANDER_NAME  # the operator-command gateway: only when the scenario scripts commands


def roles_for(world_or_sats, mode: str, *, live_commands: bool = False) -> list[str]:
    sats = list(world_or_sats.sat_names) if hasattr(world_or_sats, "sat_names") else list(world_or_sats)
    if mode not in MODES:
        raise UserError(f"--mode {mode!r}: expected one of {', '.join(MODES)}")
    roles = list(sats)
    if mode == "distributed":
        roles.append(ROUTER_ROLE)
    if mode == "centralized":
        roles.append(GROUND_ROLE)
    roles.append(CONTACTS_ROLE)
    sc = getattr(world_or_sats, "scenario", None)
    if live_commands or (sc is not None and getattr(sc, "commands", None)):
        roles.append(COMMANDER_ROLE)
    return roles


# Satellites per process when the run does not say (``--sats-per-process auto``): at most this many
# satellite processes (one each up to this many satellites, as the paper's 24)
AUTO_SAT_PROCESSES = 24


def sats_per_process_auto(n_sats: int) -> int:
    """Satellites per process for ``auto``: 1 up to :data:`AUTO_SAT_PROCESSES` satellites, then
    as few as keep the satellite processes at that many."""
    return max(1, -(-int(n_sats) // AUTO_SAT_PROCESSES))


def process_groups(roles: list[str], sats: list[str], per_process: int) -> dict[str, list[str]]:
    """Which participants each OS process of the ROS engine hosts: process role -> participant roles.

    With ``per_process`` 1 every role is its own process (named by it). Above 1 the satellites go
    ``per_process`` at a time, in their order, into processes ``sats_01``, ``sats_02``, ... (the
    number padded to the count's width), and every other role (router, ground, contacts) stays alone.
    One process runs its participants one after the other in one executor (the ROS 2 component
    container pattern, bringup/engine/ros/host.py); the engine contract makes the results the same
    however the participants are spread (tests/system/test_engines_equal.py)."""
    if per_process < 1:
        raise UserError(f"--sats-per-process must be >= 1, got {per_process}")
    if per_process == 1:
        return {r: [r] for r in roles}
    sat_set = set(sats)
    in_order = [r for r in roles if r in sat_set]
    chunks = [in_order[i:i + per_process] for i in range(0, len(in_order), per_process)]
    width = len(str(len(chunks)))
    out = {f"sats_{k + 1:0{width}d}": c for k, c in enumerate(chunks)}
    clash = [r for r in roles if r not in sat_set and r in out]
    if clash:
        raise UserError(f"role {clash[0]!r} is also the name of a satellite process group")
    out.update({r: [r] for r in roles if r not in sat_set})
    return out


def kernels_for(mode: str, role: str | None) -> tuple[str, ...]:
    """Numba kernel groups (sat_node/kernels.py) the participants of ``role`` use in ``mode`` (role
    None: the whole run's): the DP scheduler for a distributed satellite and the centralized ground
    segment, CGR for a distributed satellite."""
    if mode == "distributed" and role not in (ROUTER_ROLE, CONTACTS_ROLE, GROUND_ROLE, COMMANDER_ROLE):
        return ("dp", "cgr")
    if mode == "centralized" and role in (None, GROUND_ROLE):
        return ("dp",)
    return ()


def participant_name(role: str) -> str:
    """The name of the participant ``role`` makes (its node's name), known before it is built: a
    satellite's is the role, the others' their module's constant."""
    return {ROUTER_ROLE: ROUTER_NAME, CONTACTS_ROLE: ANNOUNCER_NAME, GROUND_ROLE: GROUND_NAME,
            COMMANDER_ROLE: COMMANDER_NAME}.get(role, role)


def make_participant(world: World, role: str, mode: str, *, store_dir: Path | None, router_kw: dict | None,
                     bpsec_key: bytes, command_key: bytes | None = None, live: tuple[Path, bytes] | None = None,
                     gateway=None, gateway_spec=None):
    """Participant ``role``. ``command_key``: the ground's command key (bringup/engine/keys.py), needed
    when the scenario scripts commands or the run takes live ones: the commander holds it, each
    satellite only the key derived from it for its name (sat_node/operations/commands.py
    satellite_command_key). ``live``: (the run's operator folder, the run key) when the run takes live
    operator requests (ground_station/operator_requests.py; ``constellation run --live-commands``).
    ``gateway``: a started ground_station.gateway.Gateway (runs with ``--ground-gateway``): the
    ground forwards to its peer, and the satellites address their downlinks to the peer's node;
    ``gateway_spec``: its GatewaySpec alone, enough for the satellites (a ROS-engine satellite process,
    which holds no gateway: bringup/engine/ros/ground_gateway.py)."""
    if gateway is not None:
        gateway_spec = gateway.spec
    scripted = getattr(world.scenario, "commands", None)
    commands = bool(scripted) or live is not None
    if commands and command_key is None:
        raise UserError("[[commands]] need the ground's command key (the run keys' 'command'); none was given")
    if role == COMMANDER_ROLE and mode != "distributed" and any(c.kind == "task" for c in scripted or ()):
        raise UserError(f"tasking requests ([[commands]] kind = 'task') need onboard planning: --mode distributed, "
                        f"not {mode}")
    if role == ROUTER_ROLE:
        return RouterLogic.for_world(world, **(router_kw or {}))
    if role == CONTACTS_ROLE:
        return ContactAnnouncer(truth_plan(world.isl_plan, **(router_kw or {})), world.ground_plan)
    if role == GROUND_ROLE:
        if gateway_spec is not None and gateway is None:
            raise UserError(f"role {role!r}: the ground of a --ground-gateway run needs its started gateway")
        # the ground's store is a file when it can hold bundles across steps: with a gateway (bundles for
        # the peer until acknowledged, bundles from it until their pass); without one every downlink is
        # delivered at once and the store stays empty (kept in memory)
        store = None if store_dir is None or gateway is None else str(Path(store_dir) / "ground.sqlite")
        return GroundLogic(world, bpsec_key, store_path=store, gateway=gateway)
    if role == COMMANDER_ROLE and commands:
        inbox = RequestInbox(live[0], operator_key(live[1])) if live is not None else None
        try:
            return CommanderLogic(world, command_key, live=inbox)
        except ValueError as exc:  # a task's target off every region's grid: refused up front
            raise UserError(str(exc)) from None
    if role in world.sat_names:
        store = str(store_path(store_dir, role)) if store_dir is not None and mode == "distributed" else None
        own = satellite_command_key(command_key, role) if commands else None
        if gateway_spec is None:
            return SatelliteLogic(world, role, mode, store_path=store, bpsec_key=bpsec_key, command_key=own)
        return SatelliteLogic(world, role, mode, store_path=store, bpsec_key=bpsec_key, command_key=own,
                              downlink_node=gateway_spec.node, ground_bundles=True)
    raise UserError(f"role {role!r}: not a satellite of the scenario, nor "
                    f"'{ROUTER_ROLE}'/'{GROUND_ROLE}'/'{CONTACTS_ROLE}' "
                    f"(or '{COMMANDER_ROLE}' with [[commands]])")


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


def all_participants(world: World, mode: str, *, bpsec_key: bytes, store_dir: Path | None = None,
                     router_kw: dict | None = None, command_key: bytes | None = None, gateway=None) -> list:
    """Every participant of a run in one process (the local engine); ``command_key`` None: a new
    random ground command key (every participant is made here, so they all agree on it)."""
    if command_key is None and getattr(world.scenario, "commands", None):
        command_key = secrets.token_bytes(32)
    return [make_participant(world, r, mode, store_dir=store_dir, router_kw=router_kw, bpsec_key=bpsec_key,
                             command_key=command_key, gateway=gateway)
            for r in roles_for(world, mode)]

