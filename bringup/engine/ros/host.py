"""One OS process of the ROS engine hosting one or more lockstep participants.

Each participant (msgs_json/envelope.py) gets its own rclpy node with ``use_sim_time`` whose
/clock subscription is remapped away: the host sets every node's clock from the step it runs
(``set_ros_time_override``; docs/design.md section 7, trap 2), so all nodes of a process see the same
time: the scenario's UTC instant (epoch + t_ns), as /clock and the bag.

Names (bringup/engine/ros/naming.py): a satellite's node is ``/<sat>/<sat>`` (under the run's push
namespace, if any) and names its own topics relatively (``dtn/out``); other participants sit in the
root namespace and name per-satellite topics relatively too; global topics stay absolute. The run's
ROS arguments (``ros_args``) apply to every node of the process, so a remap such as
``-r sat_12:__ns:=/moved/sat_12`` moves a satellite as in any ROS 2 program. Participants keep
their logical topic names (what they subscribe to and emit, and what their inbox envelopes say);
the lockstep's counts (hellos' subscriptions, acks' ``sent``, publishers' matching) use the
resolved names, which are what DDS and the recorder see. Every participant node declares the run's
settings as read-only parameters (parameter services on), and every ``live_period_s`` of sim time
the host publishes the participants' live state to whoever subscribes (bringup/engine/ros/live.py:
fixes, /diagnostics).
Data topics are std_msgs/String carrying wire envelopes (msgs_json/wire.py), RELIABLE + KEEP_ALL;
/sim/step and /sim/ack are RELIABLE + TRANSIENT_LOCAL (traps 3-4). Subscription callbacks only
buffer envelopes; the step itself runs in one loop, participants in list order, each inbox sorted
by (t_ns, source, seq) (traps 1 and 6). Before running step k the host waits until every inbox holds
all envelopes of the previous steps, counted from the step message (bringup/engine/lockstep.py, trap
5). A publisher is used only once it has matched every subscription the run declared for its
topic (plus the recorder's), so nothing is lost to discovery.

Only the run's own messages are acted on: every envelope and step message carries a MAC under the
run key (msgs_json/auth.py; the key from the run's keys file, bringup/engine/keys.py), the host
puts its MAC on everything it publishes and drops whatever does not verify or does not decode -
counted per topic and reason (bringup/engine/lockstep.py Rejections; the first of each kind logged,
then one summary line every few seconds), reported in every ack (``rejected``), never fatal.

Crash and restart: with ``state_path`` the host checkpoints after every wire step
(bringup/engine/checkpoint.py; in the participant's own SQLite store when it has one, one transaction per
step). A host started on an existing checkpoint restores its participants and its lockstep state,
says hello with ``resume_k``, answers again the step it had finished (its saved ack, after
re-publishing that step's envelopes, kept in memory and in the checkpoint), ignores older steps and
re-runs the rest. The same answer goes to a restarted clock that publishes again a step the host
already ran (bringup/engine/ros/clock_node.py): the step is never run twice, and the new recorder gets
the envelopes it missed (receivers drop them as duplicates by (source, seq)). While its inboxes miss envelopes sent during its outage it repeats the
hello every ``rejoin_period_s``; the clock answers each with a re-send of what it recorded
(bringup/engine/lockstep.py ResendMsg); duplicates are dropped by (source, seq).

A flood of replayed step messages (genuine ones of this run, recorded off the wire and sent again:
their MAC verifies): a step older than the last one done is dropped as it arrives and counted
(``stale_steps``; the queue of steps never grows with them), and the last step done is answered
again (envelopes re-published, ack re-sent) at most once per :data:`_ANSWER_AGAIN_S` - the
restarted clock's re-announcements come once a second - so a flood neither changes what the host
does (receivers drop re-published envelopes by (source, seq)) nor multiplies its traffic
(tests/faults/test_step_flood.py).

What a participant returns and emits is checked by the engine contract (bringup/engine/contract.py),
the module the local engine uses too, so a violation is the same one-line error under both engines;
the host sends it to the clock in its ack (the run's error names the participant) and exits.

Progress: each ack carries the sum of the participants' ``StepResult.in_flight`` of the step (items
held to emit later, e.g. the ISL medium's bundle copies still travelling; None when none reports
one), the figure the local engine's progress shows; the clock sums it into its progress records.

Managed nodes: every participant node is an rclpy lifecycle node, brought up (configure ->
activate) and down by the run's lifecycle manager; the host says hello once all its nodes are
active (bringup/engine/ros/host_lifecycle.py).

Oracle: tests/ros/test_lockstep.py: toy participants hosted here, driven by the clock node over
DDS, emit exactly the envelopes the local engine (bringup/engine/local.py) emits for them;
tests/ros/test_lifecycle_run.py: the nodes' states read through their lifecycle services.
"""

from __future__ import annotations

import faulthandler
import signal
import sys
import time
from collections import deque
from collections.abc import Callable, Sequence

import rclpy
from rclpy.context import Context
from rclpy.duration import Duration
from rclpy.experimental import EventsExecutor
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rclpy.time import Time
from std_msgs.msg import String

from bringup.engine.checkpoint import (
    CheckpointDB,
    persistent_connection,
    restore_participant,
    snapshot_participant,
)
from bringup.engine.contract import (
    EngineError,
    check_emits,
    check_names,
    check_result,
    failed,
    must_step,
)
from bringup.engine.lifecycle import Deferred
from bringup.engine.lockstep import (
    ACK_TOPIC,
    INTERRUPTED,
    RESEND_TOPIC,
    STEP_TOPIC,
    AckMsg,
    Gate,
    LockstepError,
    StepMsg,
    TopicInbox,
    decode_resend,
    decode_step,
)
from bringup.engine.ros.host_lifecycle import HostError, HostLifecycle, ManagedNode, Slot
from bringup.engine.ros.live import HostLive
from bringup.engine.ros.naming import node_name_and_namespace, ros_topic_name
from bringup.engine.ros.profiling import dump as dump_profile
from bringup import process_end
from bringup.stop_signals import STOP_SIGNALS
from msgs_json.envelope import Envelope, Participant, StepResult
from msgs_json.wire import string_cdr

__all__ = ["QOS_DATA", "QOS_SYNC_PUB", "QOS_SYNC_SUB", "HostError", "ParticipantHost", "exit_now", "run_host"]

QOS_DATA = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)
# Writers keep the last few step/ack messages for late joiners (only one is ever outstanding);
# readers keep all, so simultaneous acks of several hosts are never overwritten (trap 3).
QOS_SYNC_PUB = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=16, reliability=ReliabilityPolicy.RELIABLE,
                          durability=DurabilityPolicy.TRANSIENT_LOCAL)
QOS_SYNC_SUB = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE,
                          durability=DurabilityPolicy.TRANSIENT_LOCAL)
# Wall seconds between two answers to the same step done (a restarted clock re-announces once a second).
_ANSWER_AGAIN_S = 0.5
_CLOCK_REMAP = ["--ros-args", "-r", "/clock:=/_lockstep/unused_clock"]
# Fewer entities per node = smaller wait sets per spin: the host's own node has no parameter
# services; no node has a /rosout writer (participant nodes have parameter services: run settings).
_LEAN = {"start_parameter_services": False, "enable_rosout": False}


class ParticipantHost(HostLifecycle):
    """Hosts ``participants`` (built, or :class:`Deferred`: built when configured) in one rclpy
    context, one managed node each; :meth:`run` waits until they are active, then follows the clock
    to the end."""

    QOS_DATA = QOS_DATA  # (the data topics' QoS, for the nodes' subscriptions made at configure)

    def __init__(self, role: str, participants: Sequence[Participant | Deferred], *, run_key: bytes,
                 ack_timeout_s: float = 10.0, startup_timeout_s: float = 60.0, idle_timeout_s: float = 300.0,
                 first_step_timeout_s: float | None = 300.0,
                 state_path: str | None = None, rejoin_period_s: float = 2.0,
                 namespace: str = "", ros_args: Sequence[str] = (), epoch_ns: int = 0,
                 parameters: dict | Callable[[str], dict] | None = None, live_period_s: float | None = None):
        try:
            check_names(participants)
        except EngineError as exc:
            raise HostError(f"host {role}: {exc}") from None
        self.role = role
        self.namespace = namespace
        self.parameters = parameters
        self.ack_timeout_s = ack_timeout_s
        self.startup_timeout_s = startup_timeout_s
        self.idle_timeout_s = idle_timeout_s
        # before the first step the clock may still wait for slower hosts (None: no bound)
        self.first_step_timeout_s = first_step_timeout_s
        self._stop_requested = False
        self.epoch_ns = int(epoch_ns)
        self.ctx = Context()
        # the run's ROS arguments (remaps, ...) apply to every node of this process, as global args
        rclpy.init(context=self.ctx, args=["constellation", "--ros-args", *ros_args] if ros_args else None,
                   signal_handler_options=SignalHandlerOptions.NO)
        self.executor = EventsExecutor(context=self.ctx)
        self.host_node = rclpy.create_node(f"host_{role}", context=self.ctx, cli_args=_CLOCK_REMAP, **_LEAN)
        # only the run's messages get in (MAC under the run key); the rest is counted
        self.gate = Gate(run_key, self.host_node.get_logger().warning)
        self._steps: deque[StepMsg] = deque()
        self.host_node.create_subscription(String, STEP_TOPIC, self._on_step, QOS_SYNC_SUB, raw=True)
        self.ack_pub = self.host_node.create_publisher(String, ACK_TOPIC, QOS_SYNC_PUB)
        self.executor.add_node(self.host_node)
        self.slots: list[Slot] = []
        self.inboxes_by_topic: dict[str, list[TopicInbox]] = {}
        self.duplicates = 0
        for p in participants:
            name, ns = node_name_and_namespace(p.name, namespace)
            node = ManagedNode(
                name, namespace=ns, context=self.ctx, cli_args=_CLOCK_REMAP, enable_rosout=False,
                parameter_overrides=[Parameter("use_sim_time", Parameter.Type.BOOL, True)],
            )
            slot = Slot(p, node)
            node.host, node.slot = self, slot
            self.executor.add_node(node)
            self.slots.append(slot)
        self.n_active = 0
        self.seq_end: dict[str, int] = {}
        self.subs: dict[str, int] = {}
        self.subs_default = 0
        self.rejoin_period_s = rejoin_period_s
        self.host_node.create_subscription(String, RESEND_TOPIC, self._on_resend, QOS_DATA, raw=True)
        # crash/restart: last wire step done (-1 = none), the ack sent for it, the checkpoint store
        self.done_k = -1
        self.resume_k = -1
        self.last_ack: dict | None = None
        # envelopes (participant, topic, wire text) emitted in step done_k, re-published with its ack
        self.last_wires: list[tuple[str, str, str]] = []
        self._step_wires: list[tuple[str, str, str]] = []
        self.republished = 0
        self.stale_steps = 0  # replayed steps older than the last one done, dropped on arrival
        self._answered_at = -float("inf")  # (monotonic) when the last step done was last answered again
        self.ckpt = None
        self.state_path = state_path
        self.live_period_s = live_period_s
        self.live = None

    def _ready(self) -> None:
        """Every node active: the checkpoint opened (restored: a restarted host), the live state set up."""
        if self.state_path is not None and self.ckpt is None:
            self._open_checkpoint(self.state_path)
        if self.live_period_s and self.live is None:
            self.live = HostLive(self, self.epoch_ns, self.live_period_s)

    @staticmethod
    def _resolved(slot: Slot, topic: str) -> str:
        """The name DDS carries for ``slot``'s logical ``topic`` (its node's remaps and namespace)."""
        r = slot.ros.get(topic)
        if r is None:
            r = slot.ros[topic] = slot.node.resolve_topic_name(ros_topic_name(topic, slot.name))
        return r

    # -- checkpoints (bringup/engine/checkpoint.py) --------------------------------------------------------
    def _open_checkpoint(self, state_path: str) -> None:
        conns = [c for c in (persistent_connection(s.p) for s in self.slots) if c is not None]
        if len(conns) > 1:
            raise HostError(f"host {self.role}: more than one participant has its own store; "
                            "one checkpoint transaction cannot span them")
        self.ckpt = CheckpointDB(conn=conns[0]) if conns else CheckpointDB(state_path)
        row = self.ckpt.load()
        if row is None:
            return
        k, hs, parts = row
        if len(parts) != len(self.slots) or hs.get("names") != [s.name for s in self.slots]:
            raise HostError(f"host {self.role}: checkpoint {state_path} holds participants {hs.get('names')}, "
                            f"not {[s.name for s in self.slots]}")
        for slot, blob in zip(self.slots, parts, strict=True):
            restore_participant(slot.p, blob)
            slot.seq = hs["seq"][slot.name]
            slot.wake, slot.flight = hs["standing"][slot.name]
            for box in slot.inboxes:
                box.expected, box.delivered, consumed = hs["boxes"][f"{slot.name} {box.topic}"]
                box.consumed = dict(consumed)
        self.seq_end = dict(hs["seq_end"])
        self.subs, self.subs_default = dict(hs["subs"]), hs["subs_default"]
        self.done_k = self.resume_k = k
        self.last_ack = hs["ack"]
        self.last_wires = [tuple(w) for w in hs.get("wires", ())]

    def _checkpoint(self, k: int, ack: dict) -> None:
        hs = {"names": [s.name for s in self.slots], "seq": {s.name: s.seq for s in self.slots},
              "boxes": {f"{s.name} {b.topic}": (b.expected, b.delivered, dict(b.consumed))
                        for s in self.slots for b in s.inboxes},
              "seq_end": dict(self.seq_end), "subs": dict(self.subs), "subs_default": self.subs_default,
              "ack": ack, "wires": list(self._step_wires),
              "standing": {s.name: (s.wake, s.flight) for s in self.slots}}
        try:
            parts = [snapshot_participant(s.p) for s in self.slots]
        except Exception as exc:
            raise HostError(f"host {self.role}: checkpoint of step {k} failed: {type(exc).__name__}: {exc}") from exc
        self.ckpt.commit(k, hs, parts)

    # -- callbacks: check, then buffer only -----------------------------------------------------------
    def _make_cb(self, box: TopicInbox):
        gate, topic, add = self.gate, box.topic, box.add

        def cb(raw: bytes) -> None:
            text = gate.cdr_text(topic, raw)
            env = None if text is None else gate.envelope(text, topic)
            if env is not None and not add(env):
                self.duplicates += 1
        return cb

    def _on_resend(self, raw: bytes) -> None:
        text = self.gate.cdr_text(RESEND_TOPIC, raw)
        text = None if text is None else self.gate.text(RESEND_TOPIC, text)
        if text is None:
            return
        try:
            r = decode_resend(text)
        except LockstepError as exc:
            self.gate.reject(RESEND_TOPIC, "malformed", str(exc))
            return
        if r.to != self.role:
            return
        for box in self.inboxes_by_topic.get(r.topic, ()):
            for w in r.wires:
                env = self.gate.envelope(w, box.topic)  # the participant's own (logical) name
                if env is not None and not box.add(env):
                    self.duplicates += 1

    def _on_step(self, raw: bytes) -> None:
        text = self.gate.cdr_text(STEP_TOPIC, raw)
        text = None if text is None else self.gate.text(STEP_TOPIC, text)
        if text is None:
            return
        try:
            m = decode_step(text)
        except LockstepError as exc:
            self.gate.reject(STEP_TOPIC, "malformed", str(exc))
            return
        if not m.stop and m.k < self.done_k:  # (a replay: nothing to answer; never queued)
            self.stale_steps += 1
            return
        self._steps.append(m)

    def request_stop(self, *_args) -> None:
        self._stop_requested = True

    # -- helpers ------------------------------------------------------------------------------------
    def _spin_until(self, cond, timeout_s: float, what: str) -> None:
        deadline = time.monotonic() + timeout_s
        spin = self.executor.spin_once
        while not cond():
            if self._stop_requested:
                raise KeyboardInterrupt
            if time.monotonic() > deadline:
                raise HostError(f"host {self.role}: {what} (waited {timeout_s:g} s)")
            spin(timeout_sec=0.05)

    def _wait_envelopes(self, cond, what: str) -> None:
        """Wait for the previous steps' envelopes; after a restart, ask the clock to re-send them
        (a hello with ``resume_k``) every ``rejoin_period_s`` while they are missing."""
        if self.resume_k < 0:
            self._spin_until(cond, self.ack_timeout_s, what)
            return
        deadline = time.monotonic() + self.ack_timeout_s
        while True:
            try:
                self._spin_until(cond, min(self.rejoin_period_s, max(0.0, deadline - time.monotonic())), what)
                return
            except HostError:
                if time.monotonic() >= deadline:
                    raise
                self._hello()

    def _hello(self) -> None:
        """Say hello: at start, and again after a restart while envelopes are missing. ``resume_k``
        is the last step this host has done and checkpointed - the checkpoint it restarted from
        at first, then each step it has run since (a restarted host that waits for envelopes many
        steps later is not one whose state is lost: tests/ros/test_rejoin_hello.py)."""
        subs_count = {topic: len(boxes) for topic, boxes in self.inboxes_by_topic.items()}
        self._ack(k=0, t_ns=0, hello=True, participants=[s.name for s in self.slots], subscriptions=subs_count,
                  resume_k=max(self.resume_k, self.done_k) if self.resume_k >= 0 else self.resume_k)

    def _publisher(self, slot: Slot, topic: str):
        pub = slot.pubs.get(topic)
        if pub is None:
            pub = slot.node.create_lifecycle_publisher(String, ros_topic_name(topic, slot.name), QOS_DATA)
            if slot.active:  # (made after the activation, which enabled the node's publishers then)
                pub.on_activate(None)
            resolved = self._resolved(slot, topic)
            need = self.subs.get(resolved, self.subs_default)
            self._spin_until(lambda: pub.get_subscription_count() >= need, self.startup_timeout_s,
                             f"{slot.name}: {resolved} matched {pub.get_subscription_count()} of {need} subscriptions")
            slot.pubs[topic] = pub
        return pub

    def _emit(self, slot: Slot, emits, t_max_ns: int, where: str, sent: dict[str, int]) -> None:
        try:
            emits = check_emits(slot.name, emits, t_max_ns, where)
        except EngineError as exc:
            raise HostError(str(exc)) from None
        wire = self.gate.wire
        for e in emits:
            text = wire(Envelope(e.t_ns, slot.name, slot.seq, e.topic, e.data))
            self._publisher(slot, e.topic).publish(string_cdr(text))  # serialized: no String round trip
            self._step_wires.append((slot.name, e.topic, text))
            slot.seq += 1
            resolved = slot.ros.get(e.topic) or self._resolved(slot, e.topic)
            sent[resolved] = sent.get(resolved, 0) + 1

    def _ack(self, **kw) -> None:
        rej = self.gate.rejections.counts()
        if rej:  # what this host rejected so far (the clock puts the last count in /run/meta)
            kw = {**kw, "rejected": rej}
        self.ack_pub.publish(string_cdr(self.gate.sealed(ACK_TOPIC, AckMsg(participant=self.role, **kw))))

    # -- one wire step ------------------------------------------------------------------------------
    def _run_step(self, m: StepMsg) -> None:
        if self.n_active < len(self.slots):
            raise HostError(f"host {self.role}: step {m.k}: node(s) not active: "
                            + ", ".join(f"{s.name} ({self._state(s)})" for s in self.slots if not s.active))
        if self.ckpt is not None:
            self.ckpt.begin()
        self._step_wires = []
        for topic, n in m.sent.items():
            for box in self.inboxes_by_topic.get(topic, ()):
                box.expected += n
        self.seq_end.update(m.seq_end)
        sent: dict[str, int] = {}
        t = m.t_ns
        if m.start:
            self.subs, self.subs_default = dict(m.subs), m.subs_default
            for slot in self.slots:
                where = f"start at {t}"
                r = self._call(slot, slot.p.start, where, t)
                self._emit(slot, r.emits, t, where, sent)
                slot.wake, slot.flight = r.next_wakeup_ns, r.in_flight
        else:
            boxes = [b for s in self.slots for b in s.inboxes]
            seq_end = self.seq_end

            def all_ready() -> bool:
                return all(b.ready(seq_end) for b in boxes)

            if not all_ready():
                try:
                    self._wait_envelopes(all_ready, f"step {m.k} at t_ns={t}: envelopes missing")
                except HostError as exc:
                    short = {b.topic: b.missing(seq_end) for b in boxes if b.missing(seq_end)}
                    raise HostError(f"{exc}: {short}") from None
            tm = Time(nanoseconds=self.epoch_ns + t)
            for slot in self.slots:
                slot.node.get_clock().set_ros_time_override(tm)
            for slot in self.slots:
                if len(slot.inboxes) == 1:
                    inbox = slot.inboxes[0].take(seq_end)
                else:
                    inbox = [e for b in slot.inboxes for e in b.take(seq_end)]
                    inbox.sort(key=Envelope.sort_key)
                if slot.driven and not must_step(True, bool(inbox), slot.wake, t):
                    continue  # an event-driven participant with nothing this step (contract rule 1)
                where = f"step at {t}"
                r = self._call(slot, slot.p.step, where, t, inbox)
                self._emit(slot, r.emits, t, where, sent)
                slot.wake, slot.flight = r.next_wakeup_ns, r.in_flight
            if m.final:
                for slot in self.slots:
                    where = f"finish at {t}"
                    try:
                        emits = slot.p.finish(t)
                    except Exception as exc:
                        raise HostError(str(failed(slot.name, where, exc))) from exc
                    self._emit(slot, emits, t, where, sent)
        if self.live is not None and not m.start:  # every live period (sim time) and at the end
            try:
                self.live.publish(t, final=m.final)
            except EngineError as exc:  # a participant's live_state failed or broke the contract
                raise HostError(str(exc)) from None
        wakes = [s.wake for s in self.slots if s.wake is not None]
        flight = [s.flight for s in self.slots if s.flight is not None]
        ack = dict(k=m.k, t_ns=t, next_wakeup_ns=min(wakes) if wakes else None, sent=sent,
                   seq_end={s.name: s.seq for s in self.slots if s.seq})
        if flight:
            ack["in_flight"] = sum(flight)
        if self.ckpt is not None:
            self._checkpoint(m.k, ack)
        self.done_k, self.last_ack, self.last_wires = m.k, ack, self._step_wires
        self._ack(**ack)

    @staticmethod
    def _call(slot: Slot, fn, where: str, *args) -> StepResult:
        try:
            r = fn(*args)
        except Exception as exc:
            raise HostError(str(failed(slot.name, where, exc))) from exc
        try:
            return check_result(slot.name, r, where)
        except EngineError as exc:
            raise HostError(str(exc)) from None

    # -- main loop ----------------------------------------------------------------------------------
    def run(self) -> int:
        """Wait until the nodes are active, say hello, run every step the clock sends until
        ``stop``; 0 on a clean end."""
        rc = self._await_active()
        if rc is not None:
            return rc
        self._ready()
        self._hello()
        while True:
            if not self._steps:
                wait = self.idle_timeout_s
                if self.done_k < 0:
                    wait = float("inf") if self.first_step_timeout_s is None else self.first_step_timeout_s
                self._spin_until(lambda: bool(self._steps), wait, "no step message from the clock")
            m = self._steps.popleft()
            if m.stop:
                if m.reason:
                    print(f"host {self.role}: stopped by the clock: {m.reason}", file=sys.stderr)
                return 130 if m.reason == INTERRUPTED else 0
            if m.k <= self.done_k:
                # a step already done (the step writer's history, after a restart): answer the one
                # the clock may still wait for, ignore older ones
                if m.k == self.done_k and self.last_ack is not None and self._may_answer_again():
                    self._republish_last()
                    self._ack(**self.last_ack)
                continue
            if m.k != self.done_k + 1:
                raise HostError(f"host {self.role}: step {m.k} arrived after step {self.done_k}; "
                                f"steps {self.done_k + 1}..{m.k - 1} were never received")
            try:
                self._run_step(m)
            except HostError as exc:
                # Tell the clock why before leaving, so the run's error names us and the cause.
                self._ack(k=m.k, t_ns=m.t_ns, error=str(exc))
                self._flush_acks()
                raise

    def _may_answer_again(self) -> bool:
        """At most one answer to the same step done per :data:`_ANSWER_AGAIN_S` (a replayed flood)."""
        now = time.monotonic()
        if now - self._answered_at < _ANSWER_AGAIN_S:
            self.stale_steps += 1
            return False
        self._answered_at = now
        return True

    def _republish_last(self) -> None:
        """Publish again the envelopes of step ``done_k`` (same source and seq)."""
        slots = {s.name: s for s in self.slots}
        for name, topic, text in self.last_wires:
            self._publisher(slots[name], topic).publish(string_cdr(text))
        self.republished += len(self.last_wires)

    def _flush_acks(self) -> None:
        try:
            self.ack_pub.wait_for_all_acked(Duration(seconds=2.0))
        except Exception:  # noqa: BLE001 - best effort on the way out
            pass

    def close(self, dds: bool = True) -> None:
        """Close the checkpoint store and (``dds``) destroy the nodes and the context. A process
        that exits right after passes ``dds=False`` and leaves with :func:`exit_now` (see there)."""
        if not dds:
            if self.ckpt is not None:
                self.ckpt.close()
            return
        try:
            if self.ckpt is not None:
                self.ckpt.close()
            self.executor.shutdown(timeout_sec=1.0)
            for s in self.slots:
                s.node.destroy_node()
            self.host_node.destroy_node()
        finally:
            rclpy.try_shutdown(context=self.ctx)


def exit_now(code: int) -> None:
    """End a node process (host or clock) once its files are closed, without destroying its DDS
    participant. That destruction (rclpy destroy_node of the last node -> rmw destroy_participant
    -> FastDDS 2.14 ``DomainParticipant::set_listener``) can deadlock when discovery traffic
    arrives meanwhile, which it does at the end of a run, when every process of the run leaves at
    once: a FastDDS receive thread waits in ``onReaderDiscovery`` for a mutex while set_listener
    spins waiting for that listener call to end, forever (gdb stacks of a host and of the clock,
    under load, about 1 host in 30 runs), with the GIL held, so SIGTERM goes unhandled. The
    participant only frees memory and tells peers it left; peers of a finished run do not need it
    (they drop it at lease expiry), so the process skips it: stdout/stderr flushed, ``os._exit``.
    A profile started with ``AGILE_DTN_PROFILE_DIR`` (bringup/engine/ros/profiling.py) is written first."""
    dump_profile()
    process_end.exit_now(code)


def run_host(role: str, participants: Sequence[Participant], **kw) -> int:
    """Process entry: host ``participants`` until the clock stops the run, then end the process
    (:func:`exit_now`). Exit code: 0 ok, 1 the host failed (message on stderr naming the
    participant), 130 interrupted."""
    # SIGUSR1 writes every thread's Python stack into the log (stderr): the launcher sends it before
    # it kills a host that ignored SIGTERM.
    faulthandler.register(signal.SIGUSR1, all_threads=True)
    host = ParticipantHost(role, participants, **kw)
    # every way a run is stopped (a terminal's SIGHUP or Ctrl-\\ reach every process of its group too):
    # the ordinary stop (bringup/stop_signals.py)
    for sig in STOP_SIGNALS:
        signal.signal(sig, host.request_stop)
    try:
        rc = host.run()
    except KeyboardInterrupt:
        print(f"host {role}: interrupted", file=sys.stderr)
        rc = 130
    except (HostError, LockstepError) as exc:
        print(f"host {role}: error: {exc}", file=sys.stderr)
        rc = 1
    except BaseException:
        host.close()
        raise
    host.close(dds=False)
    exit_now(rc)
    return rc  # not reached
