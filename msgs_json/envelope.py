"""The lockstep contract every node logic follows, under both engines (docs/design.md sections 2-3).

A *participant* is one node's logic (a satellite, the DTN router, the ground station, ...): a
plain Python object with no rclpy in it. An engine drives all participants through the same
sequence of steps ``t_0 < t_1 < ...`` (integer ns since the scenario epoch):

* ``local`` engine: one process, an in-memory bus (bringup/engine/local.py);
* ``ros`` engine: one OS process per satellite, DDS in between, a clock node running the barrier
  (a step ends only when every participant acked it and all it sent was received;
  bringup/engine/ros/).

Rules, identical in both engines, which is what makes their runs equal:

1. At step k every participant's ``step(t_k, inbox)`` is called once. ``inbox`` holds every
   envelope on the participant's subscribed topics that was emitted during step k-1, sorted by
   ``(t_ns, source, seq)``. (Order between participants inside one step does not matter: nothing
   emitted in step k is seen before step k+1.) A participant whose ``event_driven`` attribute is
   True is called only at the steps where its inbox is not empty or its last wakeup is due
   (``next_wakeup_ns <= t_k``); at the others its last wakeup and ``in_flight`` stand. It declares
   so when a step with nothing for it could change nothing (a DTN-alone traffic node: thousands of
   steps, each for one or two of its 25 participants).
2. ``step`` returns a :class:`StepResult`: envelopes to emit (their ``t_ns`` is the exact event time
   and must be ``<= t_k``: a satellite that executed an observation at 12.3 s emits it at the step
   covering 12.3 s stamped 12.3 s), and the next time it needs to be woken (``None``: no need).
3. The engine picks ``t_{k+1} = min(next wakeups of all participants, t_k + max_step_ns,
   horizon_ns)``; it always advances by at least 1 ns. The last step is at ``horizon_ns``; then
   ``finish(horizon_ns)`` is called once and its envelopes are emitted (delivered to no one, but
   recorded).
4. ``seq`` is a per-source counter starting at 0, assigned by the engine in emission order.

Both engines check what a participant gives them, and choose the steps, with one module
(bringup/engine/contract.py): a participant that breaks these rules fails the same way under either.

Envelope payloads are JSON text (msgs_json schemas) or raw bytes (BPv7 bundles); the topic decides
which (msgs_json/topics.py). On DDS and in the bag both travel as the wire envelope of
msgs_json/wire.py on std_msgs/msg/String (bytes base64-encoded), so every record carries its
exact t_ns, source and seq.

Checked by tests/unit/test_local_engine.py and tests/unit/test_contract.py (the step and
delivery rules, on toy participants, by hand) and tests/ros/test_lockstep.py (the same under ROS).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple, Protocol, runtime_checkable

__all__ = ["Emit", "Envelope", "LiveState", "Participant", "StepResult"]


class Envelope(NamedTuple):
    """One message on the bus: exact event time, who sent it, its per-source number, where, what.

    Immutable (a named tuple: ~450k of them per paper run, made 3x faster than a frozen dataclass)."""

    t_ns: int
    source: str
    seq: int
    topic: str
    data: str | bytes

    def sort_key(self) -> tuple[int, str, int]:
        return (self.t_ns, self.source, self.seq)


class Emit(NamedTuple):
    """An envelope a participant wants sent; the engine adds source and seq. Immutable."""

    topic: str
    data: str | bytes
    t_ns: int


@dataclass(slots=True)
class StepResult:
    """What ``start``/``step`` return: envelopes to emit, when to be woken next (None: no need), and
    optionally how many items the participant holds to emit later (``in_flight``, e.g. bundle
    copies still travelling in the ISL medium): engines show the sum in their progress, nothing else."""

    emits: list[Emit] = field(default_factory=list)
    next_wakeup_ns: int | None = None
    in_flight: int | None = None


@dataclass(frozen=True, slots=True)
class LiveState:
    """What a participant shows while a run goes on: the optional ``live_state(t_ns)`` returns it (or
    None) and the ROS engine publishes it every visualisation period (``[viz] period_s``): a
    sensor_msgs/NavSatFix of ``position_ecef_km`` (None: the participant has no position) and one
    diagnostic_msgs/DiagnosticStatus with ``values`` (name -> int, float or str: counters, current
    target, ...), ``level`` (0 ok, 1 warn, 2 error, DiagnosticStatus's levels) and ``message`` (one
    line). Asking for it changes nothing in the participant."""

    position_ecef_km: tuple[float, float, float] | None = None
    values: dict[str, int | float | str] = field(default_factory=dict)
    level: int = 0
    message: str = ""


@runtime_checkable
class Participant(Protocol):
    """What an engine needs from one node's logic (optionally also ``event_driven = True``: rule 1)."""

    name: str

    def subscriptions(self) -> list[str]:
        """Exact topic names this participant reads (fixed for the whole run)."""
        ...

    def start(self, t0_ns: int) -> StepResult:
        """Called once before step 0 (its emits are delivered at step 0)."""
        ...

    def step(self, t_ns: int, inbox: list[Envelope]) -> StepResult:
        ...

    def finish(self, t_ns: int) -> list[Emit]:
        ...
