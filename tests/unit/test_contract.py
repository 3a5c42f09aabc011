"""The engine contract (bringup/engine/contract.py) under the local engine.

Oracle: each way of breaking the contract (tests/ros/toy_participants.py BREAKS) ends a local run
with one line naming the participant, the call and what is wrong, written here by hand; the ROS
engine's host gives the same line (tests/ros/test_lockstep.py). The step rule against hand-worked
cases.
"""

from __future__ import annotations

import pytest

from bringup.engine.contract import (
    ContractError,
    EngineError,
    check_emits,
    check_names,
    check_result,
    check_subscriptions,
    next_step_ns,
)
from bringup.engine.local import run_local
from msgs_json.envelope import Emit, StepResult
from tests.ros import toy_participants as toy

S = 10**9
AT = 20 * S

# what the local engine says, by hand, when counter c1 breaks the contract at 20 s
EXPECTED = {
    "negative_wakeup": f"c1 step at {AT}: next_wakeup_ns must be an int >= 0 or None, got -5",
    "bool_wakeup": f"c1 step at {AT}: next_wakeup_ns must be an int >= 0 or None, got True",
    "float_wakeup": f"c1 step at {AT}: next_wakeup_ns must be an int >= 0 or None, got {AT + 0.5!r}",
    "future_emit": f"c1 step at {AT}: emit on /toy/x at t_ns={AT + 1} outside [0, {AT}]",
    "negative_stamp": f"c1 step at {AT}: emit on /toy/x at t_ns=-1 outside [0, {AT}]",
    "int_data": f"c1 step at {AT}: emit on /toy/x has int data, expected str or bytes",
    "relative_topic": f"c1 step at {AT}: emit topic 'toy/x' is not a name starting with '/'",
    "not_an_emit": f"c1 step at {AT}: emitted tuple, expected Emit",
    "negative_in_flight": f"c1 step at {AT}: in_flight must be an int >= 0 or None, got -1",
    "not_a_step_result": f"c1 step at {AT}: returned tuple, expected StepResult",
    "raises": f"c1 failed in step at {AT}: KeyError: 'missing key'",
}


def local_error(kind: str) -> EngineError:
    """The error of a local run of three counters where c1 breaks the contract (``kind``) at 20 s."""
    parts = [toy.Counter(0, 3), toy.Breaker(1, 3, kind, AT), toy.Counter(2, 3)]
    with pytest.raises(EngineError) as info:
        run_local(parts, horizon_ns=60 * S, max_step_ns=10 * S)
    return info.value


def test_every_break_has_an_expected_line():
    assert set(EXPECTED) == set(toy.BREAKS)


@pytest.mark.parametrize("kind", sorted(toy.BREAKS))
def test_break_is_one_line_naming_the_participant(kind):
    err = local_error(kind)
    assert str(err) == EXPECTED[kind]
    assert isinstance(err, ContractError) == (kind != "raises")


def test_start_and_finish_are_checked_too():
    class BadStart(toy.Counter):
        def start(self, t0_ns):
            return StepResult([Emit("/toy/x", "{}", t0_ns + 1)], None)

    class BadFinish(toy.Counter):
        def finish(self, t_ns):
            return [Emit("/toy/x", b"", t_ns + 1)]

    with pytest.raises(ContractError, match=r"^c0 start at 0: emit on /toy/x at t_ns=1 outside \[0, 0\]$"):
        run_local([BadStart(0, 1)], horizon_ns=10 * S, max_step_ns=S)
    with pytest.raises(ContractError, match=rf"^c0 finish at {10 * S}: emit on /toy/x at t_ns={10 * S + 1} outside"):
        run_local([BadFinish(0, 1)], horizon_ns=10 * S, max_step_ns=S)


def test_names_and_subscriptions():
    assert check_names([toy.Ping(), toy.Pong()]) == ["ping", "pong"]
    for bad in ([toy.Ping(), toy.Ping()], [], [toy.Counter(0, 1), type("X", (), {"name": ""})()]):
        with pytest.raises(ContractError, match="participant names must be unique non-empty strings"):
            check_names(bad)
    assert check_subscriptions("p", ["/a", "/b", "/a"]) == ["/a", "/b"]
    with pytest.raises(ContractError, match=r"^p subscriptions: topic 'a' is not a name starting with '/'$"):
        check_subscriptions("p", ["/b", "a"])
    with pytest.raises(ContractError, match="expected a list of topic names, got str"):
        check_subscriptions("p", "/a")


def test_checks_accept_what_the_contract_allows():
    r = StepResult([Emit("/a", "x", 0), Emit("/b", b"y", 5)], 0, 3)
    assert check_result("p", r, "step at 5") is r
    assert check_emits("p", r.emits, 5, "step at 5") == r.emits
    assert check_emits("p", None, 5, "finish at 5") == [] and check_emits("p", (), 5, "finish at 5") == []
    assert check_emits("p", (e for e in r.emits), 5, "finish at 5") == r.emits
    with pytest.raises(ContractError, match="emits must be a list of Emit, got Emit"):
        check_emits("p", Emit("/a", "x", 0), 5, "finish at 5")


def test_step_rule():
    assert next_step_ns(0, [None, 5 * S, 3 * S], 10 * S, 60 * S) == 3 * S
    assert next_step_ns(0, [None], 10 * S, 60 * S) == 10 * S
    assert next_step_ns(0, [], 10 * S, 60 * S) == 10 * S
    assert next_step_ns(55 * S, [None], 10 * S, 60 * S) == 60 * S
    assert next_step_ns(55 * S, [70 * S], 10 * S, 60 * S) == 60 * S  # never past the horizon
    assert next_step_ns(7, [7, 2], 10 * S, 60 * S) == 8  # always at least 1 ns forward
    assert next_step_ns(7, [0], 10 * S, 60 * S) == 8


def test_event_driven_participant_is_called_only_for_an_inbox_or_a_due_wakeup():
    """Ping emits at 0, 7.3, 14.6, ... s; the event-driven listener wakes every 13 s: it is called at
    13, 26, ... and at the step after each ping (its inbox), nowhere else, although the engine steps
    every 7.3 s, every 13 s and every 5 s (the timer beside it, and the max step)."""
    listener, ping, timer = toy.Listener(), toy.Ping(), toy.Counter(0, 1, blob_every=0, period_s=5.0)
    res = run_local([ping, listener, timer], horizon_ns=60 * S, max_step_ns=5 * S)
    steps = sorted({*range(0, 61 * S, 5 * S), *range(0, 61 * S, 13 * S), *range(0, 61 * S, 7_300_000_000)})
    assert res.steps == len(steps)
    pings = list(range(0, 60 * S, 7_300_000_000))
    after_ping = {steps[steps.index(t) + 1] for t in pings}
    assert listener.calls == sorted(after_ping | set(range(13 * S, 60 * S, 13 * S)))
    assert listener.heard == len(pings) == 9 and len(listener.calls) == 11 < res.steps == 25


def test_live_state_is_checked():
    from bringup.engine.contract import check_live_state
    from msgs_json.envelope import LiveState

    assert check_live_state("sat_11", None, "live_state at 0") is None
    ok = LiveState((7000.0, 0, 1.5), {"observations": 3, "target": "gp 7", "ratio": 0.5}, 1, "fine")
    assert check_live_state("sat_11", ok, "live_state at 0") is ok
    bad = [
        ({"x": 1}, "expected LiveState"),
        (LiveState((1.0, 2.0)), "3 finite numbers"),
        (LiveState((1.0, float("nan"), 2.0)), "3 finite numbers"),
        (LiveState(values={"": 1}), "not a name"),
        (LiveState(values={"a": [1]}), "not a name"),
        (LiveState(level=3), "level must be"),
        (LiveState(message=None), "message must be"),
    ]
    for s, why in bad:
        with pytest.raises(EngineError, match=f"^sat_11 live_state at 5: .*{why}"):
            check_live_state("sat_11", s, "live_state at 5")
