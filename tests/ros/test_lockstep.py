"""The ROS engine's lockstep against the local engine (the oracle), over real DDS processes.

Toy participants (tests/ros/toy_participants.py) whose output hashes their inboxes run under the
launcher (clock + one process per role, unique ROS_DOMAIN_ID, loopback only); the envelopes
recorded in the MCAP bag must equal, field for field, those bringup/engine/local.py emits for
fresh copies of the same participants. A participant that stops answering is named.
"""

from __future__ import annotations

import time

import pytest

from bringup.engine.ros.launcher import launch
from bringup.engine.local import run_local
from bringup.recording.bag import BagReader
from bringup.engine.ros.run_spec import RunSpec
from bringup.engine.lockstep import next_step_ns
from tests.ros import toy_participants as toy

pytestmark = [pytest.mark.ros, pytest.mark.timeout(180)]
S = 10**9


def _key(e):
    return (e.t_ns, e.source, e.seq, e.topic, e.data)


def test_next_step_rule3():
    assert next_step_ns(0, [None, 5 * S, 3 * S], 10 * S, 60 * S) == 3 * S
    assert next_step_ns(0, [None], 10 * S, 60 * S) == 10 * S
    assert next_step_ns(55 * S, [None], 10 * S, 60 * S) == 60 * S
    assert next_step_ns(7, [7, 2], 10 * S, 60 * S) == 8  # always at least 1 ns forward


def test_ros_engine_equals_local_engine(tmp_path):
    spec = RunSpec(factory="tests.ros.toy_participants:make", roles=toy.roles(3), horizon_ns=90 * S,
                   max_step_ns=10 * S, bag_dir=str(tmp_path / "bag"), extra={"n_counters": 3})
    res = launch(spec, tmp_path)
    assert res.ok, res.message

    ref = run_local(toy.all_participants(spec), horizon_ns=spec.horizon_ns, max_step_ns=spec.max_step_ns)
    with BagReader(tmp_path / "bag") as bag:
        topics = {t.topic: t.count for t in bag.topics()}
        got = list(bag.envelopes([t for t in topics if t.startswith("/toy/")]))
        clock_n = topics.get("/clock", 0)
    assert len(ref.envelopes) > 100  # the toy run is not trivial: pings, counts, blobs (bytes)
    assert any(isinstance(e.data, bytes) for e in ref.envelopes)
    assert sorted(map(_key, got)) == sorted(map(_key, ref.envelopes))
    assert clock_n == ref.steps == res.last.steps
    assert res.last.t_ns == spec.horizon_ns


def test_runs_are_repeatable_and_paced(tmp_path):
    """Same participants twice (second run paced at 100x real time): identical envelopes."""
    runs = []
    for i, rtf in enumerate((None, 100.0)):
        spec = RunSpec(factory="tests.ros.toy_participants:make", roles=toy.roles(2), horizon_ns=40 * S,
                       max_step_ns=10 * S, bag_dir=str(tmp_path / f"bag{i}"), extra={"n_counters": 2},
                       real_time_factor=rtf)
        res = launch(spec, tmp_path / f"run{i}")
        assert res.ok, res.message
        with BagReader(tmp_path / f"bag{i}") as bag:
            runs.append(sorted(map(_key, bag.envelopes([t.topic for t in bag.topics() if t.topic.startswith("/toy/")]))))
        if rtf:
            # 40 s of sim time at 100x cannot take less than 0.4 s of stepping
            assert res.last.wall_s >= 40 / rtf * 0.9
    assert runs[0] == runs[1]


def test_stalled_participant_is_named(tmp_path):
    spec = RunSpec(factory="tests.ros.toy_participants:make", roles=toy.roles(3, pingpong=False),
                   horizon_ns=600 * S, max_step_ns=10 * S, ack_timeout_s=2.0,
                   extra={"n_counters": 3, "stall": {"role": "c1", "at_ns": 30 * S}})
    t0 = time.monotonic()
    res = launch(spec, tmp_path)
    waited = time.monotonic() - t0
    assert not res.ok
    assert "c1" in res.message and "no ack" in res.message, res.message
    assert "c0" not in res.message.split("from", 1)[-1]  # only the silent one is blamed
    assert waited < 60  # bounded: ack timeout (2 s) + start-up + shutdown, not forever


def test_bad_message_is_counted_not_fatal(monkeypatch):
    """A subscription callback fed junk counts it and keeps going (no exception escapes)."""
    from std_msgs.msg import String

    from bringup.engine.ros.launcher import lease_domain_id
    from bringup.engine.ros.host import ParticipantHost

    with lease_domain_id() as lease:
        monkeypatch.setenv("ROS_DOMAIN_ID", str(lease.domain_id))
        host = ParticipantHost("pingpong", [toy.Ping(), toy.Pong()])
        try:
            box = host.slots[1].inboxes[0]  # pong's /toy/ping inbox
            cb = host._make_cb(box)
            cb(String(data="not json"))
            cb(String(data='{"t_ns": -1, "src": "x", "seq": 0, "body": "{}"}'))
            cb(String(data='{"t_ns": 5, "src": "ping", "seq": 0, "body": "{}"}'))
            assert box.decode_errors == 2 and host.decode_errors == {"/toy/ping": 2}
            assert [e.seq for e in box.pending] == [0]
            assert box.ready({"ping": 0}) is True and box.expected == 0  # a later step's envelope is held
            box.expected = 1
            assert box.ready({"ping": 1}) and [e.t_ns for e in box.take({"ping": 1})] == [5]
        finally:
            host.close()
