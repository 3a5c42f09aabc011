"""The run's headline series in its bag, as numbers a plot reads: value so far and bundles in flight.

Data topics carry JSON in std_msgs/String, which Foxglove's Plot panel cannot read. Beside the
visualisation frames (bringup/recording/viz_feed.py), both engines' recorders write, every
``period_s`` of sim time (and at the last step):

* ``/viz/value`` (std_msgs/msg/Float64): the cumulative true value (the study's Eq. 1) of every
  observation executed so far, the figure report.json gives as ``value.cumulative`` at the end:
  the recorder passes each ``/<sat>/observations`` envelope to :meth:`MetricsFeed.observe` and the
  feed adds them in time order (ties: satellite, GP) to a :class:`sat_node.value.ValueLedger`, the
  report's own ledger. A point is written only when every observation up to that step is in
  (``complete``: always in the local engine's recorder; in the ROS clock, when its recorder holds
  as many observation envelopes as the hosts' acks counted) - never a value that a late envelope
  would change;
* ``/viz/bundles_in_flight`` (std_msgs/msg/UInt32): the bundle copies the ISL medium holds after the
  previous step (the figure of the progress line; none when the run has no ISL medium).

Log time and stamp: the step's t_ns, on the bag's clock (bringup/recording/bag.py).

Oracle: tests/unit/test_metrics_feed.py (the series' last value equals report.json's
``value.cumulative``; a point is withheld while an observation is missing; out-of-order arrival
within a step gives the same series).
"""

from __future__ import annotations

import struct

from msgs_json import codec
from msgs_json import schemas as S
from msgs_json.codec import MessageError
from msgs_json.envelope import Envelope
from msgs_json.topics import VIZ_IN_FLIGHT, VIZ_VALUE
from sat_node.value import ValueLedger

__all__ = ["FLOAT64", "UINT32", "MetricsFeed"]

FLOAT64 = "std_msgs/msg/Float64"
UINT32 = "std_msgs/msg/UInt32"
_CDR_F64 = struct.Struct("<4sd")  # CDR header, float64 (aligned from the body start)
_CDR_U32 = struct.Struct("<4sI")
_CDR_LE = b"\x00\x01\x00\x00"
_NS = 1_000_000_000


class MetricsFeed:
    def __init__(self, revisit_zero_s: float, period_s: float = 60.0):
        self.ledger = ValueLedger(revisit_zero_s)
        self.period_ns = int(round(period_s * _NS))
        self._pending: list[S.Observation] = []
        self.next_value_ns = 0
        self.next_flight_ns = 0
        self.written = 0
        self.rejected = 0  # observation payloads that did not decode (the report counts them too)

    def observe(self, env: Envelope) -> None:
        """An envelope the recorder got on a ``*/observations`` topic (others are ignored)."""
        if env.topic.endswith("/observations"):
            try:
                self._pending.append(codec.decode_as(S.Observation, env.data, env.topic))
            except MessageError:
                self.rejected += 1

    def write(self, bag, t_ns: int, *, in_flight: int | None = None, complete: bool = True, final: bool = False) -> int:
        """The series points due at step ``t_ns``; returns how many were written."""
        n = 0
        if complete and self._pending:
            for o in sorted(self._pending, key=lambda o: (o.t_ns, o.sat, o.gp)):
                self.ledger.add(o.gp, o.t_ns, o.recorded_value)
            self._pending.clear()
        if complete and (final or t_ns >= self.next_value_ns):
            bag.write_raw(VIZ_VALUE, FLOAT64, _CDR_F64.pack(_CDR_LE, self.ledger.total), t_ns)
            self.next_value_ns = (t_ns // self.period_ns + 1) * self.period_ns
            n += 1
        if in_flight is not None and (final or t_ns >= self.next_flight_ns):
            bag.write_raw(VIZ_IN_FLIGHT, UINT32, _CDR_U32.pack(_CDR_LE, int(in_flight)), t_ns)
            self.next_flight_ns = (t_ns // self.period_ns + 1) * self.period_ns
            n += 1
        self.written += n
        return n
