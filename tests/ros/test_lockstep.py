"""The ROS engine's lockstep against the local engine (the oracle), over real DDS processes.

Toy participants (tests/ros/toy_participants.py) whose output hashes their inboxes run under the
launcher (clock + one process per role, unique ROS_DOMAIN_ID, loopback only); the envelopes
recorded in the MCAP bag must equal, field for field, those bringup/engine/local.py emits for
fresh copies of the same participants. A participant that stops answering is named.
"""

from __future__ import annotations

import time

import pytest

from bringup.engine.local import run_local
from bringup.engine.ros.launcher import launch
from bringup.engine.ros.run_spec import RunSpec
from bringup.recording.bag import BagReader
from tests.ros import toy_participants as toy
from tests.unit.test_contract import AT, EXPECTED, local_error

pytestmark = [pytest.mark.ros, pytest.mark.timeout(180)]
S = 10**9
KEY = bytes(range(32))


def _key(e):
    return (e.t_ns, e.source, e.seq, e.topic, e.data)


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


def test_slow_first_step_is_waited_for(tmp_path):
    """Step 0 includes the discovery of every data topic: its ack deadline is at least the clock's
    _FIRST_STEP_ACK_S (30 s), not the per-step 2 s, so a host 5 s slow in step 0 (its participants'
    start) is waited for; the same host 5 s slow at a later step is named (the per-step deadline
    still holds there)."""
    def run(at_ns):
        spec = RunSpec(factory="tests.ros.toy_participants:make", roles=toy.roles(3, pingpong=False),
                       horizon_ns=60 * S, max_step_ns=10 * S, ack_timeout_s=2.0,
                       extra={"n_counters": 3, "stall": {"role": "c1", "at_ns": at_ns, "sleep_s": 5.0}})
        return launch(spec, tmp_path / f"at{at_ns}")
    first = run(-1)
    assert first.ok, first.message
    later = run(30 * S)
    assert not later.ok and "c1" in later.message and "no ack" in later.message, later.message


def _activate(host) -> None:
    """Configure and activate the host's nodes (what the run's lifecycle manager does through their
    services, bringup/engine/ros/lifecycle_manager.py): their subscriptions exist from configure on."""
    from rclpy.lifecycle import TransitionCallbackReturn

    for slot in host.slots:
        assert slot.node.trigger_configure() == TransitionCallbackReturn.SUCCESS
        assert slot.node.trigger_activate() == TransitionCallbackReturn.SUCCESS


def test_bad_message_is_counted_not_fatal(monkeypatch):
    """A subscription callback (it gets the String's CDR bytes: a raw subscription) fed junk bytes,
    junk text, envelopes without a MAC or with a wrong one counts each by reason and keeps going (no
    exception escapes); only the run's own envelope is buffered."""
    from bringup.engine.ros.host import ParticipantHost
    from bringup.engine.ros.launcher import lease_domain_id
    from msgs_json.auth import RunAuth
    from msgs_json.envelope import Envelope
    from msgs_json.wire import encode_envelope, string_cdr

    def String(data: str) -> bytes:  # what the raw subscription hands the callback
        return string_cdr(data)

    good = Envelope(5, "ping", 0, "/toy/ping", "{}")
    with lease_domain_id() as lease:
        monkeypatch.setenv("ROS_DOMAIN_ID", str(lease.domain_id))
        host = ParticipantHost("pingpong", [toy.Ping(), toy.Pong()], run_key=KEY)
        try:
            _activate(host)
            box = host.slots[1].inboxes[0]  # pong's /toy/ping inbox
            cb = host._make_cb(box)
            cb(b"\x00\x01\x00\x00\xff\xff\x00\x00junk")  # not a String's CDR
            cb(String(data="not json"))
            cb(String(data='{"t_ns": -1, "src": "x", "seq": 0, "body": "{}"}'))
            cb(String(data=encode_envelope(good)))  # no MAC
            cb(String(data=encode_envelope(good, RunAuth(b"another run's key").mac(good))))
            cb(String(data=encode_envelope(good._replace(seq=1), RunAuth(KEY).mac(good))))  # MAC of another one
            cb(String(data=encode_envelope(good, RunAuth(KEY).mac(good))))
            assert host.gate.rejections.counts() == {"/toy/ping": {"bad_mac": 2, "malformed": 3, "unauthenticated": 1}}
            assert [e.seq for e in box.pending] == [0]
            assert box.ready({"ping": 0}) is True and box.expected == 0  # a later step's envelope is held
            box.expected = 1
            assert box.ready({"ping": 1}) and [e.t_ns for e in box.take({"ping": 1})] == [5]
        finally:
            host.close()


@pytest.mark.parametrize("kind", sorted(toy.BREAKS))
def test_contract_break_is_the_same_line_in_the_host_as_in_the_local_engine(monkeypatch, kind):
    """The ROS host checks with the same contract module as the local engine: breaking it the same
    way gives the same line (tests/unit/test_contract.py wrote the local engine's by hand)."""
    from bringup.engine.lockstep import StepMsg
    from bringup.engine.ros.host import HostError, ParticipantHost
    from bringup.engine.ros.launcher import lease_domain_id

    with lease_domain_id() as lease:
        monkeypatch.setenv("ROS_DOMAIN_ID", str(lease.domain_id))
        host = ParticipantHost("c1", [toy.Breaker(1, 3, kind, AT)], run_key=bytes(32))
        try:
            _activate(host)
            host._run_step(StepMsg(k=0, t_ns=0, start=True))
            host._run_step(StepMsg(k=1, t_ns=10 * S))
            with pytest.raises(HostError) as info:
                host._run_step(StepMsg(k=2, t_ns=AT))
        finally:
            host.close()
    assert str(info.value) == EXPECTED[kind] == str(local_error(kind))


def test_contract_break_ends_the_ros_run_naming_the_participant(tmp_path):
    spec = RunSpec(factory="tests.ros.toy_participants:make", roles=toy.roles(3, pingpong=False),
                   horizon_ns=60 * S, max_step_ns=10 * S,
                   extra={"n_counters": 3, "break": {"role": "c1", "kind": "negative_wakeup", "at_ns": AT}})
    res = launch(spec, tmp_path)
    assert not res.ok
    assert EXPECTED["negative_wakeup"] in res.message, res.message
