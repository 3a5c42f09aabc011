"""The local engine against the lockstep rules of msgs_json/envelope.py, with toy participants."""

from __future__ import annotations

import pytest

from bringup.engine.local import EngineError, LocalEngine, run_local
from msgs_json.envelope import Emit, Envelope, Participant, StepResult

S = 1_000_000_000


class Recorder:
    """Records every call; emits what the test scripts for given step times."""

    def __init__(self, name, subs=(), script=None, wakeups=None, start_emits=(), finish_emits=()):
        self.name = name
        self.subs = list(subs)
        self.script = script or {}  # t_ns -> list[Emit]
        self.wakeups = wakeups or {}  # t_ns -> next wakeup
        self.start_emits = list(start_emits)
        self.finish_emits = list(finish_emits)
        self.calls: list[tuple[int, list[Envelope]]] = []
        self.started = self.finished = None

    def subscriptions(self):
        return self.subs

    def start(self, t0_ns):
        self.started = t0_ns
        return StepResult(list(self.start_emits), self.wakeups.get("start"))

    def step(self, t_ns, inbox):
        self.calls.append((t_ns, list(inbox)))
        return StepResult(list(self.script.get(t_ns, [])), self.wakeups.get(t_ns))

    def finish(self, t_ns):
        assert self.finished is None, "finish called twice"
        self.finished = t_ns
        return list(self.finish_emits)


class Echo:
    """Replies on /pong to every /ping at the step it receives it."""

    def __init__(self, name="echo"):
        self.name = name

    def subscriptions(self):
        return ["/ping"]

    def start(self, t0_ns):
        return StepResult()

    def step(self, t_ns, inbox):
        return StepResult([Emit("/pong", f"{e.source}:{e.data}", t_ns) for e in inbox])

    def finish(self, t_ns):
        return []


class Timer:
    """Pings every period_ns and wants to be woken exactly then."""

    def __init__(self, name, period_ns, subs=("/pong",)):
        self.name, self.period_ns, self.subs, self.n, self.seen = name, period_ns, list(subs), 0, []

    def subscriptions(self):
        return self.subs

    def start(self, t0_ns):
        self.next = t0_ns + self.period_ns
        return StepResult([], self.next)

    def step(self, t_ns, inbox):
        self.seen.extend((t_ns, e.data) for e in inbox)
        emits = []
        if t_ns >= self.next:
            emits.append(Emit("/ping", str(self.n), t_ns))
            self.n += 1
            self.next += self.period_ns
        return StepResult(emits, self.next)

    def finish(self, t_ns):
        return [Emit("/done", str(self.n), t_ns)]


def test_toys_are_participants():
    assert isinstance(Recorder("a"), Participant) and isinstance(Echo(), Participant)


def test_max_step_grid_and_finish_once():
    r = Recorder("r")
    res = run_local([r], horizon_ns=10 * S, max_step_ns=3 * S)
    assert [c[0] for c in r.calls] == [0, 3 * S, 6 * S, 9 * S, 10 * S]
    assert r.started == 0 and r.finished == 10 * S and res.steps == 5


def test_wakeup_choice_is_the_minimum_and_advances_at_least_1ns():
    a = Recorder("a", wakeups={"start": 2 * S, 2 * S: 7 * S, 7 * S: 7 * S})  # 7 s again: must still advance
    b = Recorder("b", wakeups={0: 5 * S, 2 * S: 4 * S})
    run_local([a, b], horizon_ns=20 * S, max_step_ns=6 * S)
    # only the latest StepResult counts: a's start wakeup (2 s) is superseded by its step-0 result
    # (None); b asks for 5 s; after that nobody asks, so max_step (6 s) rules, clipped at the horizon.
    times = [c[0] for c in a.calls]
    assert times == [0, 5 * S, 11 * S, 17 * S, 20 * S]
    assert [c[0] for c in b.calls] == times


def test_wakeup_exact_sequence():
    # explicit: wakeups returned at each step time
    a = Recorder("a", wakeups={0: 2 * S, 2 * S: 2 * S, 2 * S + 1: 9 * S})
    run_local([a], horizon_ns=10 * S, max_step_ns=5 * S)
    assert [c[0] for c in a.calls] == [0, 2 * S, 2 * S + 1, 7 * S + 1, 10 * S]


def test_delivery_next_step_only_and_ping_pong_timing():
    timer = Timer("timer", 3 * S)
    echo = Echo()
    res = run_local([echo, timer], horizon_ns=10 * S, max_step_ns=1 * S)
    # ping at 3 s -> echo sees it at 4 s, replies stamped 4 s -> timer sees it at 5 s
    assert timer.seen[0] == (5 * S, "timer:0")
    assert [t for t, _ in timer.seen] == [5 * S, 8 * S]
    pongs = [e for e in res.envelopes if e.topic == "/pong"]
    assert [(e.t_ns, e.source, e.seq) for e in pongs] == [(4 * S, "echo", 0), (7 * S, "echo", 1), (10 * S, "echo", 2)]
    # the ping of 9 s is answered at 10 s (last step): recorded though delivered to no one
    done = [e for e in res.envelopes if e.topic == "/done"]
    assert done == [Envelope(10 * S, "timer", 3, "/done", "3")]


def test_inbox_sorted_by_time_source_seq_and_filtered_by_subscription():
    t1 = 5 * S
    b = Recorder("b", script={t1: [Emit("/x", "b1", 3), Emit("/x", "b2", 1), Emit("/y", "by", 0)]})
    a = Recorder("a", script={t1: [Emit("/x", "a1", 3), Emit("/x", "a2", 3)]})
    sink = Recorder("zz", subs=["/x"])
    run_local([b, sink, a], horizon_ns=10 * S, max_step_ns=5 * S)
    inbox = dict(sink.calls)[10 * S]
    assert [(e.t_ns, e.source, e.seq, e.data) for e in inbox] == [
        (1, "b", 1, "b2"), (3, "a", 0, "a1"), (3, "a", 1, "a2"), (3, "b", 0, "b1")
    ]
    assert dict(sink.calls)[5 * S] == [] and dict(sink.calls)[0] == []


def test_start_emits_arrive_at_step_0():
    a = Recorder("a", start_emits=[Emit("/x", "hello", 0)])
    b = Recorder("b", subs=["/x"])
    run_local([a, b], horizon_ns=S, max_step_ns=S, t0_ns=0)
    assert [e.data for e in b.calls[0][1]] == ["hello"]


def test_participant_order_does_not_change_the_run():
    def build():
        return [Timer("t1", 3 * S), Timer("t2", 2 * S), Echo("e1"), Echo("e2")]

    r1 = run_local(build(), horizon_ns=30 * S, max_step_ns=7 * S).envelopes
    r2 = run_local(build()[::-1], horizon_ns=30 * S, max_step_ns=7 * S).envelopes
    assert r1 == r2 and len(r1) > 20
    seqs: dict[str, list[int]] = {}
    for e in r1:
        seqs.setdefault(e.source, []).append(e.seq)
    for s in seqs.values():
        assert sorted(s) == list(range(len(s)))


def test_sink_streams_and_counts():
    got = []
    clock = []
    res = run_local([Timer("t", S), Echo()], horizon_ns=5 * S, max_step_ns=S, sink=got.append, on_step=clock.append)
    assert res.envelopes == [] and len(got) == sum(res.counts_by_topic.values())
    assert clock == [0, S, 2 * S, 3 * S, 4 * S, 5 * S]
    assert res.counts_by_topic["/ping"] == 5


@pytest.mark.parametrize(
    "emit,where",
    [(Emit("/x", "late", 6 * S), "outside"), (Emit("/x", "neg", -1), "outside"),
     (Emit("/x", 123, 0), "int data"), ("notanemit", "expected Emit")],
)
def test_bad_emits_are_rejected_naming_the_participant(emit, where):
    a = Recorder("bad_sat", script={5 * S: [emit]})
    with pytest.raises(EngineError, match=f"bad_sat.*{where}"):
        run_local([a], horizon_ns=10 * S, max_step_ns=5 * S)


def test_failing_participant_is_named():
    class Boom(Recorder):
        def step(self, t_ns, inbox):
            raise KeyError("x")

    with pytest.raises(EngineError, match="boom failed in step"):
        run_local([Boom("boom")], horizon_ns=S, max_step_ns=S)


def test_bad_configuration():
    with pytest.raises(EngineError):
        LocalEngine([Recorder("a"), Recorder("a")], horizon_ns=S, max_step_ns=S)
    with pytest.raises(EngineError):
        LocalEngine([Recorder("a")], horizon_ns=S, max_step_ns=0)
    with pytest.raises(EngineError):
        LocalEngine([Recorder("a")], horizon_ns=S, max_step_ns=S, t0_ns=2 * S)


def test_progress_reports_final_state():
    seen = []
    run_local([Timer("t", S)], horizon_ns=4 * S, max_step_ns=S, progress=seen.append, progress_interval_s=0.0)
    assert seen[-1].t_ns == 4 * S and seen[-1].fraction == 1.0 and seen[-1].real_time_factor > 0
    assert [p.steps for p in seen] == sorted(p.steps for p in seen)
