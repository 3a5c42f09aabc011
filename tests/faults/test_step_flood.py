"""A flood of replayed /sim/step messages (bringup/engine/ros/host.py ``_on_step`` and ``run``).

Genuine step messages of the run, recorded off the wire and sent again, carry a valid MAC, so the
gate lets them in. Tried against this branch before the fix: every replay was queued (the queue grew
with the flood), and every replay of the step last done made the host re-publish all that step's
envelopes and re-send its ack - one flood message, a whole step's traffic again.

Oracle: the host's own step handler and main loop (real Gate and sealed messages under one run key;
the host's ROS publishing replaced by counters), at step 10:

* 1000 replays of steps 0..9 are dropped on arrival: the queue stays empty, all 1000 counted stale;
* 500 replays of step 10 between steps 10 and 11 make one answer (not 500), the rest counted, and
  step 11 still runs exactly once, then the stop ends the host with 0;
* a re-announcement of the step done that comes after the rate limit (the restarted clock's,
  once a second) is answered again.
"""

from __future__ import annotations

import secrets
from collections import deque

import pytest

rclpy = pytest.importorskip("rclpy")

from rclpy.serialization import serialize_message
from std_msgs.msg import String

from bringup.engine.lockstep import STEP_TOPIC, Gate, StepMsg
from bringup.engine.ros import host as host_mod
from bringup.engine.ros.host import ParticipantHost

pytestmark = [pytest.mark.faults]


def _host(key: bytes) -> ParticipantHost:
    h = object.__new__(ParticipantHost)
    h.role, h.gate, h._steps = "sat_11", Gate(key, lambda _line: None), deque()
    h.done_k, h.last_ack, h.stale_steps, h._answered_at = 10, {"k": 10, "t_ns": 100}, 0, -float("inf")
    h.answers, h.ran = 0, []
    h._hello = lambda: None
    h._await_active = lambda: None  # its nodes already active (the lifecycle is tested in tests/ros)
    h._ready = lambda: None
    h._ack = lambda **kw: None

    def republish():
        h.answers += 1

    def run_step(m):
        h.ran.append(m.k)
        h.done_k = m.k

    h._republish_last, h._run_step = republish, run_step
    h._spin_until = lambda cond, *_a: None
    return h


def test_replayed_step_flood_is_dropped_and_answered_once(monkeypatch):
    key = secrets.token_bytes(32)
    clock = Gate(key, lambda _line: None)
    h = _host(key)

    def wire(**kw) -> bytes:  # what the raw step subscription hands the host: rclpy's serialized String
        return serialize_message(String(data=clock.sealed(STEP_TOPIC, StepMsg(**kw))))

    for i in range(1000):
        h._on_step(wire(k=i % 10, t_ns=i % 10))
    assert len(h._steps) == 0 and h.stale_steps == 1000
    for _ in range(500):
        h._on_step(wire(k=10, t_ns=100))
    h._on_step(wire(k=11, t_ns=110))
    h._on_step(wire(k=0, t_ns=0, stop=True))
    assert h.run() == 0
    assert h.answers == 1 and h.ran == [11]
    assert h.stale_steps == 1000 + 499
    # the restarted clock's re-announcement, a second later: answered
    monkeypatch.setattr(host_mod, "_ANSWER_AGAIN_S", 0.0)
    h._on_step(wire(k=11, t_ns=110))
    h._on_step(wire(k=0, t_ns=0, stop=True))
    assert h.run() == 0 and h.answers == 2
