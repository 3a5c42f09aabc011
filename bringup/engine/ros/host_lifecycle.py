"""The life cycle of a host's participant nodes: each one an rclpy managed (lifecycle) node.

Every participant node of a host process (bringup/engine/ros/host.py) is an rclpy LifecycleNode with
the standard services (``<node>/get_state``, ``change_state``, ``get_available_states``,
``get_available_transitions``; the state machine of bringup/engine/lifecycle.py). The process starts
with its nodes ``unconfigured`` and nothing of their participants running; the run's lifecycle
manager (in the clock process, bringup/engine/ros/lifecycle_manager.py) calls their services:

- ``on_configure`` builds the participant (a :class:`~bringup.engine.lifecycle.Deferred` entry: the
  scenario's satellites, their planner and bundle store), creates its subscriptions and declares its
  parameters (the run settings);
- ``on_activate`` enables its (lifecycle) publishers and lets it take part in the lockstep: the host
  says hello once all its nodes are active;
- ``on_deactivate`` takes it out (a step that finds one of the host's nodes not active fails the
  host, named);
- ``on_cleanup`` and ``on_shutdown`` destroy its subscriptions and publishers and release the
  participant (``close()``: the bundle store).

A transition whose work raises is logged on stderr (the process's log) with its cause and answered
as a failure (the node stays in its state). A host started again after a crash sees the run's steps
already going while its nodes are unconfigured: no manager will come, so it brings its nodes up
itself, through the same transitions (rclpy's ``trigger_configure`` / ``trigger_activate``).

Oracle: tests/ros/test_lifecycle_run.py (every node active, read through get_state by a client of
the test; a node whose configure raises is named with its cause and the run ends).
"""

from __future__ import annotations

import sys
import time

from rclpy.lifecycle import LifecycleNode, TransitionCallbackReturn
from std_msgs.msg import String

from bringup.engine.contract import check_subscriptions, is_event_driven
from bringup.engine.lifecycle import ACTIVE, UNCONFIGURED, Deferred
from bringup.engine.lockstep import INTERRUPTED, TopicInbox
from bringup.engine.ros.live import declare_run_parameters
from bringup.engine.ros.naming import ros_topic_name
from msgs_json.envelope import Participant

__all__ = ["HostError", "HostLifecycle", "ManagedNode", "Slot"]


class HostError(RuntimeError):
    """The host cannot go on (protocol broken, participant failed, clock silent); one line."""


class Slot:
    """One participant with its node, inboxes, publishers and seq counter. ``p`` is None until
    the node is configured when the entry is :class:`Deferred` (built in ``on_configure``)."""

    def __init__(self, entry: Participant | Deferred, node: LifecycleNode):
        self.entry = entry
        self.p: Participant | None = None if isinstance(entry, Deferred) else entry
        self.name = entry.name
        self.node = node
        self.inboxes: list[TopicInbox] = []
        self.subs: list[object] = []  # the node's subscriptions (destroyed at cleanup)
        self.pubs: dict[str, object] = {}
        self.ros: dict[str, str] = {}  # logical topic -> the resolved name DDS carries
        self.seq = 0
        self.driven = False
        self.active = False
        self.declared = False  # the run's parameters (declared at the first configure)
        self.wake: int | None = None  # the last StepResult's wakeup and in_flight (they stand on a skipped step)
        self.flight: int | None = None


class ManagedNode(LifecycleNode):
    """A participant's node: its transitions call the host (:meth:`ParticipantHost._transition`),
    then rclpy's own handling of its managed entities (the lifecycle publishers)."""

    host: HostLifecycle
    slot: Slot

    def on_configure(self, state):
        return self.host._transition(self.slot, "configure", state, super().on_configure)

    def on_activate(self, state):
        return self.host._transition(self.slot, "activate", state, super().on_activate)

    def on_deactivate(self, state):
        return self.host._transition(self.slot, "deactivate", state, super().on_deactivate)

    def on_cleanup(self, state):
        return self.host._transition(self.slot, "cleanup", state, super().on_cleanup)

    def on_shutdown(self, state):
        return self.host._transition(self.slot, "shutdown", state, super().on_shutdown)


class HostLifecycle:
    """The part of bringup/engine/ros/host.py ParticipantHost that answers its nodes' transitions."""

    def _transition(self, slot: Slot, label: str, state, base) -> TransitionCallbackReturn:
        """Run transition ``label`` of ``slot``'s node: the host's part, then rclpy's (``base``:
        the lifecycle publishers enabled or disabled). What raises is logged with its cause and
        answered as a failure."""
        try:
            if label == "configure":
                self._configure(slot)
            elif label in ("deactivate", "shutdown") and slot.active:
                slot.active = False
                self.n_active -= 1
            r = base(state)
            if r != TransitionCallbackReturn.SUCCESS:
                return r
            if label == "activate":
                slot.active = True
                self.n_active += 1
            elif label in ("cleanup", "shutdown"):
                self._release(slot)
            return r
        except Exception as exc:  # noqa: BLE001 - a failed transition is answered, never fatal here
            print(f"host {self.role}: error: node {slot.name}: transition '{label}' failed: "
                  f"{type(exc).__name__}: {exc}", file=sys.stderr, flush=True)
            if label == "configure":
                self._release(slot)
            return TransitionCallbackReturn.FAILURE

    def _configure(self, slot: Slot) -> None:
        """The participant built (a Deferred entry), its subscriptions created, its parameters declared."""
        if slot.p is None:
            p = slot.entry.build()
            if getattr(p, "name", None) != slot.name:
                raise HostError(f"the factory built {getattr(p, 'name', None)!r} for node {slot.name!r}")
            slot.p = p
        p = slot.p
        topics = check_subscriptions(p.name, p.subscriptions())
        slot.driven = is_event_driven(p)
        node = slot.node
        if not slot.declared:
            prm = self.parameters
            declare_run_parameters(node, prm(p.name) if callable(prm) else (prm or {}))
            slot.declared = True
        for topic in topics:
            box = TopicInbox(topic)
            slot.subs.append(node.create_subscription(String, ros_topic_name(topic, p.name), self._make_cb(box),
                                                      self.QOS_DATA, raw=True))
            slot.inboxes.append(box)
            self.inboxes_by_topic.setdefault(self._resolved(slot, topic), []).append(box)

    def _release(self, slot: Slot) -> None:
        """Undo :meth:`_configure`: subscriptions and publishers destroyed, the participant closed
        (its bundle store) and, when it was built at configure, dropped."""
        node = slot.node
        for sub in slot.subs:
            node.destroy_subscription(sub)
        for pub in slot.pubs.values():
            node.destroy_lifecycle_publisher(pub)
        for box in slot.inboxes:
            boxes = self.inboxes_by_topic.get(self._resolved(slot, box.topic), [])
            if box in boxes:
                boxes.remove(box)
        slot.subs, slot.pubs, slot.inboxes = [], {}, []
        p = slot.p
        if p is not None and callable(getattr(p, "close", None)):
            p.close()
        if isinstance(slot.entry, Deferred):
            slot.p = None

    def _await_active(self) -> int | None:
        """Serve the lifecycle services until every node is active. A stop from the clock first
        (the run ended before it started: a node of another process failed its transition) returns
        the exit code. A step of the run already going (this host was started again after a crash:
        no manager will come) makes the host bring its nodes up itself, through the same transitions."""
        bound = float("inf") if self.first_step_timeout_s is None else self.first_step_timeout_s
        deadline = time.monotonic() + bound
        while self.n_active < len(self.slots):
            if self._stop_requested:
                raise KeyboardInterrupt
            if self._steps and self._steps[0].stop:
                m = self._steps.popleft()
                print(f"host {self.role}: stopped by the clock before its nodes were active: {m.reason}",
                      file=sys.stderr)
                return 130 if m.reason == INTERRUPTED else 0
            if self._steps:
                self._bring_up_myself()
                break
            if time.monotonic() > deadline:
                raise HostError(f"host {self.role}: its nodes were not activated within {bound:g} s: "
                                + ", ".join(f"{s.name} ({self._state(s)})" for s in self.slots if not s.active))
            self.executor.spin_once(timeout_sec=0.05)
        return None

    @staticmethod
    def _state(slot: Slot) -> str:
        return slot.node._state_machine.current_state[1]

    def _bring_up_myself(self) -> None:
        print(f"host {self.role}: the run is under way (step {self._steps[0].k} seen); bringing its nodes "
              "up itself (configure, activate)", file=sys.stderr, flush=True)
        for slot in self.slots:
            if self._state(slot) == UNCONFIGURED and slot.node.trigger_configure() != TransitionCallbackReturn.SUCCESS:
                raise HostError(f"host {self.role}: node {slot.name}: transition 'configure' failed")
            if self._state(slot) != ACTIVE and slot.node.trigger_activate() != TransitionCallbackReturn.SUCCESS:
                raise HostError(f"host {self.role}: node {slot.name}: transition 'activate' failed")

