"""Satellite modes and the fault detection, isolation and recovery (FDIR) rules that pick them.

Three modes, as flight software commonly has them (ECSS-E-ST-70-11C section 5.5 "on-board
autonomy"; NASA cFS and F Prime carry the same split):

* ``NOMINAL`` - images, replans, forwards bundles;
* ``DEGRADED`` - keeps going with what still works: an instrument fault stops imaging (and the
  replans, which would plan looks it cannot take); a full store stops new bundles (the looks are
  still taken and recorded); a late clock step only flags it;
* ``SAFE`` - no imaging, no replanning, the boresight held at nadir (the safe attitude), the radio
  keeps forwarding the bundles it holds and receives (priority 1 among them), and its neighbours
  are told (sat_node/operations/notice.py) so their planners no longer count on it.

The rules (:func:`mode_for`), evaluated at every step on the satellite's own telemetry
(:class:`Telemetry`) before it executes anything, most severe first:

==========================================  ========  ==========================
limit check                                 mode      reason (event / report key)
==========================================  ========  ==========================
ACS reports a fault                         SAFE      ``acs_fault``
pointing error > ``pointing_error_max_deg``  SAFE      ``pointing_error``
commanded SAFE                              SAFE      ``commanded``
instrument reports a fault                  DEGRADED  ``instrument_fault``
store occupancy >= ``store_max_bundles``    DEGRADED  ``store_full``
clock step late by > ``clock_late_max_s``   DEGRADED  ``clock_late``
none of these                               NOMINAL   -
==========================================  ========  ==========================

Recovery by rule: the mode is re-evaluated at every step, so a cleared fault (a scenario fault's
``until_s``) returns the satellite to NOMINAL at its next step; recovery by command clears a
commanded SAFE. A mode is a function of the telemetry at that step only (no hysteresis).

Faults are injected by the environment, not sensed by magic: a :class:`FaultSchedule` holds the
scenario's ``[[faults]]`` of one satellite and sets the hardware flags the telemetry reads (the
ACS's and the instrument's fault bits, the store's occupancy) - what a real unit's own built-in
test would report. A ``radio_off`` fault is refused at load (the bundle agent's radio has no off
state: bringup/scenario/config.py names it).

How we know it is right: tests/unit/test_operations_modes.py checks every row of the table on
hand-made telemetry, the order of precedence, and the schedule's activation windows;
tests/system/test_operations_faults.py runs an ACS fault through whole runs on both engines.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["DEGRADED", "FAULT_KINDS", "MODES", "NOMINAL", "SAFE", "Fault", "FaultSchedule", "Limits",
           "Telemetry", "imaging_allowed", "mode_for"]

NOMINAL, DEGRADED, SAFE = "NOMINAL", "DEGRADED", "SAFE"
MODES = (NOMINAL, DEGRADED, SAFE)
#: the fault kinds a scenario may inject (radio_off is refused at load: module docstring)
FAULT_KINDS = ("acs_stuck", "instrument_off", "store_full")


@dataclass(frozen=True)
class Limits:
    """The limit checks' thresholds (scenario ``[operations]``)."""

    pointing_error_max_deg: float = 5.0
    store_max_bundles: int = 100_000
    clock_late_max_s: float = 60.0


@dataclass(frozen=True)
class Telemetry:
    """What the satellite knows of itself at one step (its own housekeeping)."""

    acs_fault: bool = False
    instrument_fault: bool = False
    pointing_error_deg: float = 0.0
    store_bundles: int = 0
    clock_late_s: float = 0.0
    commanded_safe: bool = False


def mode_for(tm: Telemetry, lim: Limits) -> tuple[str, str]:
    """(mode, reason) by the table of the module docstring; reason "" for NOMINAL."""
    if tm.acs_fault:
        return SAFE, "acs_fault"
    if tm.pointing_error_deg > lim.pointing_error_max_deg:
        return SAFE, "pointing_error"
    if tm.commanded_safe:
        return SAFE, "commanded"
    if tm.instrument_fault:
        return DEGRADED, "instrument_fault"
    if tm.store_bundles >= lim.store_max_bundles:
        return DEGRADED, "store_full"
    if tm.clock_late_s > lim.clock_late_max_s:
        return DEGRADED, "clock_late"
    return NOMINAL, ""


def imaging_allowed(mode: str, reason: str) -> bool:
    """Whether the satellite may image and replan in ``mode`` entered for ``reason``."""
    return mode == NOMINAL or (mode == DEGRADED and reason in ("store_full", "clock_late"))


@dataclass(frozen=True)
class Fault:
    """One injected fault: ``kind`` (:data:`FAULT_KINDS`) on ``sat`` over [at_ns, until_ns)
    (until_ns None: to the end of the run)."""

    sat: str
    kind: str
    at_ns: int
    until_ns: int | None = None

    def active(self, t_ns: int) -> bool:
        return self.at_ns <= t_ns and (self.until_ns is None or t_ns < self.until_ns)


class FaultSchedule:
    """The faults of one satellite; which are active at a time, and the times they start or end
    (the satellite wakes up then, so a fault acts within the step it starts in)."""

    def __init__(self, faults):
        for f in faults:
            if f.kind not in FAULT_KINDS:
                raise ValueError(f"fault kind {f.kind!r}: expected one of {', '.join(FAULT_KINDS)}")
        self.faults = tuple(faults)

    def active(self, t_ns: int) -> frozenset[str]:
        return frozenset(f.kind for f in self.faults if f.active(t_ns))

    def next_change_ns(self, t_ns: int) -> int | None:
        ts = [x for f in self.faults for x in (f.at_ns, f.until_ns) if x is not None and x > t_ns]
        return min(ts) if ts else None
