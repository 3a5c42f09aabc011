"""The managed-node state machine both engines drive (bringup/engine/lifecycle.py) and the local
engine's use of it (bringup/engine/local.py).

Oracle: the ROS 2 managed-node design as lifecycle_msgs numbers it (State / Transition ids, written
out here by hand from the message definitions) - every transition from every primary state, the
failure path back to the start state, the error path through errorprocessing - and the refusal
of every transition a state does not offer. tests/ros/test_lifecycle_run.py checks the same table
against rcl_lifecycle on a live node.
"""

from __future__ import annotations

import pytest

from bringup.engine.contract import EngineError
from bringup.engine.lifecycle import (
    STATE_IDS,
    TRANSITION_IDS,
    Lifecycle,
    LifecycleError,
    available,
    bring_up_path,
    shut_down_path,
)
from bringup.engine.local import LocalEngine
from msgs_json.envelope import Emit, StepResult

ALL = ("configure", "activate", "deactivate", "cleanup", "shutdown")


def test_ids_are_lifecycle_msgs():
    # lifecycle_msgs/msg/State and Transition constants
    assert STATE_IDS["unconfigured"] == 1 and STATE_IDS["inactive"] == 2 and STATE_IDS["active"] == 3
    assert STATE_IDS["finalized"] == 4 and STATE_IDS["errorprocessing"] == 15
    assert TRANSITION_IDS == {("unconfigured", "configure"): 1, ("inactive", "cleanup"): 2,
                              ("inactive", "activate"): 3, ("active", "deactivate"): 4,
                              ("unconfigured", "shutdown"): 5, ("inactive", "shutdown"): 6,
                              ("active", "shutdown"): 7}


def test_the_full_cycle_and_every_refusal():
    calls = []
    lc = Lifecycle("sat_11", {k: (lambda k=k: calls.append(k)) for k in ALL})
    for label, goal in [("configure", "inactive"), ("activate", "active"), ("deactivate", "inactive"),
                        ("cleanup", "unconfigured"), ("configure", "inactive"), ("activate", "active"),
                        ("shutdown", "finalized")]:
        for bad in set(ALL) - set(lc.available()):
            with pytest.raises(LifecycleError, match=f"node sat_11: transition '{bad}' is not available in "
                                                     f"state '{lc.state}'"):
                lc.trigger(bad)
        assert lc.trigger(label) is True
        assert lc.state == goal
    assert calls == ["configure", "activate", "deactivate", "cleanup", "configure", "activate", "shutdown"]
    assert lc.available() == []
    for label in ALL:  # finalized is final
        with pytest.raises(LifecycleError, match="available: none"):
            lc.trigger(label)


def test_failure_returns_to_the_start_state_and_error_goes_through_errorprocessing():
    lc = Lifecycle("ground_station", {"configure": lambda: False})
    assert lc.trigger("configure") is False and lc.state == "unconfigured"
    with pytest.raises(LifecycleError, match=r"node ground_station: transition 'configure' failed in state "
                                             r"'unconfigured' \(now 'unconfigured'\)$"):
        lc.change("configure")

    def boom():
        raise OSError("store folder is read-only")

    lc = Lifecycle("sat_12", {"configure": boom})
    with pytest.raises(LifecycleError, match="now 'unconfigured'.*OSError: store folder is read-only"):
        lc.change("configure")  # on_error succeeded (no hook): back to unconfigured
    lc = Lifecycle("sat_13", {"configure": boom, "error": lambda: False})
    assert lc.trigger("configure") is False and lc.state == "finalized"  # on_error failed: finalized


def test_plans_up_and_down():
    assert bring_up_path("unconfigured") == ("configure", "activate")
    assert bring_up_path("active") == ()
    assert shut_down_path("active") == ("deactivate", "cleanup", "shutdown")
    assert shut_down_path("unconfigured") == ("shutdown",)
    with pytest.raises(LifecycleError):
        bring_up_path("finalized")
    # every plan is a chain of available transitions
    for start in ("unconfigured", "inactive", "active"):
        for plan in (bring_up_path(start), shut_down_path(start)):
            lc = Lifecycle("x")
            for label in bring_up_path("unconfigured")[: ("unconfigured", "inactive", "active").index(start)]:
                lc.change(label)
            for label in plan:
                assert label in available(lc.state)
                lc.change(label)


class _Part:
    def __init__(self, name, fail=None):
        self.name, self.fail, self.log = name, fail, []

    def subscriptions(self):
        return []

    def configure(self):
        self.log.append("configure")
        if self.fail == "configure":
            raise OSError(f"{self.name}: cannot open its store")

    def start(self, t0_ns):
        self.log.append("start")
        return StepResult([Emit("/x", "s", t0_ns)], None)

    def step(self, t_ns, inbox):
        self.log.append("step")
        return StepResult([], None)

    def finish(self, t_ns):
        self.log.append("finish")
        return []

    def close(self):
        self.log.append("close")


def test_local_engine_drives_every_participant_through_the_cycle():
    a, b = _Part("a"), _Part("b")
    eng = LocalEngine([a, b], horizon_ns=20, max_step_ns=10)
    eng.run()
    assert a.log == ["configure", "start", "step", "step", "step", "finish", "close"]
    assert [lc.state for lc in eng.lifecycles] == ["finalized", "finalized"]
    a, b = _Part("a"), _Part("b")
    eng = LocalEngine([a, b], horizon_ns=20, max_step_ns=10)
    eng.run(release=False)  # inactive, resources held: the caller releases them
    assert [lc.state for lc in eng.lifecycles] == ["inactive", "inactive"] and "close" not in a.log
    eng.release(workers=2)
    assert [lc.state for lc in eng.lifecycles] == ["finalized", "finalized"] and b.log[-1] == "close"


def test_local_engine_names_a_participant_that_fails_configure_and_starts_nothing():
    a, b = _Part("a"), _Part("b", fail="configure")
    with pytest.raises(EngineError, match="node b: transition 'configure' failed .*OSError: b: cannot open its store"):
        LocalEngine([a, b], horizon_ns=20, max_step_ns=10).run()
    assert "start" not in a.log and "start" not in b.log
