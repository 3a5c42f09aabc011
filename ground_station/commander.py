"""The ground gateway for operator commands: signs the scenario's ``[[commands]]`` and uplinks them.

Each command (sat_node/operations/commands.py wire form) is signed with the command key at its
issue time ``at_s`` and valid ``valid_s`` after it. It goes up at the first ground contact of any
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

from msgs_json import codec
from msgs_json import schemas as S
from msgs_json import topics as T
from msgs_json.envelope import Emit, Envelope, LiveState, StepResult
from sat_node.operations.commands import SETTABLE, Command, command_key, encode_command

__all__ = ["COMMANDER_NAME", "CommanderLogic", "uplink_slot"]

COMMANDER_NAME = "commander"
_NS = 1_000_000_000


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

    def __init__(self, world, bpsec_key: bytes):
        self.world = world
        self._key = command_key(bpsec_key)
        contacts = world.ground_plan.contacts
        horizon = world.scenario.horizon_ns
        self.sends: list[tuple[int, str, str, str]] = []  # (t_ns, relay, station, signed text)
        self.not_uplinked = 0
        for k, cfg in enumerate(world.scenario.commands):
            t0 = int(round(cfg.at_s * _NS))
            if cfg.kind == "mode":
                args = {"mode": cfg.mode}
            else:
                tp = SETTABLE[cfg.name][0]
                args = {"name": cfg.name, "value": tp(cfg.value)}
            cmd = Command(f"c{k + 1}", k + 1, cfg.sat, cfg.kind, args, t0, t0 + int(round(cfg.valid_s * _NS)))
            text = encode_command(cmd, b"not the command key" if cfg.forge else self._key).decode()
            slot = uplink_slot(contacts, t0, cfg.sat)
            if slot is None or slot[0] > horizon:
                self.not_uplinked += 1
                continue
            self.sends.append((slot[0], slot[1], slot[2], text))
            if cfg.repeat:
                again = uplink_slot(contacts, slot[0], cfg.sat, after_ns=slot[0])
                if again is not None and again[0] <= horizon:
                    self.sends.append((again[0], again[1], again[2], text))
        self.sends.sort()
        self._i = 0

    def subscriptions(self) -> list[str]:
        return []

    def start(self, t0_ns: int) -> StepResult:
        return StepResult(self._due(t0_ns), self._wakeup(t0_ns))

    def step(self, t_ns: int, inbox: list[Envelope]) -> StepResult:
        return StepResult(self._due(t_ns), self._wakeup(t_ns))

    def finish(self, t_ns: int) -> list[Emit]:
        return self._due(t_ns)

    def live_state(self, t_ns: int) -> LiveState:
        return LiveState(None, {"commands.sent": self._i, "commands.not_uplinked": self.not_uplinked},
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
