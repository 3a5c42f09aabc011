"""Scenario tables of the satellites' operations (docs/guide/operations.md): ``[operations]`` (the mode
rules' limits), ``[[faults]]`` (injected faults) and ``[[commands]]`` (operator commands), with their
cross-checks (bringup/scenario/config.py loads them with the rest of a scenario).

Oracle: tests/unit/test_operations_modes.py and tests/unit/test_operations_commands.py break each key
and expect one ScenarioError line naming it.
"""

from __future__ import annotations

import datetime as _dt
from typing import Annotated, Literal

import msgspec

from sat_node.operations.commands import SETTABLE
from sat_node.operations.tasking import PRIORITIES

__all__ = ["ALL_SATS", "CommandCfg", "FaultCfg", "OperationsCfg", "check_operations", "deadline_s"]

#: ``sat`` of a task for the whole constellation (one command per satellite, each under its own key)
ALL_SATS = "all"


def deadline_s(sc, by: str) -> float:
    """A task's deadline ``by`` (UTC ISO 8601 ending in Z) in seconds from the scenario's epoch;
    ValueError naming the expected form."""
    if not by.endswith("Z"):
        raise ValueError(f"{by!r} must be UTC ISO 8601 ending in 'Z', e.g. 2000-01-01T13:00:00Z")
    try:
        t = _dt.datetime.fromisoformat(by[:-1]).replace(tzinfo=_dt.UTC)
    except ValueError:
        raise ValueError(f"{by!r} is not an ISO 8601 time, e.g. 2000-01-01T13:00:00Z") from None
    return (t - sc.epoch).total_seconds()

Pos = Annotated[float, msgspec.Meta(gt=0)]
NonNeg = Annotated[float, msgspec.Meta(ge=0)]
Name = Annotated[str, msgspec.Meta(min_length=1)]


class _S(msgspec.Struct, forbid_unknown_fields=True, frozen=True, kw_only=True):
    pass


class FaultCfg(_S, kw_only=True):
    """An injected fault (sat_node/operations/modes.py): ``kind`` on ``sat`` from ``at_s`` until
    ``until_s`` (0: to the end of the run), seconds from the epoch."""

    sat: Name
    kind: Literal["acs_stuck", "instrument_off", "store_full", "radio_off"]
    at_s: NonNeg
    until_s: NonNeg = 0.0


class CommandCfg(_S, kw_only=True):
    """An operator command the ground gateway issues at ``at_s`` to ``sat`` (ground_station/commander.py):
    ``kind`` mode (``mode`` safe | nominal), set (``name``, ``value``) or task (``lat_deg``, ``lon_deg``,
    ``priority`` 1..3, ``by`` the deadline in UTC ISO 8601 ending in Z; ``sat = "all"``: every
    satellite, sat_node/operations/tasking.py); valid for ``valid_s`` after issue. ``forge`` (a wrong tag) and ``repeat`` (the same signed command uplinked twice) script a
    hostile sender, to show such commands are rejected and counted."""

    sat: Name
    kind: Literal["mode", "set", "task"]
    at_s: NonNeg
    mode: Literal["", "safe", "nominal"] = ""
    name: str = ""
    value: float = 0.0
    lat_deg: float = 0.0
    lon_deg: float = 0.0
    priority: int = 1
    by: str = ""
    valid_s: Pos = 3600.0
    forge: bool = False
    repeat: bool = False


class OperationsCfg(_S, kw_only=True):
    """The limit checks of the satellites' modes (sat_node/operations/modes.py Limits)."""

    pointing_error_max_deg: Annotated[float, msgspec.Meta(gt=0, le=180)] = 5.0
    store_max_bundles: Annotated[int, msgspec.Meta(gt=0)] = 100_000
    clock_late_max_s: Pos = 60.0
    # housekeeping channels every this many seconds (/sat_XX/ops/hk; 0: none)
    hk_period_s: NonNeg = 0.0


def check_operations(sc, bad) -> None:
    """The cross-field rules of the operations tables; ``bad(key, why)`` raises the loader's error."""
    names_sat = set(sc.sat_names) if (sc.faults or getattr(sc, "commands", None)) else set()
    for k, f in enumerate(sc.faults):
        if f.sat not in names_sat:
            bad(f"faults[{k}].sat", f"{f.sat!r} is not a satellite of this constellation")
        if f.kind == "radio_off":
            bad(f"faults[{k}].kind", "radio_off is not implemented (the bundle agent's radio has no off "
                "state); use acs_stuck, instrument_off or store_full")
        if f.until_s and f.until_s <= f.at_s:
            bad(f"faults[{k}].until_s", f"{f.until_s:g} s is not after at_s {f.at_s:g} s (0: to the end)")
    for k, c in enumerate(sc.commands):
        _check_command(c, f"commands[{k}]", names_sat, sc, bad)


def _check_command(c: CommandCfg, key: str, sats: set, sc, bad) -> None:
    if c.sat not in sats and not (c.kind == "task" and c.sat == ALL_SATS):
        bad(f"{key}.sat", f"{c.sat!r} is not a satellite of this constellation"
            + (f" (a task may name {ALL_SATS!r})" if c.kind == "task" else ""))
    if c.kind == "task":
        if not (-90 <= c.lat_deg <= 90):
            bad(f"{key}.lat_deg", f"{c.lat_deg:g} is outside [-90, 90]")
        if not (-180 <= c.lon_deg <= 180):
            bad(f"{key}.lon_deg", f"{c.lon_deg:g} is outside [-180, 180]")
        if c.priority not in PRIORITIES:
            bad(f"{key}.priority", f"{c.priority} is not one of {', '.join(map(str, PRIORITIES))} (1: most urgent)")
        if not c.by:
            bad(f"{key}.by", "a task needs its deadline by = 'YYYY-MM-DDTHH:MM:SSZ'")
        try:
            by_s = deadline_s(sc, c.by)
        except ValueError as exc:
            bad(f"{key}.by", str(exc))
        if by_s <= c.at_s:
            bad(f"{key}.by", f"{c.by} is not after the issue time at_s {c.at_s:g} s")
    if c.kind == "mode" and not c.mode:
        bad(f"{key}.mode", "a mode command needs mode = 'safe' or 'nominal'")
    if c.kind == "set":
        if c.name not in SETTABLE:
            bad(f"{key}.name", f"{c.name!r} is not settable in flight (settable: {', '.join(SETTABLE)})")
        _tp, lo, hi = SETTABLE[c.name]
        if not lo <= c.value <= hi:
            bad(f"{key}.value", f"{c.value:g} is outside [{lo}, {hi}] for {c.name}")
    if not sc.ground.stations:
        bad(f"{key}", "commands go up at ground contacts, and the scenario has no ground.stations")
