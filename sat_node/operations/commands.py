"""Operator commands: their wire form, their authentication and the checks a satellite makes.

A command is compact JSON whose first key is ``"command"`` (one look at a bundle payload's first
bytes tells it from an observation's inference or a mode notice), followed by a MAC line::

    {"command":ID,"seq":N,"sat":SAT,"kind":KIND,"args":{...},"issued_ns":T0,"expires_ns":T1}\\n<hex tag>

``tag`` = HMAC-SHA256 (RFC 2104, FIPS 198-1) under the addressee's **command key** over the JSON bytes.

Keys (:func:`satellite_command_key`): the ground holds a command key of its own (a run's, in the
run keys file next to the BPSec key: bringup/engine/keys.py; never derived from the BPSec key
every satellite holds). Each satellite holds only the key derived from it for its own name. HMAC
is symmetric - whoever verifies could also sign - so this is what it buys: a satellite (or anyone
holding the BPSec key) cannot forge a command to another satellite; a compromised satellite can
forge commands to itself only. Asymmetric signatures (Ed25519) would take that away too; the
project has no dependency that provides them. Kinds:
``mode`` (``args.mode`` = ``safe`` | ``nominal``), ``set`` (``args.name``, ``args.value``: one of
:data:`SETTABLE`) and ``task`` (``args.lat_deg``, ``args.lon_deg``, ``args.priority`` 1..3,
``args.by_ns`` the deadline: a tasking request, sat_node/operations/tasking.py).

A satellite accepts a command only when (:class:`CommandGuard`, in this order) it parses
(``malformed``), the tag verifies under the command key (``forged``), it names this satellite
(``not_for_me``), its id was not seen before (``replayed``) and the time of arrival is before
``expires_ns`` (``expired``); each rejection is counted by reason and changes nothing else.

How we know it is right: tests/unit/test_operations_commands.py - the MAC against Python's
``hmac`` module recomputed by the test over the exact bytes, a flipped byte of payload or tag is
``forged``, the same command twice is ``replayed``, a late one ``expired``, every rejection counted;
a command under the BPSec key, the ground's key itself or another satellite's key is ``forged``.
"""

from __future__ import annotations

import hashlib
import hmac
import json
import math
from dataclasses import dataclass, field

from sat_node.operations.tasking import PRIORITIES

__all__ = ["SETTABLE", "Command", "CommandGuard", "CommandRejected", "encode_command",
           "is_command", "parse_command", "satellite_command_key",
           "target_of"]

_PREFIX = b'{"command":'
#: parameters a ``set`` command may change: name -> (type, low, high)
SETTABLE = {
    "operations.pointing_error_max_deg": (float, 0.0, 180.0),
    "operations.store_max_bundles": (int, 1, 10**9),
    "operations.clock_late_max_s": (float, 0.0, 86400.0),
}
KINDS = ("mode", "set", "task")
#: the arguments of a task command (sat_node/operations/tasking.py)
_TASK_ARGS = {"lat_deg", "lon_deg", "priority", "by_ns"}


class CommandRejected(ValueError):
    """A command refused; ``reason`` is the counter's name."""

    def __init__(self, reason: str, detail: str, command: Command | None = None):
        super().__init__(f"command {reason}: {detail}")
        self.reason = reason
        self.command = command  # when it was read (and authenticated): what it was


@dataclass(frozen=True)
class Command:
    id: str
    seq: int
    sat: str
    kind: str
    args: dict = field(default_factory=dict)
    issued_ns: int = 0
    expires_ns: int = 0


def satellite_command_key(ground_key: bytes, sat: str) -> bytes:
    """Satellite ``sat``'s command key: HMAC-SHA256 (RFC 2104) under the ground's command key of a
    fixed label and the satellite's name. The ground holds ``ground_key`` (its own, independent of
    the BPSec key the satellites share for bundles); each satellite holds its own derived key only,
    so one satellite's key verifies (and could sign) commands to that satellite alone."""
    if len(ground_key) < 16:
        raise ValueError(f"the ground's command key has {len(ground_key)} bytes; at least 16 are needed")
    return hmac.new(ground_key, b"constellation command key v2\0" + sat.encode(), hashlib.sha256).digest()


def encode_command(c: Command, key: bytes) -> bytes:
    body = json.dumps({"command": c.id, "seq": c.seq, "sat": c.sat, "kind": c.kind, "args": c.args,
                       "issued_ns": c.issued_ns, "expires_ns": c.expires_ns}, separators=(",", ":"),
                      sort_keys=False).encode()
    return body + b"\n" + hmac.new(key, body, hashlib.sha256).hexdigest().encode()


def is_command(payload: bytes) -> bool:
    return payload[:len(_PREFIX)] == _PREFIX


def _int(d: dict, k: str) -> int:
    v = d.get(k)
    if isinstance(v, bool) or not isinstance(v, int) or v < 0:
        raise CommandRejected("malformed", f"bad {k!r} ({v!r})")
    return v


def parse_command(payload: bytes, key: bytes) -> Command:
    """The command in ``payload`` when it is well formed and its tag verifies; CommandRejected else."""
    body, sep, tag = payload.rpartition(b"\n")
    if not sep or not is_command(body):
        raise CommandRejected("malformed", "not a command followed by a tag line")
    want = hmac.new(key, body, hashlib.sha256).hexdigest().encode()
    if not hmac.compare_digest(want, tag):
        raise CommandRejected("forged", "the tag does not verify under the command key")
    try:
        d = json.loads(body)
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise CommandRejected("malformed", f"not JSON ({exc})") from None
    cid, sat, kind, args = d.get("command"), d.get("sat"), d.get("kind"), d.get("args")
    if not isinstance(cid, str) or not cid or len(cid) > 64:
        raise CommandRejected("malformed", f"bad 'command' id ({cid!r})")
    if not isinstance(sat, str) or not sat:
        raise CommandRejected("malformed", f"bad 'sat' ({sat!r})")
    if kind not in KINDS:
        raise CommandRejected("malformed", f"kind {kind!r}: expected one of {', '.join(KINDS)}")
    if not isinstance(args, dict):
        raise CommandRejected("malformed", "'args' is not an object")
    c = Command(cid, _int(d, "seq"), sat, kind, args, _int(d, "issued_ns"), _int(d, "expires_ns"))
    check_args(c)
    return c


def check_args(c: Command) -> None:
    """A command's arguments are ones it can execute (CommandRejected ``malformed`` else)."""
    if c.kind == "mode":
        if c.args.get("mode") not in ("safe", "nominal") or set(c.args) != {"mode"}:
            raise CommandRejected("malformed", f"mode command args {c.args!r}: expected mode safe|nominal")
        return
    if c.kind == "task":
        a = c.args
        lat, lon, pri, by = a.get("lat_deg"), a.get("lon_deg"), a.get("priority"), a.get("by_ns")
        num = all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in (lat, lon))
        if set(a) != _TASK_ARGS or not num or not (-90 <= lat <= 90 and -180 <= lon <= 180):
            raise CommandRejected("malformed", f"task command args {a!r}: expected lat_deg in [-90, 90], "
                                  "lon_deg in [-180, 180], priority, by_ns")
        if pri not in PRIORITIES or isinstance(pri, bool):
            raise CommandRejected("malformed", f"task priority {pri!r}: expected one of {PRIORITIES}")
        if isinstance(by, bool) or not isinstance(by, int) or by <= c.issued_ns:
            raise CommandRejected("malformed", f"task deadline by_ns {by!r}: not an integer after the issue time")
        return
    name, value = c.args.get("name"), c.args.get("value")
    if name not in SETTABLE or set(c.args) != {"name", "value"}:
        raise CommandRejected("malformed", f"set command: parameter {name!r} is not settable "
                              f"({', '.join(SETTABLE)})")
    tp, lo, hi = SETTABLE[name]
    ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
    if not ok or (tp is int and not isinstance(value, int)) or not lo <= value <= hi:
        raise CommandRejected("malformed", f"set {name}: value {value!r} is not a {tp.__name__} "
                              f"in [{lo}, {hi}]")


class CommandGuard:
    """One satellite's acceptance checks (module docstring) and its rejection counters."""

    def __init__(self, sat: str, key: bytes):
        self.sat = sat
        self._key = key
        self.seen: set[str] = set()
        self.rejected: dict[str, int] = {}
        self.accepted = 0

    def __getstate__(self) -> dict:  # a checkpoint (sat_node/persist.py) never holds the key
        return {k: v for k, v in vars(self).items() if k != "_key"}

    def __setstate__(self, state: dict) -> None:
        vars(self).update(state)
        self._key = None  # until :meth:`keep_key_of` (a guard without its key rejects everything as forged)

    def keep_key_of(self, fresh: CommandGuard) -> None:
        """Take the key of ``fresh`` (the guard of the satellite a checkpoint is restored into)."""
        self._key = fresh._key

    def accept(self, payload: bytes, t_ns: int) -> Command:
        try:
            if self._key is None:
                raise CommandRejected("forged", "no command key (a restored guard not given its key)")
            c = parse_command(payload, self._key)
            if c.sat != self.sat:
                raise CommandRejected("not_for_me", f"{c.id} is for {c.sat}", c)
            if c.id in self.seen:
                raise CommandRejected("replayed", f"{c.id} was received before", c)
            if t_ns >= c.expires_ns:
                raise CommandRejected("expired", f"{c.id} expired at {c.expires_ns} ns, arrived {t_ns} ns", c)
        except CommandRejected as exc:
            self.rejected[exc.reason] = self.rejected.get(exc.reason, 0) + 1
            raise
        self.seen.add(c.id)
        self.accepted += 1
        return c


def target_of(payload: bytes) -> str | None:
    """The satellite a command names, read WITHOUT authentication (a relay routes on it; only the
    addressee's :class:`CommandGuard` verifies); None when it cannot be read."""
    body = payload.rpartition(b"\n")[0]
    try:
        d = json.loads(body)
    except (UnicodeDecodeError, json.JSONDecodeError):
        return None
    sat = d.get("sat") if isinstance(d, dict) else None
    return sat if isinstance(sat, str) else None
