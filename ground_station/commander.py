"""The ground gateway for operator commands: signs the scenario's ``[[commands]]`` and uplinks them.

Each command (sat_node/operations/commands.py wire form) is signed at its issue time ``at_s`` with
its satellite's command key - derived from the ground's own command key, which only the gateway
holds (``satellite_command_key``) - and valid ``valid_s`` after it. A tasking request
(``kind = "task"``) carries the target, priority and deadline; one for ``sat = "all"`` becomes one
command per satellite (ids ``cK.sat_XX``), each under that satellite's key, and is refused up front
when the target lies farther than ``regions.gp_spacing_km`` from every ground point. It goes up at the first ground contact of any
satellite (the world's ground plan) that is still open at the issue time - preferring the command's
own satellite when its contact allows the same uplink time - on ``/ground/commands`` (GroundCommand:
the relay, the station, the signed text). A relay that is not the command's satellite forwards it
as a priority-1 bundle over the ISLs (sat_node/satellite.py). A command with no ground contact left
before the horizon is not sent and is counted (``not_uplinked``).

The gateway exists in a run only when the scenario scripts commands (bringup/scenario/participants.py),
so a run without commands is unchanged. ``forge`` sends a command under a wrong key, ``repeat`` the
same signed command again at the next contact: a hostile sender's tries, for the tests.

Oracle: tests/unit/test_operations_commands.py (uplink times against the ground plan searched by
hand; the signed text verifies under the satellites' key, the forged one does not);
tests/system/test_operations_commands_run.py (whole runs: latency, execution, rejections counted).
"""

from __future__ import annotations

import datetime as dt
import math

from ground_station.operator_requests import RequestInbox
from msgs_json import codec
from msgs_json import schemas as S
from msgs_json import topics as T
from msgs_json.envelope import Emit, Envelope, LiveState, StepResult
from sat_node.operations.commands import SETTABLE, Command, encode_command, satellite_command_key
from sat_node.operations.tasking import PRIORITIES, nearest_gp

__all__ = ["ALL_SATS", "COMMANDER_NAME", "CommanderLogic", "task_args", "uplink_slot"]

COMMANDER_NAME = "commander"
ALL_SATS = "all"  # a task's ``sat`` for every satellite (bringup/scenario/operations_cfg.py)
_NS = 1_000_000_000
LIVE_VALID_S = 3600  # a live command expires this long after its issue


def task_args(world, cfg, where: str) -> dict:
    """The ``args`` of a task command for the scenario's ``cfg`` (lat_deg, lon_deg, priority, by);
    ValueError in one line naming ``where`` when no ground point of the world's grid lies within
    ``regions.gp_spacing_km`` of the target (a satellite could not plan it: refused up front)."""
    sc = world.scenario
    by_ns = _ns_since(cfg.by, sc.epoch)
    gps = world.gps
    _gp, dist = nearest_gp(gps.lat_deg, gps.lon_deg, cfg.lat_deg, cfg.lon_deg)
    if dist > sc.regions.gp_spacing_km:
        raise ValueError(f"{where}: the target ({cfg.lat_deg:g}, {cfg.lon_deg:g}) is {dist:.1f} km from the "
                         f"nearest ground point; a task must fall within regions.gp_spacing_km "
                         f"({sc.regions.gp_spacing_km:g} km) of one (inside a region)")
    return {"lat_deg": float(cfg.lat_deg), "lon_deg": float(cfg.lon_deg), "priority": int(cfg.priority),
            "by_ns": int(by_ns)}


class _LiveTask:
    """A live task request's fields as task_args reads them, checked (ValueError in one line)."""

    def __init__(self, req: dict):
        lat, lon, pri, by = req.get("lat_deg"), req.get("lon_deg"), req.get("priority"), req.get("by")
        if not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in (lat, lon)) \
                or not (-90 <= lat <= 90 and -180 <= lon <= 180):
            raise ValueError(f"target ({lat!r}, {lon!r}): expected lat_deg in [-90, 90], lon_deg in [-180, 180]")
        if pri not in PRIORITIES or isinstance(pri, bool):
            raise ValueError(f"priority {pri!r}: expected one of {', '.join(map(str, PRIORITIES))}")
        if not isinstance(by, str) or not by.endswith("Z"):
            raise ValueError(f"deadline {by!r}: expected UTC ISO 8601 ending in Z")
        try:
            dt.datetime.fromisoformat(by[:-1])
        except ValueError:
            raise ValueError(f"deadline {by!r}: not an ISO 8601 time") from None
        self.lat_deg, self.lon_deg, self.priority, self.by = float(lat), float(lon), int(pri), by


def _live_set_args(req: dict) -> dict:
    """A live ``set`` request's command arguments, checked as a scripted ``[[commands]]`` set is
    (bringup/scenario/operations_cfg.py): a settable name, a value of its type within its bounds."""
    name, value = req.get("name"), req.get("value")
    if name not in SETTABLE:
        raise ValueError(f"set: {name!r} is not settable in flight (settable: {', '.join(SETTABLE)})")
    tp, lo, hi = SETTABLE[name]
    num = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
    if not num or (tp is int and not isinstance(value, int)) or not lo <= value <= hi:
        raise ValueError(f"set {name}: {value!r} is not {'an integer' if tp is int else 'a number'} in [{lo}, {hi}]")
    return {"name": name, "value": tp(value)}


def _ns_since(text: str, epoch: dt.datetime) -> int:
    """UTC ISO 8601 ``text`` (ending in Z) in integer ns after ``epoch``."""
    d = dt.datetime.fromisoformat(text.removesuffix("Z")).replace(tzinfo=dt.UTC) - epoch
    return (d.days * 86_400 + d.seconds) * _NS + d.microseconds * 1_000


def uplink_slot(contacts, t_ns: int, prefer: str, after_ns: int | None = None) -> tuple[int, str, str] | None:
    """(uplink time, relay satellite, station): the earliest time >= ``t_ns`` (and > ``after_ns``) in a
    satellite-to-station contact; ties go to ``prefer``, then by satellite name. None: no contact left."""
    best = None
    for c in contacts:
        if not str(c.dst).startswith("gs_"):
            continue
        s, e = int(round(c.start_s * _NS)), int(round(c.end_s * _NS))
        t = max(t_ns, s, (after_ns + 1) if after_ns is not None else 0)
        if t >= e:
            continue
        key = (t, c.src != prefer, c.src)
        if best is None or key < best[0]:
            best = (key, (t, c.src, c.dst))
    return None if best is None else best[1]


class CommanderLogic:
    name = COMMANDER_NAME

    def __init__(self, world, ground_key: bytes, live: RequestInbox | None = None):
        self.world = world
        self._ground_key = ground_key  # the ground's command key: each satellite's is derived from it
        self.live = live  # live operator requests (ground_station/operator_requests.py), None: none
        self.live_issued = 0
        sc = world.scenario
        self.sends: list[tuple[int, str, str, str]] = []  # (t_ns, relay, station, signed text)
        self.not_uplinked = 0
        seq = 0
        for k, cfg in enumerate(sc.commands):
            t0 = int(round(cfg.at_s * _NS))
            if cfg.kind == "mode":
                args = {"mode": cfg.mode}
            elif cfg.kind == "task":
                args = task_args(world, cfg, f"commands[{k}]")
            else:
                tp = SETTABLE[cfg.name][0]
                args = {"name": cfg.name, "value": tp(cfg.value)}
            sats = world.sat_names if cfg.sat == ALL_SATS else [cfg.sat]
            for sat in sats:  # a task for the constellation: one command per satellite, under its key
                seq += 1
                cid = f"c{k + 1}" if cfg.sat != ALL_SATS else f"c{k + 1}.{sat}"
                cmd = Command(cid, seq, sat, cfg.kind, args, t0, t0 + int(round(cfg.valid_s * _NS)))
                key = b"not the command key" if cfg.forge else self.key_of(sat)
                self._queue(encode_command(cmd, key).decode(), t0, sat, repeat=cfg.repeat)
        self.sends.sort()
        self._i = 0
        self._seq = seq

    def _poll(self, t_ns: int) -> None:
        """Issue the live operator requests that arrived (ground_station/operator_requests.py) now, at
        ``t_ns``, and answer each one."""
        if self.live is None:
            return
        self.live.mark_time(t_ns)
        new = False
        for name, req, err in self.live.poll():
            if req is not None:
                try:
                    ids = self._issue_live(req, t_ns)
                except ValueError as exc:
                    err = f"refused: {exc}"
                    self.live.refused["refused"] = self.live.refused.get("refused", 0) + 1
                else:
                    new = True
                    self.live.reply(name, {"ok": True, "commands": ids, "issued_s": t_ns / _NS})
                    continue
            self.live.reply(name, {"ok": False, "error": err})
        if new:  # the sends not yet made, in time order again
            self.sends = self.sends[:self._i] + sorted(self.sends[self._i:])

    def _issue_live(self, req: dict, t_ns: int) -> list[str]:
        """Sign and queue the commands of one operator request issued at ``t_ns``; ValueError (one line)."""
        kind, sat = req["request"], req["sat"]
        names = self.world.sat_names
        if sat not in names and not (kind == "task" and sat == ALL_SATS):
            raise ValueError(f"sat {sat!r} is not a satellite of this run" + (" (or 'all')" if kind == "task" else ""))
        if kind == "mode":
            if req.get("mode") not in ("safe", "nominal"):
                raise ValueError(f"mode {req.get('mode')!r}: expected safe or nominal")
            args = {"mode": req["mode"]}
        elif kind == "set":
            args = _live_set_args(req)
        else:
            cfg = _LiveTask(req)
            args = task_args(self.world, cfg, "task")
            if args["by_ns"] <= t_ns:
                raise ValueError(f"the deadline {cfg.by} is not after the issue time ({t_ns / _NS:g} s into the run)")
        self.live_issued += 1
        k = self.live_issued
        ids = []
        for s in (names if sat == ALL_SATS else [sat]):
            self._seq += 1
            cid = f"op{k}" if sat != ALL_SATS else f"op{k}.{s}"
            cmd = Command(cid, self._seq, s, kind, args, t_ns, t_ns + LIVE_VALID_S * _NS)
            if self._queue(encode_command(cmd, self.key_of(s)).decode(), t_ns, s):
                ids.append(cid)
        return ids

    def key_of(self, sat: str) -> bytes:
        """Satellite ``sat``'s command key (sat_node/operations/commands.py satellite_command_key)."""
        return satellite_command_key(self._ground_key, sat)

    def _queue(self, text: str, t0: int, sat: str, *, repeat: bool = False) -> bool:
        """Queue ``text`` for the first uplink at or after ``t0`` (False: no contact left, counted)."""
        contacts = self.world.ground_plan.contacts
        horizon = self.world.scenario.horizon_ns
        slot = uplink_slot(contacts, t0, sat)
        if slot is None or slot[0] > horizon:
            self.not_uplinked += 1
            return False
        self.sends.append((slot[0], slot[1], slot[2], text))
        if repeat:
            again = uplink_slot(contacts, slot[0], sat, after_ns=slot[0])
            if again is not None and again[0] <= horizon:
                self.sends.append((again[0], again[1], again[2], text))
        return True

    def subscriptions(self) -> list[str]:
        return []

    def start(self, t0_ns: int) -> StepResult:
        self._poll(t0_ns)
        return StepResult(self._due(t0_ns), self._wakeup(t0_ns))

    def step(self, t_ns: int, inbox: list[Envelope]) -> StepResult:
        self._poll(t_ns)
        return StepResult(self._due(t_ns), self._wakeup(t_ns))

    def finish(self, t_ns: int) -> list[Emit]:
        return self._due(t_ns)

    def live_state(self, t_ns: int) -> LiveState:
        v = {"commands.sent": self._i, "commands.not_uplinked": self.not_uplinked, "live.issued": self.live_issued}
        if self.live is not None:
            v.update((f"live.refused.{k}", n) for k, n in self.live.refused.items())
        return LiveState(None, v,
                         0, f"{self._i} of {len(self.sends)} commands uplinked")

    def _due(self, t_ns: int) -> list[Emit]:
        out = []
        while self._i < len(self.sends) and self.sends[self._i][0] <= t_ns:
            t, relay, station, text = self.sends[self._i]
            self._i += 1
            msg = S.GroundCommand(relay=relay, station=station, t_ns=t, payload=text)
            out.append(Emit(T.GROUND_COMMANDS, codec.encode(msg), t))
        return out

    def _wakeup(self, t_ns: int) -> int | None:
        return self.sends[self._i][0] if self._i < len(self.sends) else None
