"""The run's lifecycle manager: brings every participant node up and down through its services.

Lives in the clock process (bringup/engine/ros/clock_node.py), as node ``lifecycle_manager`` (under
the run's namespace), so it runs wherever the clock runs: launched by `constellation run`, in a
container, in a network namespace. It finds the run's managed nodes on the ROS graph (every
``<node>/change_state`` service of type lifecycle_msgs/srv/ChangeState: the participant nodes of
bringup/engine/ros/host.py) and, as a real client of their lifecycle services, asks each for its
state (``get_state``) and calls ``change_state`` along the shared plan (bringup/engine/lifecycle.py):
before step 0 configure -> activate for every node (a host says hello when all its nodes are
active, and the clock waits for every hello); after the run deactivate -> cleanup -> shutdown. The
calls go to every node at once (a process serves its nodes' one after the other). A transition a
node refuses or fails stops the run: :attr:`LifecycleManager.failure` names the node, the process
hosting it (from the run spec's groups) and the transition; the node's process log holds the cause.

Lost answers: a service may drop its response when it comes before the client's response reader
has matched its writer (rmw_fastrtps: "failed to send response (timeout)"; seen under heavy load),
so a call still unanswered after a while (``get_state`` :data:`_GET_S`, doubling while answers
keep missing; ``change_state`` :data:`_CHANGE_S`) is given up and the node's state asked again: the
plan goes on from the state the node reports (a transition it did make is not made twice; one still
running is answered for by the next ``get_state``, which its process serves after it). A transition
asked for :data:`_TRIES` times from the same state without an answer is a failure.

Oracle: tests/ros/test_lifecycle_run.py (a launched run: every participant node active, read by an
independent rclpy client through ``get_state`` while the run goes on, finalized at the end; a node
whose configure fails is named with its process and transition, and every process ends);
tests/ros/test_lifecycle_manager.py (answers dropped on purpose: the plan goes on from the state the
node reports, no transition made twice; a node that never answers is named).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

from lifecycle_msgs.srv import ChangeState, GetState

from bringup.engine.lifecycle import ACTIVE, FINALIZED, TRANSITION_IDS, bring_up_path, goal_of, shut_down_path

__all__ = ["LifecycleManager"]

_CHANGE_STATE = "lifecycle_msgs/srv/ChangeState"
_SUFFIX = "/change_state"
# wall seconds between two looks at the graph for new managed nodes
_POLL_S = 0.1
# wall seconds a call may stay unanswered before the node's state is asked again (a lost response):
# get_state first (doubled while its answers keep missing: a process answers its nodes' calls one
# after the other, behind a configure that may take seconds), change_state
_GET_S = 1.0
_GET_MAX_S = 8.0
_CHANGE_S = 3.0
# calls of one transition from one state before it counts as failed
_TRIES = 3


@dataclass
class _Managed:
    fqn: str
    get: object
    change: object
    state: str | None = None
    pending: tuple | None = None  # ("get", future) or ("change", label, future)
    since: float = 0.0  # (monotonic) when the pending call was made
    done: list[str] = field(default_factory=list)  # transitions done, in order
    tries: dict = field(default_factory=dict)  # (state, transition) -> calls made
    lost: int = 0  # calls given up unanswered
    get_s: float = field(default_factory=lambda: _GET_S)  # how long the next get_state may stay unanswered


class LifecycleManager:
    """Drives the managed nodes of the graph toward :attr:`goal` (``active``, then ``finalized``);
    :meth:`poll` advances them without blocking (the clock calls it while it spins)."""

    def __init__(self, node, process_of=lambda name: ""):
        self.node = node
        self.process_of = process_of  # node name -> the process role hosting it ("" unknown)
        self.nodes: dict[str, _Managed] = {}
        self.goal = ACTIVE
        self.failure = ""  # one line naming the node, its process and the transition
        self.failed: dict | None = None
        self._next_look = 0.0

    def _look(self) -> None:
        for name, types in self.node.get_service_names_and_types():
            if name.endswith(_SUFFIX) and _CHANGE_STATE in types:
                fqn = name[: -len(_SUFFIX)]
                if fqn not in self.nodes:
                    self.nodes[fqn] = _Managed(fqn, self.node.create_client(GetState, f"{fqn}/get_state"),
                                               self.node.create_client(ChangeState, f"{fqn}/change_state"))

    def poll(self) -> None:
        now = time.monotonic()
        if now >= self._next_look:
            self._next_look = now + _POLL_S
            self._look()
        if not self.failure:
            for m in self.nodes.values():
                self._advance(m)

    def at_goal(self, n: int | None = None) -> bool:
        """Every node found (at least ``n`` of them) is in :attr:`goal`."""
        return (n is None or len(self.nodes) >= n) and all(m.state == self.goal for m in self.nodes.values())

    def lost_answers(self) -> int:
        """Calls given up unanswered so far (all nodes)."""
        return sum(m.lost for m in self.nodes.values())

    def shut_down(self) -> None:
        """From now on drive every node to ``finalized`` (deactivate -> cleanup -> shutdown)."""
        self.goal = FINALIZED

    def _advance(self, m: _Managed) -> None:
        if m.pending is not None:
            fut = m.pending[-1]
            if not fut.done():
                getting = m.pending[0] == "get"
                if time.monotonic() - m.since < (m.get_s if getting else _CHANGE_S):
                    return
                # no answer: given up, the state asked again (below)
                (m.get if getting else m.change).remove_pending_request(fut)
                if getting:
                    m.get_s = min(2 * m.get_s, _GET_MAX_S)
                m.pending, m.state = None, None
                m.lost += 1
                fut = None
        if m.pending is not None:
            kind, *rest = m.pending
            m.pending = None
            res = fut.result()
            if kind == "get":
                m.state = res.current_state.label
                m.get_s = _GET_S
            elif res.success:
                m.state = goal_of(m.state, rest[0])
                m.done.append(rest[0])
            else:
                self._fail(m, rest[0])
                return
        if m.state is None:
            if m.get.service_is_ready():
                m.pending, m.since = ("get", m.get.call_async(GetState.Request())), time.monotonic()
            return
        path = bring_up_path(m.state) if self.goal == ACTIVE else shut_down_path(m.state)
        if not path or not m.change.service_is_ready():
            return
        key = (m.state, path[0])
        m.tries[key] = m.tries.get(key, 0) + 1
        if m.tries[key] > _TRIES:
            self._fail(m, path[0], f"; no answer to {_TRIES} calls")
            return
        req = ChangeState.Request()
        req.transition.id = TRANSITION_IDS[key]
        m.pending, m.since = ("change", path[0], m.change.call_async(req)), time.monotonic()

    def _fail(self, m: _Managed, label: str, why: str = "") -> None:
        name = m.fqn.rsplit("/", 1)[-1]
        proc = self.process_of(name)
        where = f" (process {proc})" if proc else ""
        self.failed = {"node": m.fqn, "process": proc, "transition": label, "state": m.state}
        self.failure = (f"lifecycle: node {m.fqn}{where} failed transition '{label}' in state '{m.state}'{why} "
                        f"(its cause is in {'logs/' + proc + '.log' if proc else 'its process log'})")
