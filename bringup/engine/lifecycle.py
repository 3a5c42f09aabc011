"""The managed-node life cycle both engines drive (ROS 2 node lifecycle design, lifecycle_msgs).

Every participant of a run is a managed node with the ROS 2 states and transitions: primary states
``unconfigured``, ``inactive``, ``active``, ``finalized``; transitions ``configure`` (unconfigured ->
inactive), ``activate`` (inactive -> active), ``deactivate`` (active -> inactive), ``cleanup``
(inactive -> unconfigured) and ``shutdown`` (any of the first three -> finalized). A transition runs
its hook in the intermediate state (``configuring``, ...): success reaches the goal, failure
returns to the start state, an error (the hook raised) goes through ``errorprocessing`` (the
``error`` hook: success -> unconfigured, else finalized). Ids and labels are lifecycle_msgs' (State,
Transition), so a state here and a ``<node>/get_state`` answer of an rclpy LifecycleNode compare
as they are.

:class:`Lifecycle` is one node's machine, used as is by the local engine (bringup/engine/local.py:
configure and activate every participant before ``start``, deactivate after ``finish``, cleanup and
shutdown when the run releases them); the ROS engine's nodes use rclpy's LifecycleNode (the rcl
state machine, bringup/engine/ros/host.py) and its manager plans its service calls with
:func:`bring_up_path` / :func:`shut_down_path` (bringup/engine/ros/lifecycle_manager.py). A
transition that is not available in the current state is refused (:class:`LifecycleError`, one
line naming the node, the transition and what is available), never ignored.

:class:`Deferred` is a participant not built yet: a name and a ``build()`` the ROS host calls in the
node's ``on_configure`` (the scenario's satellites: their planner and bundle store are made there).

Oracle: the transition table is rcl_lifecycle's, the one rclpy's LifecycleNode serves:
tests/ros/test_lifecycle_run.py compares :func:`available` with ``get_available_transitions`` of a
live node in every primary state; tests/unit/test_lifecycle.py walks every transition, failure
and error path, and the refusals.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

__all__ = ["ACTIVE", "FINALIZED", "INACTIVE", "STATE_IDS", "TRANSITION_IDS", "UNCONFIGURED", "Deferred",
           "Lifecycle", "LifecycleError", "available", "bring_up_path", "goal_of", "shut_down_path"]

UNCONFIGURED, INACTIVE, ACTIVE, FINALIZED = "unconfigured", "inactive", "active", "finalized"
# lifecycle_msgs/msg/State ids
STATE_IDS = {UNCONFIGURED: 1, INACTIVE: 2, ACTIVE: 3, FINALIZED: 4, "configuring": 10, "cleaningup": 11,
             "shuttingdown": 12, "activating": 13, "deactivating": 14, "errorprocessing": 15}

# (start state, transition label) -> (lifecycle_msgs/msg/Transition id, intermediate state, goal state)
_TABLE: dict[tuple[str, str], tuple[int, str, str]] = {
    (UNCONFIGURED, "configure"): (1, "configuring", INACTIVE),
    (INACTIVE, "cleanup"): (2, "cleaningup", UNCONFIGURED),
    (INACTIVE, "activate"): (3, "activating", ACTIVE),
    (ACTIVE, "deactivate"): (4, "deactivating", INACTIVE),
    (UNCONFIGURED, "shutdown"): (5, "shuttingdown", FINALIZED),
    (INACTIVE, "shutdown"): (6, "shuttingdown", FINALIZED),
    (ACTIVE, "shutdown"): (7, "shuttingdown", FINALIZED),
}
TRANSITION_IDS = {key: v[0] for key, v in _TABLE.items()}

_UP = {UNCONFIGURED: ("configure", "activate"), INACTIVE: ("activate",), ACTIVE: ()}
_DOWN = {ACTIVE: ("deactivate", "cleanup", "shutdown"), INACTIVE: ("cleanup", "shutdown"),
         UNCONFIGURED: ("shutdown",), FINALIZED: ()}


class LifecycleError(RuntimeError):
    """A transition refused (not available in the state) or a hook that failed; one line."""


def available(state: str) -> list[str]:
    """The transitions a node in primary state ``state`` accepts (rcl_lifecycle's order)."""
    return [label for (s, label) in _TABLE if s == state]


def goal_of(state: str, label: str) -> str:
    """The state transition ``label`` from ``state`` reaches on success (LifecycleError: not available)."""
    entry = _TABLE.get((state, label))
    if entry is None:
        raise LifecycleError(f"transition {label!r} is not available in state {state!r}")
    return entry[2]


def bring_up_path(state: str) -> tuple[str, ...]:
    """Transitions from ``state`` to ``active`` (none from ``finalized``: LifecycleError)."""
    if state not in _UP:
        raise LifecycleError(f"no way from state {state!r} to 'active'")
    return _UP[state]


def shut_down_path(state: str) -> tuple[str, ...]:
    """Transitions from ``state`` to ``finalized``: deactivate -> cleanup -> shutdown as far as needed."""
    if state not in _DOWN:
        raise LifecycleError(f"no way from state {state!r} to 'finalized'")
    return _DOWN[state]


@dataclass(frozen=True)
class Deferred:
    """A participant built in its node's ``on_configure``: ``build()`` returns it."""

    name: str
    build: Callable[[], object]


Hook = Callable[[], "bool | None"]


class Lifecycle:
    """One managed node's state machine. ``hooks`` maps ``configure``, ``activate``, ``deactivate``,
    ``cleanup``, ``shutdown`` and ``error`` to callables: returning ``False`` is a failure (back to
    the start state), raising is an error (``errorprocessing``, then the ``error`` hook), anything
    else a success. A missing hook succeeds."""

    def __init__(self, name: str, hooks: dict[str, Hook] | None = None):
        self.name = name
        self.hooks = dict(hooks or {})
        self.state = UNCONFIGURED
        self.last_error = ""  # the error of the last transition, when its hook raised

    def available(self) -> list[str]:
        return available(self.state)

    def trigger(self, label: str) -> bool:
        """Run transition ``label``; True when its goal is reached, False when its hook failed
        (back to the start state, or through errorprocessing). A transition not available in the
        current state raises :class:`LifecycleError`."""
        entry = _TABLE.get((self.state, label))
        if entry is None:
            raise LifecycleError(f"node {self.name}: transition {label!r} is not available in state "
                                 f"{self.state!r} (available: {', '.join(self.available()) or 'none'})")
        _tid, middle, goal = entry
        start = self.state
        self.last_error = ""
        self.state = middle
        try:
            ok = self._call(label)
        except Exception as exc:  # noqa: BLE001 - a hook's error is the transition's result
            self.last_error = f"{type(exc).__name__}: {exc}"
            self.state = "errorprocessing"
            try:
                recovered = self._call("error")
            except Exception:  # noqa: BLE001 - an error while processing an error: finalized
                recovered = False
            self.state = UNCONFIGURED if recovered is not False else FINALIZED
            return False
        if ok is False:
            self.state = start
            return False
        self.state = goal
        return True

    def change(self, label: str) -> None:
        """:meth:`trigger`, with a failed hook raised as :class:`LifecycleError` naming the node,
        the transition and the state it left the node in."""
        start = self.state
        if not self.trigger(label):
            why = f": {self.last_error}" if self.last_error else ""
            raise LifecycleError(f"node {self.name}: transition {label!r} failed in state {start!r} "
                                 f"(now {self.state!r}){why}")

    def _call(self, label: str):
        hook = self.hooks.get(label)
        return None if hook is None else hook()
