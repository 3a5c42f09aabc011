"""The lifecycle manager's handling of lost answers (bringup/engine/ros/lifecycle_manager.py).

A service can drop its response (rmw_fastrtps: "failed to send response (timeout)" when the client's
response reader has not matched yet; seen on a 24-satellite run under a load of 55). Oracle: a fake
node whose service answers are dropped on purpose, with the transitions it really made counted: the
manager asks the state again and goes on from it (the configure the node made is not made twice);
a node that never answers is a named failure after the allowed calls.
"""

from __future__ import annotations

import pytest
from lifecycle_msgs.srv import ChangeState, GetState

import bringup.engine.ros.lifecycle_manager as lm
from bringup.engine.lifecycle import Lifecycle

pytestmark = [pytest.mark.ros]


class _Future:
    def __init__(self, result=None, done=False):
        self._result, self._done = result, done

    def done(self):
        return self._done

    def result(self):
        return self._result


class _Client:
    def __init__(self, server, kind):
        self.server, self.kind, self.removed = server, kind, 0

    def service_is_ready(self):
        return True

    def remove_pending_request(self, fut):
        self.removed += 1

    def call_async(self, req):
        return self.server.call(self.kind, req)


class _Server:
    """A managed node: a real state machine; ``drop`` = how many change answers it loses (after
    making the transition, or, with ``deaf``, without making it)."""

    def __init__(self, name, drop=0, deaf=False, drop_get=0):
        self.lc = Lifecycle(name)
        self.drop, self.deaf, self.made, self.drop_get = drop, deaf, [], drop_get

    def call(self, kind, req):
        if kind == "get" and self.drop_get > 0:
            self.drop_get -= 1
            return _Future()
        if kind == "get":
            resp = GetState.Response()
            resp.current_state.label = self.lc.state
            return _Future(resp, True)
        if self.deaf:
            return _Future()
        label = {1: "configure", 2: "cleanup", 3: "activate", 4: "deactivate", 5: "shutdown", 6: "shutdown",
                 7: "shutdown"}[req.transition.id]
        ok = self.lc.trigger(label)
        self.made.append(label)
        if self.drop > 0:
            self.drop -= 1
            return _Future()  # the node made the transition; its answer is lost
        resp = ChangeState.Response()
        resp.success = ok
        return _Future(resp, True)


class _Node:
    def __init__(self, servers):
        self.servers = servers

    def get_service_names_and_types(self):
        return [(f"/{n}/{n}/change_state", ["lifecycle_msgs/srv/ChangeState"]) for n in self.servers]

    def create_client(self, srv, name):
        n = name.split("/")[1]
        return _Client(self.servers[n], "get" if srv is GetState else "change")


def _drive(mgr, goal_n, rounds=200):
    for _ in range(rounds):
        mgr.poll()
        if mgr.failure or mgr.at_goal(goal_n):
            return


def test_a_lost_answer_is_recovered_from_the_state_and_nothing_is_made_twice(monkeypatch):
    monkeypatch.setattr(lm, "_CHANGE_S", 0.0)
    monkeypatch.setattr(lm, "_GET_S", 0.0)
    servers = {"sat_11": _Server("sat_11", drop=1), "sat_12": _Server("sat_12", drop_get=2)}
    mgr = lm.LifecycleManager(_Node(servers), process_of=lambda n: n)
    _drive(mgr, 2)
    assert not mgr.failure and mgr.at_goal(2)
    assert servers["sat_11"].made == servers["sat_12"].made == ["configure", "activate"]
    assert mgr.nodes["/sat_11/sat_11"].lost == 1 and mgr.nodes["/sat_12/sat_12"].lost == 2
    mgr.shut_down()
    servers["sat_12"].drop = 2
    _drive(mgr, 2)
    assert not mgr.failure and mgr.at_goal(2)
    assert servers["sat_12"].made[2:] == ["deactivate", "cleanup", "shutdown"]


def test_a_node_that_never_answers_is_named(monkeypatch):
    monkeypatch.setattr(lm, "_CHANGE_S", 0.0)
    monkeypatch.setattr(lm, "_GET_S", 0.0)
    servers = {"sat_21": _Server("sat_21", deaf=True)}
    mgr = lm.LifecycleManager(_Node(servers), process_of=lambda n: "sats_1")
    _drive(mgr, 1)
    assert mgr.failure.startswith("lifecycle: node /sat_21/sat_21 (process sats_1) failed transition 'configure' "
                                  "in state 'unconfigured'; no answer to 3 calls")
    assert mgr.failed == {"node": "/sat_21/sat_21", "process": "sats_1", "transition": "configure",
                          "state": "unconfigured"}
