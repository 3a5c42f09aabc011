"""One satellite's operations state: its mode, what it was told of its neighbours, its counters.

:class:`Operations` is what sat_node/satellite.py keeps per satellite (and checkpoints with the
rest of it, sat_node/persist.py): the mode picked by the rules of sat_node/operations/modes.py at
every step, the ACS's frozen boresight while it is stuck, the newest mode notice per neighbour
(sat_node/operations/notice.py), the time spent in each mode and the plan value dropped on
leaving imaging. It holds no engine code: both engines run it through the satellite.

Oracle: tests/unit/test_operations_modes.py (transitions, time in mode, notices kept newest-first)
and tests/system/test_operations_faults.py (whole runs, both engines).
"""

from __future__ import annotations

from sat_node.operations.modes import (
    MODES,
    NOMINAL,
    FaultSchedule,
    Limits,
    Telemetry,
    imaging_allowed,
    mode_for,
)
from sat_node.operations.notice import ModeNotice

__all__ = ["ModeTransition", "Operations"]


class ModeTransition(tuple):
    """(t_ns, previous, mode, reason) of one change."""

    __slots__ = ()

    def __new__(cls, t_ns: int, previous: str, mode: str, reason: str):
        return super().__new__(cls, (t_ns, previous, mode, reason))

    t_ns = property(lambda s: s[0])
    previous = property(lambda s: s[1])
    mode = property(lambda s: s[2])
    reason = property(lambda s: s[3])


class Operations:
    # command acknowledgements (sat_node/operations/onboard.py): queued (downlink time, number, CommandAck),
    # how many were queued, sent, and not sent for want of a ground contact (class defaults: a
    # checkpoint from before them restores with none)
    acks: list | tuple = ()
    acks_queued = 0
    acks_sent = 0
    acks_not_sent = 0

    def __init__(self, name: str, faults: FaultSchedule, limits: Limits, t0_ns: int = 0):
        self.name = name
        self.faults = faults
        self.limits = limits
        self.mode = NOMINAL
        self.reason = ""
        self.commanded_safe = False
        self.since_ns = t0_ns
        self.time_in_mode_ns = {m: 0 for m in MODES}
        self.frozen_target_km = None  # where a stuck ACS holds the boresight (None: not stuck)
        self.peer_notice: dict[str, ModeNotice] = {}  # newest notice per neighbour
        self.bundles_not_stored = 0  # observations whose bundle a full store refused
        self.value_dropped = 0.0

    @property
    def imaging(self) -> bool:
        return imaging_allowed(self.mode, self.reason)

    def update(self, t_ns: int, tm: Telemetry) -> ModeTransition | None:
        """Apply the rules to ``tm``; the transition when the mode (or its reason) changed."""
        mode, reason = mode_for(tm, self.limits)
        if mode == self.mode and reason == self.reason:
            return None
        prev = self.mode
        if mode != prev:
            self.time_in_mode_ns[prev] += max(0, t_ns - self.since_ns)
            self.since_ns = t_ns
        self.mode, self.reason = mode, reason
        return ModeTransition(t_ns, prev, mode, reason) if mode != prev else None

    def time_in_mode_s(self, t_end_ns: int) -> dict[str, float]:
        out = dict(self.time_in_mode_ns)
        out[self.mode] += max(0, t_end_ns - self.since_ns)
        return {m: v / 1e9 for m, v in out.items()}

    def learn_notice(self, n: ModeNotice) -> bool:
        """Keep ``n`` if it is the newest from its source; True when the source's imaging changed."""
        old = self.peer_notice.get(n.src)
        if old is not None and old.t_ns >= n.t_ns:
            return False
        self.peer_notice[n.src] = n
        return (old.imaging if old is not None else True) != n.imaging

    def peers_not_imaging(self) -> frozenset[str]:
        return frozenset(s for s, n in self.peer_notice.items() if not n.imaging)
