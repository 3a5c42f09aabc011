"""Participants in a worker process (bringup/worker_group.py) give the local engine exactly what they
give it in one process: the oracle is the one-process run of the same toy participants."""

from __future__ import annotations

import os

import pytest

from bringup.local_engine import EngineError, run_local
from bringup.worker_group import WorkerGroup
from msgs_json.envelope import Emit, StepResult

S = 1_000_000_000


class Chatter:
    """Emits on /c at its own period, echoes what it hears with its name, wakes at odd instants; its
    finish reports how many envelopes it saw (so the inboxes must match too)."""

    def __init__(self, name: str, period_ns: int, phase_ns: int):
        self.name, self.period, self.next, self.heard = name, period_ns, phase_ns, []

    def subscriptions(self):
        return ["/c", "/echo"]

    def start(self, t0_ns):
        return StepResult([Emit("/c", f"{self.name}:start", t0_ns)], self.next)

    def step(self, t_ns, inbox):
        self.heard.extend((t_ns, e.source, e.seq) for e in inbox)
        emits = [Emit("/echo", f"{self.name}<{e.source}.{e.seq}", t_ns) for e in inbox if e.topic == "/c"][:3]
        if t_ns >= self.next:
            emits.append(Emit("/c", f"{self.name}@{t_ns}".encode(), t_ns - 1 if t_ns else 0))
            self.next += self.period
        return StepResult(emits, self.next)

    def finish(self, t_ns):
        return [Emit("/done", f"{self.name}:{len(self.heard)}:{hash(tuple(self.heard)) & 0xffff}", t_ns)]


class Boom(Chatter):
    def step(self, t_ns, inbox):
        if t_ns >= 5 * S:
            raise RuntimeError("sensor on fire")
        return super().step(t_ns, inbox)


def _toys(names):
    return [Chatter(n, (i + 2) * S // 3, i * S // 7) for i, n in enumerate(names)]


NAMES = ["a", "b", "c", "d", "e"]


def _key(res):
    return [(e.t_ns, e.source, e.seq, e.topic, e.data) for e in res.envelopes]


@pytest.mark.parametrize("away", [["b", "d"], ["a", "b", "c", "d", "e"], ["e"]])
def test_worker_run_equals_one_process_run(away):
    one = run_local(_toys(NAMES), horizon_ns=20 * S, max_step_ns=2 * S)
    index = {n: i for i, n in enumerate(NAMES)}
    local = [p for p in _toys(NAMES) if p.name not in away]
    g = WorkerGroup(lambda: [_toys(NAMES)[index[n]] for n in away])
    try:
        assert g.names == away and g.subscriptions == [["/c", "/echo"]] * len(away)
        two = run_local(local, horizon_ns=20 * S, max_step_ns=2 * S, groups=[g])
    finally:
        g.close()
    assert two.steps == one.steps
    assert _key(two) == _key(one)  # same envelopes, same order, inboxes included (the /done counts)
    assert len(_key(one)) > 100


def test_two_groups_and_their_pipes():
    one = run_local(_toys(NAMES), horizon_ns=10 * S, max_step_ns=1 * S)
    index = {n: i for i, n in enumerate(NAMES)}
    g1 = WorkerGroup(lambda: [_toys(NAMES)[index["a"]]])
    g2 = WorkerGroup(lambda: [_toys(NAMES)[index[n]] for n in ("c", "e")], close_in_child=[g1.pipe])
    try:
        two = run_local([p for p in _toys(NAMES) if p.name in ("b", "d")], horizon_ns=10 * S, max_step_ns=1 * S,
                        groups=[g1, g2])
    finally:
        g1.close()
        g2.close()
    assert sorted(_key(two)) == sorted(_key(one)) and _key(two) == _key(one)


def test_a_failing_worker_participant_is_named_and_the_worker_ends():
    g = WorkerGroup(lambda: [Chatter("ok", S, 0), Boom("hot", S, 0)])
    try:
        with pytest.raises(EngineError, match=r"hot failed in step\(5000000000\): RuntimeError: sensor on fire"):
            run_local([Chatter("here", S, 0)], horizon_ns=10 * S, max_step_ns=S, groups=[g])
    finally:
        g.close(abandon=True)
    assert g._proc.exitcode == 0


def test_a_bad_result_or_emit_in_the_worker_is_rejected():
    class BadResult(Chatter):
        def step(self, t_ns, inbox):
            return "not a StepResult"

    class BadEmit(Chatter):
        def step(self, t_ns, inbox):
            return StepResult([("/c", "tuple, not Emit", t_ns)], None)

    for cls, msg in ((BadResult, "returned str, expected StepResult"), (BadEmit, "emitted tuple, expected Emit")):
        g = WorkerGroup(lambda cls=cls: [cls("bad", S, 0)])
        try:
            with pytest.raises(EngineError, match=f"bad failed in step.*{msg}"):
                run_local([], horizon_ns=3 * S, max_step_ns=S, groups=[g])
        finally:
            g.close(abandon=True)


def test_start_up_failure_and_closed_group():
    def make():
        raise OSError("no such store")

    with pytest.raises(Exception, match="worker failed in start-up: OSError: no such store"):
        WorkerGroup(make)
    g = WorkerGroup(lambda: [Chatter("x", S, 0)])
    g.close()
    g.close()  # idempotent
    with pytest.raises(Exception, match="already closed"):
        g.start(0)


def test_worker_exits_when_the_parent_end_closes():
    g = WorkerGroup(lambda: [Chatter("x", S, 0)])
    pid = g._proc.pid
    g._conn.close()  # as if this process had died: the child reads EOF
    g._proc.join(timeout=30)
    assert g._proc.exitcode == 0
    with pytest.raises(ProcessLookupError):
        os.kill(pid, 0)
