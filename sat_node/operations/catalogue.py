"""The event catalogue and the command / telemetry dictionary of the satellites' operations.

Events: every ModeChange and CommandEvent message (sat_node/operations/onboard.py) is one event of
the log, with a fixed numeric ID, a severity (the ECSS PUS service 5 levels: informative, low,
medium, high - ECSS-E-ST-70-41C section 6.5) and a one-line text, by :data:`EVENTS`:

* 1xxx mode changes: 1000 + the rule that fired (modes.py's table), 1000 itself for a return to NOMINAL;
* 2xxx commands: 2001 received, 2002 executed, 2100 + the rejection reason (commands.py).

The dictionary (:func:`dictionary`) is generated from the code, never written by hand: every command
kind with its arguments (the settable parameters with type and bounds, commands.py ``SETTABLE``),
every event of the catalogue, and every operations message with its fields, types and units (from
the msgspec schemas, msgs_json/schemas.py; the unit from the field name's suffix: ``_ns``, ``_s``,
``_deg``). ``constellation ops dictionary`` writes it as one JSON file.

Oracle: tests/unit/test_operations_catalogue.py - every rule reason of modes.py and every rejection
reason a CommandGuard can give has an event; IDs are unique; the dictionary lists every settable
parameter and every field of the schemas (read back through msgspec's own inspection); the events
of hand-made messages.
"""

from __future__ import annotations

import msgspec

from msgs_json import schemas as S
from sat_node.operations.commands import KINDS, SETTABLE
from sat_node.operations.packets import CHANNELS, HK_APID_BASE
from sat_node.operations.tasking import PRIORITIES, TASK_VALUE

__all__ = ["EVENTS", "MESSAGES", "REJECTIONS", "RULE_REASONS", "dictionary", "event_of"]

#: the reasons modes.mode_for can give (its table), "" = back to NOMINAL
RULE_REASONS = ("", "acs_fault", "pointing_error", "commanded", "instrument_fault", "store_full", "clock_late")
#: the rejection reasons of CommandGuard, of a relay and of a task off the grid (onboard.py)
REJECTIONS = ("malformed", "forged", "not_for_me", "replayed", "expired", "no_isl", "no_such_satellite", "no_target")

_SEVERITY_OF_MODE = {"NOMINAL": "informative", "DEGRADED": "medium", "SAFE": "high"}


def _catalogue() -> dict[int, dict]:
    ev: dict[int, dict] = {}
    for i, reason in enumerate(RULE_REASONS):
        mode = {"": "NOMINAL", "acs_fault": "SAFE", "pointing_error": "SAFE", "commanded": "SAFE"}.get(reason, "DEGRADED")
        ev[1000 + i] = {"name": f"MODE_{mode}" + (f"_{reason.upper()}" if reason else ""), "severity":
                        _SEVERITY_OF_MODE[mode], "message": "ModeChange", "mode": mode, "reason": reason,
                        "text": f"entered {mode}" + (f" ({reason})" if reason else "")}
    ev[2001] = {"name": "CMD_RECEIVED", "severity": "informative", "message": "CommandEvent", "stage": "received",
                "text": "command received"}
    ev[2002] = {"name": "CMD_EXECUTED", "severity": "informative", "message": "CommandEvent", "stage": "executed",
                "text": "command executed"}
    for i, reason in enumerate(REJECTIONS):
        ev[2100 + i] = {"name": f"CMD_REJECTED_{reason.upper()}", "severity": "low" if reason == "expired" else "medium",
                        "message": "CommandEvent", "stage": "rejected", "reason": reason,
                        "text": f"command rejected: {reason}"}
    return ev


#: event id -> {name, severity, message, text, and what selects it (mode / reason / stage)}
EVENTS: dict[int, dict] = _catalogue()
_BY_KEY = {(e["message"], e.get("mode", e.get("stage")), e.get("reason", "")): k for k, e in EVENTS.items()}
#: the operations messages the dictionary describes
MESSAGES = (S.ModeChange, S.CommandEvent, S.CommandAck, S.GroundCommand, S.Housekeeping)


def event_of(msg) -> tuple[int, str, str]:
    """(event id, severity, text) of a ModeChange or CommandEvent message; ValueError for another."""
    if isinstance(msg, S.ModeChange):
        key = ("ModeChange", msg.mode, msg.reason)
    elif isinstance(msg, S.CommandEvent):
        key = ("CommandEvent", msg.stage, msg.reason if msg.stage == "rejected" else "")
    else:
        raise ValueError(f"{type(msg).__name__} is not an operations event")
    eid = _BY_KEY.get(key)
    if eid is None:
        raise ValueError(f"no catalogued event for {key}")
    e = EVENTS[eid]
    text = e["text"] + (f" {msg.command_id}" if isinstance(msg, S.CommandEvent) else "")
    return eid, e["severity"], text


def _unit(name: str) -> str:
    for suffix, unit in (("_ns", "ns"), ("_deg", "deg"), ("_s", "s")):
        if name.endswith(suffix):
            return unit
    return ""


def _param_unit(name: str) -> str:
    return "deg" if "_deg" in name else "s" if name.endswith("_s") else "bundles" if "bundles" in name else ""


def _type_name(t) -> str:
    mi = msgspec.inspect
    if isinstance(t, mi.LiteralType):
        return "enum(" + ", ".join(map(str, t.values)) + ")"
    return type(t).__name__.removesuffix("Type").lower()


def dictionary() -> dict:
    """The command and telemetry dictionary (module docstring), as a JSON-ready dict."""
    msgs = []
    for m in MESSAGES:
        info = msgspec.inspect.type_info(m)
        msgs.append({"message": m.__name__, "doc": " ".join((m.__doc__ or "").split()),
                     "fields": [{"name": f.name, "type": _type_name(f.type), "unit": _unit(f.name)}
                                for f in info.fields if f.name != "v"]})
    return {
        "commands": [{"kind": "mode", "args": [{"name": "mode", "type": "enum(safe, nominal)"}]},
                     {"kind": "set", "args": [{"name": "name", "type": "enum(" + ", ".join(SETTABLE) + ")"},
                                              {"name": "value", "type": "number"}],
                      "parameters": [{"name": n, "type": tp.__name__, "min": lo, "max": hi, "unit": _param_unit(n)}
                                     for n, (tp, lo, hi) in SETTABLE.items()]},
                     {"kind": "task", "args": [{"name": "lat_deg", "type": "float", "min": -90, "max": 90, "unit": "deg"},
                                               {"name": "lon_deg", "type": "float", "min": -180, "max": 180,
                                                "unit": "deg"},
                                               {"name": "priority", "type": "enum(" + ", ".join(map(str, PRIORITIES))
                                                + ")", "unit": ""},
                                               {"name": "by_ns", "type": "int", "unit": "ns"}],
                      "values": {str(p): v for p, v in TASK_VALUE.items()}}],
        "command_kinds": list(KINDS),
        "events": [{"id": k, **e} for k, e in sorted(EVENTS.items())],
        "packets": {"standard": "CCSDS 133.0-B-2 space packets, big-endian, no secondary header",
                    "housekeeping": {"apid": f"{HK_APID_BASE:#x} + satellite index (1-based)",
                                     "channels": [{"name": n, "type": t, "bits": b, "unit": u}
                                                  for n, _c, t, b, u in CHANNELS]}},
        "telemetry": msgs,
    }
