"""A replayed ack never rolls a host's rejection counts back (bringup/engine/ros/clock_node.py ``_on_ack``).

Against main 8408404 the clock stored an ack's ``rejected`` counts before its staleness check, so an
old ack of a host (a valid MAC: recorded off the wire and sent again) replaced the host's counts
with older, smaller ones, hiding what the host had rejected since from report.json ``security``.

Oracle: the clock's own ack handler, fed the run's genuinely sealed acks (the run key, the real
Gate) as they arrive in a run - step 5's ack with 3 rejections, then step 6's with 7 - then step 5's
replayed, then step 6's again, and an ack from step 7 before the clock is at step 7: the counts stay
those of the last ack the clock accepted (7), and the replays are counted as stale.
"""

from __future__ import annotations

import secrets

import pytest

rclpy = pytest.importorskip("rclpy")

from rclpy.serialization import serialize_message
from std_msgs.msg import String

from bringup.engine.lockstep import ACK_TOPIC, AckMsg, Gate
from bringup.engine.ros.clock_node import LockstepClock

pytestmark = [pytest.mark.faults]


def _clock(gate: Gate) -> LockstepClock:
    """The ack handler's state of a clock at step 6, without its ROS node (only _on_ack runs)."""
    c = object.__new__(LockstepClock)
    c.gate, c.roles, c.running, c.restart, c.bag = gate, ["sat_11"], True, False, None
    c.host_rejected, c.acks, c.hellos, c.rejoins, c.stale_acks = {}, {}, {}, [], 0
    return c


def test_replayed_ack_does_not_roll_rejections_back():
    key = secrets.token_bytes(32)
    host = Gate(key, lambda _line: None)
    clock = _clock(Gate(key, lambda _line: None))

    def wire(k: int, n: int) -> bytes:
        ack = AckMsg(participant="sat_11", k=k, t_ns=k * 10**10,
                     rejected={"/sat_11/observations": {"bad_mac": n}} if n else {})
        return serialize_message(String(data=host.sealed(ACK_TOPIC, ack)))

    step5, step6, step7 = wire(5, 3), wire(6, 7), wire(7, 9)
    clock.cur_k = 5
    clock._on_ack(step5)
    assert clock.host_rejected == {"sat_11": {"/sat_11/observations": {"bad_mac": 3}}}
    clock.acks.clear()
    clock.cur_k = 6
    clock._on_ack(step6)
    want = {"sat_11": {"/sat_11/observations": {"bad_mac": 7}}}
    assert clock.host_rejected == want
    clock._on_ack(step5)  # replayed: an old ack, a valid MAC
    assert clock.host_rejected == want and clock.stale_acks == 1
    clock._on_ack(step7)  # from a step the clock has not announced
    assert clock.host_rejected == want and clock.stale_acks == 2
    clock._on_ack(step6)  # the same ack again: recorded once
    assert clock.host_rejected == want
    assert clock.gate.rejections.counts() == {}  # (genuine acks: nothing rejected by the gate)
