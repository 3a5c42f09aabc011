"""The lockstep coordinator of the ROS engine: owns simulated time (docs/design.md section 3).

Publishes /clock (rosgraph_msgs/Clock, the scenario's UTC instant: epoch + t_ns) and /sim/step, collects one /sim/ack per host process and
picks the next step with rule 3 of msgs_json/envelope.py (bringup/engine/lockstep.py has the
protocol). A step ends when every registered host acked it; what was sent in it is counted in the
acks and the next step message carries the counts, so receivers run the next step only once they
hold all of it (docs/design.md section 7, trap 5). Pacing: as fast as possible, or ``real_time_factor`` sim
seconds per wall second. Progress: a JSON line on stdout every ``progress_period_s`` (sim time,
steps, wall time and, when a host holds the DTN router, ``in_flight``: the bundle copies the router
holds after that step, summed from the acks; bringup/engine/ros/launcher.py reads them). A host that does not
ack within ``ack_timeout_s`` wall seconds is reported by name (with its participants) and the run
stops; so does a host that acks an error.

Managed nodes: the clock process also runs the run's lifecycle manager
(bringup/engine/ros/lifecycle_manager.py). While it waits for the hellos it brings every participant
node through configure -> activate by calling its lifecycle services (a host says hello once all its
nodes are active); a node that fails a transition stops the run, named with its process and the
transition (stderr, and a ``lifecycle_failed`` record on stdout for the launcher). After the last
step (the bag complete) it takes every node through deactivate -> cleanup -> shutdown before it
tells the hosts to stop.

Ready is not a step: before step 0 the clock waits for every host's hello (sent once its
participants are built and their numba kernels loaded and its nodes active, bringup/cli/node.py), as long as it takes
unless the spec bounds it (``startup_timeout_s``), naming every ``_READY_REPORT_S`` the hosts not
ready yet and how long it has waited (stderr, and a ``waiting`` record on stdout for the launcher's
progress display). Step 0 (the start step) is where the hosts' data publishers wait until the
subscriptions counted in the hellos have matched (DDS discovery between every pair of endpoints, which
grows with the endpoints each node has: topics, parameter services), so its ack deadline is at least
``_FIRST_STEP_ACK_S``; the per-step ``ack_timeout_s`` applies from step 1 on
(tests/ros/test_lockstep.py: a host 5 s slow in step 0 is waited for, at a later step it is named). Oracle for the cold start:
tests/system/test_cold_start.py (24 satellites from an empty numba cache).

The same process records every topic into a rosbag2 MCAP bag (bringup/recording/bag.py BagWriter):
/clock and /sim/step as written, /sim/ack and every data topic from raw (CDR) subscriptions, log
time = the step's / the envelope's t_ns. Data topics are those the hosts subscribe to plus any
String topic that appears on the graph (polled while waiting); hosts publish on a topic only once
the recorder's subscription has matched, so the bag holds every envelope. With a scenario the bag
also gets the visualisation frames and the plotted series (value so far, bundles in flight:
bringup/recording/metrics_feed.py); the frames' markers and TF tree are also published live, the
same bytes (``viz/constellation`` under the run's namespace, ``/tf``, ``/tf_static``;
bringup/engine/ros/live.py). SIGINT/SIGTERM (also sent when its launcher dies,
bringup/engine/ros/lifeline.py): the clock tells the hosts to stop and closes the bag (readable).

Authenticated traffic: the clock seals its step messages and checks the MAC (msgs_json/auth.py)
of every ack and every envelope it records (bringup/engine/lockstep.py Gate); what does not verify
is neither acted on nor recorded, only counted. The bag holds each envelope without its MAC (the
wire form of msgs_json/wire.py, as the local engine writes it). /run/meta's ``security`` holds what
the clock and each host (its last ack) rejected: report.json ``security``.

Why one module: the clock is one ROS node whose callbacks share one state - the barrier (the
current step's acks), the recorder (dedupe keys, counts, re-send buffer, journal) and the
checkpoint that must hold both in one transaction; split, each part would reach into the others.

Crash and restart: with ``restart_wait_s > 0`` a host that misses the ack deadline is
reported by name on stderr and waited for (bounded by ``restart_wait_s``) while the launcher
restarts it; the recorder then always listens (bag or not) and keeps the envelopes of the last
``_RESEND_STEPS`` wire steps. A hello from a host during the run is a rejoin: the clock re-sends it
(/_lockstep/resend) what it recorded on its topics; the host drops what it already holds. Acks for
any step but the current one are ignored (a restarted host repeats its last one); a host whose
checkpoint is older than the last step it acked (its store deleted or replaced) stops the run, named
(tests/faults/test_store_lost.py); the recorder
keeps one copy per (topic, source, seq), so a re-run step is recorded once.

Clock restart: with ``restart_wait_s > 0`` and a ``state_dir`` the clock itself survives
SIGKILL. It records into a journal (bringup/recording/journal.py BagJournal, ``state_dir/clock.sqlite``)
instead of straight into the bag, and before publishing wire step k it commits, in one SQLite
transaction, everything recorded through step k-1 plus its checkpoint: k, t_ns, the step message
(which carries the per-source seq_end and per-topic sent counts of step k-1), the running totals,
the hosts' hellos, the recorded topics and the visualisation cursor. It commits only once the
recorder holds every envelope the acks of step k-1 counted, so the journal has no gap. The
launcher restarts a clock that crashed; the new one loads the checkpoint (its dedupe keys, counts
and re-send buffer come from the journal's rows) and publishes step k again, every ``_REANNOUNCE_S``
until every host has acked it (a host whose subscription had not matched the new clock's publisher
yet would miss a single publication, and its ack the new clock's subscription). Hosts that had not run
step k run it; hosts that had (``k == done_k``) answer with their saved ack and re-publish the
envelopes of that step (bringup/engine/ros/host.py), which receivers drop as duplicates and the new
recorder records once; no step runs twice. Envelopes the new recorder still misses after 1 s (its
subscriptions were not matched yet) are asked for again by re-announcing the step. At the end (also
on error or Ctrl-C) the journal is exported into ``bag_dir`` (one ordinary bag).

Oracle: tests/ros/test_lockstep.py (toy participants over DDS give exactly the local engine's
envelopes, read back from the bag; a killed host is named within the bounded wait; Ctrl-C leaves
a readable bag); tests/faults/test_faults_hostile_ros.py (forged steps, acks, stops, observations
and replays on a live run: rejected, counted in report.json, the report unchanged).
"""

from __future__ import annotations

import faulthandler
import json
import os
import pickle
import signal
import sys
import time
from pathlib import Path

import rclpy
from rclpy.context import Context
from rclpy.duration import Duration
from rclpy.experimental import EventsExecutor
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rosgraph_msgs.msg import Clock
from std_msgs.msg import String

from bringup.engine.contract import next_step_ns
from bringup.engine.lockstep import (
    ACK_TOPIC,
    INTERRUPTED,
    RESEND_TOPIC,
    STEP_TOPIC,
    AckMsg,
    Gate,
    LockstepError,
    ResendMsg,
    StepMsg,
    decode_ack,
    decode_step,
    encode_msg,
)
from bringup.engine.ros.host import QOS_DATA, QOS_SYNC_PUB, QOS_SYNC_SUB, exit_now
from bringup.engine.ros.lifecycle_manager import LifecycleManager
from bringup.engine.ros.lifeline import ENV_RESTARTED
from bringup.engine.ros.live import ClockLive
from bringup.engine.ros.run_spec import CLOCK_ROLE, RunSpec
from bringup.recording.bag import BagWriter, string_cdr, string_from_cdr
from bringup.recording.bag_format import clock_cdr
from bringup.recording.journal import BagJournal
from bringup.recording.metrics_feed import MetricsFeed
from bringup.recording.viz_feed import VizFeed
from bringup.scenario.participants import participant_name
from bringup.scenario.world import World
from bringup.stop_signals import STOP_SIGNALS
from msgs_json.envelope import Envelope
from msgs_json.topics import design_topic
from msgs_json.wire import decode_envelope

__all__ = ["ClockError", "LockstepClock", "run_clock"]

_STRING = "std_msgs/msg/String"
_CLOCK = "rosgraph_msgs/msg/Clock"
_QOS_CLOCK = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)
_RESEND_STEPS = 6
_FIRST_STEP_ACK_S = 30.0  # the start step's ack deadline at least (discovery of the data topics)
# Wall seconds the clock waits for the recorder before re-announcing the step (clock restart).
_REANNOUNCE_S = 1.0
# Wall seconds between two reports of the hosts not ready yet (before step 0).
_READY_REPORT_S = 5.0


class ClockError(RuntimeError):
    """The run cannot go on; the message names the host/participants and the step."""


class LifecycleFailed(ClockError):
    """A node refused or failed a lifecycle transition (never waited out)."""


class LostStateError(ClockError):
    """A restarted host lost state the run relied on: no restart can mend it (never waited out)."""


class LockstepClock:
    def __init__(self, spec: RunSpec):
        self.spec = spec
        self.roles = list(spec.roles)
        self.horizon_ns, self.max_step_ns = spec.bounds_ns()
        self.t0_ns = spec.t0_ns
        run_key = spec.keys().run
        # what each host rejected, from its last ack (AckMsg.rejected)
        self.host_rejected: dict[str, dict[str, dict[str, int]]] = {}
        self._stop_requested = False
        self.ctx = Context()
        rclpy.init(context=self.ctx, args=["constellation", "--ros-args", *spec.ros_args] if spec.ros_args else None,
                   signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node("orbit_clock", namespace=spec.namespace or "/", context=self.ctx,
                                      start_parameter_services=False)
        # only the run's messages get in (MAC under the run key); the rest is counted
        self.gate = Gate(run_key, self.node.get_logger().warning)
        self.executor = EventsExecutor(context=self.ctx)
        self.executor.add_node(self.node)
        # the run's lifecycle manager (bringup/engine/ros/lifecycle_manager.py), polled while the
        # clock waits for the hosts to come up and, after the run, to go down
        self.mgr_node = rclpy.create_node("lifecycle_manager", namespace=spec.namespace or "/", context=self.ctx,
                                          start_parameter_services=False, enable_rosout=False)
        self.executor.add_node(self.mgr_node)
        self.lifecycle = LifecycleManager(self.mgr_node, process_of=self._process_of)
        self._lifecycle_busy = False
        self.clock_pub = self.node.create_publisher(Clock, "/clock", _QOS_CLOCK)
        self.step_pub = self.node.create_publisher(String, STEP_TOPIC, QOS_SYNC_PUB)
        self.acks: dict[str, AckMsg] = {}
        self.hellos: dict[str, AckMsg] = {}
        self.node.create_subscription(String, ACK_TOPIC, self._on_ack, QOS_SYNC_SUB, raw=True)
        self.bag = None
        self.bag_custom = {"engine": "ros", "roles": ",".join(self.roles)}
        # /clock and the bag's times are UTC: the scenario epoch + t_ns (bringup/recording/bag.py)
        self.epoch_ns = spec.epoch_ns()
        # clock restart: the journal (bag rows + checkpoint) and the checkpoint found at start, if any
        self.journal = None
        self.resumed: tuple[int, dict] | None = None
        self.reannounces = 0
        self._incarnation = 0
        if spec.restart_wait_s > 0 and spec.state_dir:
            self.journal = self.bag = BagJournal(Path(spec.state_dir) / "clock.sqlite", epoch_ns=self.epoch_ns)
            row = self.journal.load()
            if row is not None:
                self.resumed = (row[0], pickle.loads(row[1]))
        elif spec.bag_dir:
            self.bag = BagWriter(spec.bag_dir, custom=self.bag_custom, epoch_ns=self.epoch_ns)
        # A `constellation run`: its metadata record and the visualisation topics (bringup/recording/viz_feed.py).
        self.meta = spec.extra.get("meta")
        self.viz = None
        self.metrics = None  # the plotted series (bringup/recording/metrics_feed.py), with viz
        if self.bag is not None and self.meta is not None:
            if self.resumed is None:
                self.bag.write_envelope(Envelope(self.t0_ns, "run", 0, "/run/meta",
                                                 json.dumps({"meta": self.meta})))
            if spec.extra.get("world"):
                world = World.load(spec.extra["world"], spec.extra.get("world_key"))
                self.viz = VizFeed(world)
                self.metrics = MetricsFeed(world.scenario.value.revisit_zero_s)
        # the visualisation frames live too (bringup/engine/ros/live.py)
        self.live = ClockLive(self.node) if self.viz is not None else None
        self.rec_topics: dict[str, object] = {}
        self.rec_counts: dict[str, int] = {}
        self.totals: dict[str, int] = {}
        self._next_graph_poll = 0.0
        self.steps = 0
        # bundle copies in flight in the DTN router after the last step (from the acks; None: no router)
        self.in_flight: int | None = None
        # crash/restart: current wire step, dedupe keys, recent envelopes per topic, rejoin requests
        self.restart = spec.restart_wait_s > 0
        self.cur_k = -1
        self.running = False
        self._rec_keys: set[tuple[str, str, int]] = set()
        self.rec_duplicates = 0
        self.recent: dict[str, list[tuple[int, str]]] = {}
        self.rejoins: list[AckMsg] = []
        self.rejoined: dict[str, int] = {}
        self.stale_acks = 0
        self.resend_pub = self.node.create_publisher(String, RESEND_TOPIC, QOS_DATA) if self.restart else None

    # -- callbacks ----------------------------------------------------------------------------------
    def _on_ack(self, raw: bytes) -> None:
        reject = self.gate.reject
        text = self.gate.cdr_text(ACK_TOPIC, raw)
        text = None if text is None else self.gate.text(ACK_TOPIC, text)
        if text is None:
            return
        try:
            ack = decode_ack(text)
        except LockstepError as exc:
            reject(ACK_TOPIC, "malformed", str(exc))
            return
        if ack.participant not in self.roles:
            reject(ACK_TOPIC, "unknown_source", f"{ACK_TOPIC}: ack from unknown host {ack.participant!r}")
            return
        # a host's rejection counts are taken from an ack the run accepts, never before its checks: an
        # old ack of the same host (valid MAC, replayed) must not roll its counts back
        if ack.hello:
            if self.running:
                if not self.restart:  # only a restarted host says hello again, and none is restarted
                    reject(ACK_TOPIC, "unexpected_hello", f"{ACK_TOPIC}: hello from {ack.participant} "
                           "during a run without restarts")
                    return
                self.rejoins.append(ack)
            elif ack.rejected:
                self.host_rejected[ack.participant] = ack.rejected
            self.hellos[ack.participant] = ack
        else:
            if ack.k != self.cur_k:
                self.stale_acks += 1
                return
            if ack.participant in self.acks:  # the same ack again (re-announced step): recorded once
                return
            self.acks[ack.participant] = ack
            if ack.rejected:
                self.host_rejected[ack.participant] = ack.rejected
            if self.bag is not None:  # recorded as the ack itself (the MAC is the transport's)
                self.bag.write_raw(ACK_TOPIC, _STRING, string_cdr(text), ack.t_ns)

    def _make_rec_cb(self, topic: str):
        # senders seal the participants' own names (docs/design.md's): a per-satellite topic moved by
        # a namespace push or remap is checked under that name and recorded under its own
        checked = design_topic(topic)
        gate = self.gate

        def cb(raw: bytes) -> None:
            text = gate.cdr_text(topic, raw)
            got = None if text is None else gate.envelope_wire(text, checked)
            if got is None:
                return
            env, wire = got
            key = (topic, env.source, env.seq)
            if key in self._rec_keys:
                self.rec_duplicates += 1
                return
            self._rec_keys.add(key)
            if self.restart:
                self.recent.setdefault(topic, []).append((self.cur_k, text))
            self.rec_counts[topic] = self.rec_counts.get(topic, 0) + 1
            if self.metrics is not None:
                self.metrics.observe(env)
            # recorded without its MAC: the bag holds the envelope's wire form (msgs_json/wire.py)
            cdr = string_cdr(wire)
            if self.journal is not None:
                self.journal.write_keyed(topic, _STRING, cdr, env.t_ns, env.source, env.seq)
            elif self.bag is not None:
                self.bag.write_raw(topic, _STRING, cdr, env.t_ns)
        return cb

    def _record(self, topic: str) -> None:
        if topic in self.rec_topics or topic in (STEP_TOPIC, ACK_TOPIC, "/clock", "/rosout", "/parameter_events"):
            return
        self.rec_topics[topic] = self.node.create_subscription(
            String, topic, self._make_rec_cb(topic), QOS_DATA, raw=True)

    def _poll_graph(self) -> None:
        now = time.monotonic()
        if now < self._next_graph_poll:
            return
        self._next_graph_poll = now + 0.1
        for topic, types in self.node.get_topic_names_and_types():
            if _STRING in types and not topic.startswith("/_lockstep"):
                self._record(topic)

    def _serve_rejoins(self) -> None:
        """Re-send to each restarted host what was recorded on its topics in the last steps. A host
        must resume at least after step cur_k - 1 (it acked that step, and a host checkpoints a step
        before it acks it): one whose checkpoint is older or missing (its store deleted, replaced by
        an older copy, or emptied) lost state the run already relied on, so the run stops naming it
        (ClockError) instead of letting it step from the wrong state."""
        while self.rejoins:
            h = self.rejoins.pop(0)
            if h.resume_k < self.cur_k - 1:
                lost = "no checkpoint" if h.resume_k < 0 else f"a checkpoint of step {h.resume_k}"
                raise LostStateError(f"host {h.participant} restarted with {lost} while the run is at step {self.cur_k} "
                                 f"(it had acked step {self.cur_k - 1}): its saved state was lost (its store deleted, "
                                 "corrupted or replaced by an older copy); it cannot rejoin the run")
            n = self.rejoined[h.participant] = self.rejoined.get(h.participant, 0) + 1
            if n == 1:
                print(f"clock: host {h.participant} rejoined at step {self.cur_k} "
                      f"(resumes after step {h.resume_k})", file=sys.stderr, flush=True)
            for topic in h.subscriptions:
                wires = [w for _k, w in self.recent.get(topic, ())]
                self.resend_pub.publish(String(data=self.gate.sealed(
                    RESEND_TOPIC, ResendMsg(to=h.participant, topic=topic, wires=wires))))

    def _prune_recent(self) -> None:
        lo = self.cur_k - _RESEND_STEPS
        for topic, items in self.recent.items():
            if items and items[0][0] < lo:
                self.recent[topic] = [it for it in items if it[0] >= lo]

    def request_stop(self, *_args) -> None:
        self._stop_requested = True

    # -- the nodes' life cycle (bringup/engine/ros/lifecycle_manager.py) -----------------------------------
    def _process_of(self, node_name: str) -> str:
        """The process role hosting the participant node ``node_name`` ("" when the spec cannot tell)."""
        for r in self.roles:
            if any(participant_name(m) == node_name for m in self.spec.members(r)):
                return r
        return ""

    def _lifecycle_check(self) -> None:
        """LifecycleFailed once the manager saw a transition fail (its record goes to the launcher)."""
        if self.lifecycle.failure:
            self._out({"lifecycle_failed": self.lifecycle.failed})
            raise LifecycleFailed(self.lifecycle.failure)

    def _shut_down_nodes(self) -> None:
        """Every participant node through deactivate -> cleanup -> shutdown (bounded wait, named)."""
        self.lifecycle.shut_down()
        self._lifecycle_busy = True
        n = sum(len(h.participants) for h in self.hellos.values())
        bound = max(30.0, self.spec.ack_timeout_s)

        def down() -> bool:
            self._lifecycle_check()
            return self.lifecycle.at_goal(n)

        def late() -> str:
            left = [f"{m.fqn} ({m.state})" for m in self.lifecycle.nodes.values() if m.state != "finalized"]
            return f"lifecycle: nodes not shut down within {bound:g} s: {', '.join(left) or '(not found)'}"
        t0 = time.monotonic()
        try:
            self._spin_until(down, bound, late)
        finally:
            self._lifecycle_busy = False
        print(f"clock: lifecycle: {len(self.lifecycle.nodes)} nodes shut down in {time.monotonic() - t0:.1f} s "
              f"({self.lifecycle.lost_answers()} answers lost)", file=sys.stderr, flush=True)

    # -- waiting ------------------------------------------------------------------------------------
    def _spin_until(self, cond, timeout_s: float, on_timeout) -> None:
        deadline = time.monotonic() + timeout_s
        spin = self.executor.spin_once
        while not cond():
            if self._stop_requested:
                raise KeyboardInterrupt
            if time.monotonic() > deadline:
                raise ClockError(on_timeout())
            if self.bag is not None:
                self._poll_graph()
            if self._lifecycle_busy:
                self.lifecycle.poll()
            if self.rejoins:
                self._serve_rejoins()
            spin(timeout_sec=0.02)

    def _who(self, roles) -> str:
        parts = []
        for r in roles:
            h = self.hellos.get(r)
            ps = ",".join(h.participants) if h else "?"
            parts.append(f"{r} (participants {ps})")
        return "; ".join(parts)

    def _wait_ready(self) -> None:
        """Wait until every host said hello (it is ready: participants built, kernels loaded).

        Separate from the per-step deadline: a slow start (a cold numba cache, a loaded machine) is
        waited for, and every ``_READY_REPORT_S`` the hosts not ready yet are named, with how long
        the clock has waited, on stderr and as a ``waiting`` record on stdout (the launcher's progress).
        Bounded only when the spec says so (``startup_timeout_s``; None: as long as it takes)."""
        spec = self.spec
        t0 = time.monotonic()
        bound = float("inf") if spec.startup_timeout_s is None else spec.startup_timeout_s

        def ready() -> bool:
            self._lifecycle_check()
            return len(self.hellos) == len(self.roles)

        self._lifecycle_busy = True  # every node brought to active meanwhile
        while not ready():
            waited = time.monotonic() - t0
            try:
                self._spin_until(ready, max(0.0, min(_READY_REPORT_S, bound - waited)), lambda: "")
            except LifecycleFailed:
                raise
            except ClockError:
                waited = time.monotonic() - t0
                missing = [r for r in self.roles if r not in self.hellos]
                if waited >= bound:
                    raise ClockError(f"hosts not ready after {waited:.0f} s: " + self._who(missing)) from None
                print(f"clock: waiting for {len(missing)} of {len(self.roles)} processes to be ready "
                      f"after {waited:.0f} s: {', '.join(missing)}", file=sys.stderr, flush=True)
                self._out({"waiting": {"not_ready": missing, "roles": len(self.roles),
                                       "wall_s": round(waited, 1), "horizon_ns": self.horizon_ns}})
        self._lifecycle_busy = False
        print(f"clock: lifecycle: {len(self.lifecycle.nodes)} nodes active, every process ready after "
              f"{time.monotonic() - t0:.1f} s ({self.lifecycle.lost_answers()} answers lost)", file=sys.stderr, flush=True)

    def _alone_on_domain(self) -> None:
        """ClockError when another run's clock is on this ROS domain: two runs on one domain use the
        same topic names, so each one's subscriptions count as matched for the other's publishers,
        a host can publish before its own run's subscribers have matched and envelopes are lost (seen:
        'recorder is missing envelopes'). Checked once every host said hello (by then DDS discovery
        has found the other run's nodes); each run's MACs keep the other's messages out, not this."""
        name = self.node.get_name()
        clocks = [f"{ns.rstrip('/')}/{n}" for n, ns in self.node.get_node_names_and_namespaces() if n == name]
        others = list(clocks)
        others.remove(f"{self.node.get_namespace().rstrip('/')}/{name}")  # (this clock, listed once)
        if others:
            dom = os.environ.get("ROS_DOMAIN_ID", "0")
            raise ClockError(f"another run is on ROS_DOMAIN_ID {dom} (its clock {others[0]}): two runs on one domain "
                             "lose each other's messages; choose another --domain-id (or none: a free one is leased)")

    def _publish_step(self, msg: StepMsg) -> None:
        if not msg.start and not msg.stop:
            c = clock_cdr(self.epoch_ns + msg.t_ns)  # rosgraph_msgs/Clock serialized (bringup/recording/bag_format.py)
            self.clock_pub.publish(c)
            if self.bag is not None:
                self.bag.write_raw("/clock", _CLOCK, c, msg.t_ns)
                if self.viz is not None:
                    for topic, msgtype, cdr in self.viz.frame(msg.t_ns, self.epoch_ns + msg.t_ns):
                        self.bag.write_raw(topic, msgtype, cdr, msg.t_ns)
                        self.live.publish(topic, cdr)
                    self.metrics.write(self.bag, msg.t_ns, in_flight=self.in_flight,
                                       complete=self._observations_recorded())
        text = encode_msg(msg)
        self.step_pub.publish(string_cdr(self.gate.auth.seal(STEP_TOPIC, text)))
        if self.bag is not None:
            self.bag.write_raw(STEP_TOPIC, _STRING, string_cdr(text), msg.t_ns)

    def _progress(self, t_ns: int, wall_s: float, done: bool = False) -> None:
        rec = {"t_ns": t_ns, "horizon_ns": self.horizon_ns, "steps": self.steps, "wall_s": round(wall_s, 4)}
        if self.in_flight is not None:
            rec["in_flight"] = self.in_flight
        self._out({"done" if done else "progress": rec})

    def _out(self, rec: dict) -> None:
        """A progress record on stdout (the launcher reads it). A closed pipe means the launcher is
        gone: the run stops (hosts told, bag closed), as on SIGTERM."""
        try:
            print(json.dumps(rec), flush=True)
        except (BrokenPipeError, OSError):
            if not self._stop_requested:
                print("clock: the launcher's pipe is closed (launcher gone): stopping", file=sys.stderr, flush=True)
            self._stop_requested = True

    # -- checkpoint (clock restart) -------------------------------------------------------------------
    def _state(self, k: int, t: int, msg: StepMsg, wall_s: float) -> bytes:
        return pickle.dumps({
            "k": k, "t_ns": t, "msg": encode_msg(msg), "totals": dict(self.totals), "steps": self.steps,
            "hellos": {r: encode_msg(h) for r, h in self.hellos.items()}, "rec_topics": list(self.rec_topics),
            "wall_s": wall_s, "incarnation": self._incarnation, "rejoined": dict(self.rejoined), "reannounces": self.reannounces,
            "viz": (self.viz.next_ns, self.viz.written) if self.viz is not None else None,
            "metrics": ((self.metrics.next_value_ns, self.metrics.next_flight_ns, self.metrics.written)
                        if self.metrics is not None else None),
        }, protocol=pickle.HIGHEST_PROTOCOL)

    def _restore(self) -> tuple[int, int, StepMsg, float] | None:
        """State of the checkpoint found at start; the recorder's keys, counts and re-send buffer
        come back from the journal's rows."""
        k, st = self.resumed  # type: ignore[misc]
        if st.get("done"):
            print("clock: restarted after the run had finished; exporting the bag", file=sys.stderr, flush=True)
            return None
        self.totals = dict(st["totals"])
        self.steps = int(st["steps"])
        self.hellos = {r: decode_ack(txt) for r, txt in st["hellos"].items()}
        self.rejoined = dict(st["rejoined"])
        self.reannounces = int(st.get("reannounces", 0))
        self._incarnation = int(st.get("incarnation", 0)) + 1
        if self.viz is not None and st["viz"] is not None:
            self.viz.next_ns, self.viz.written = st["viz"]
        if self.metrics is not None and st.get("metrics") is not None:
            # every observation the journal committed goes to the value series again (folded whole
            # at the next point: the ledger only depends on the set, taken in time order)
            self.metrics.next_value_ns, self.metrics.next_flight_ns, self.metrics.written = st["metrics"]
            for topic, cdr in self.journal.rows_on("/observations"):
                self.metrics.observe(decode_envelope(string_from_cdr(cdr), topic))
        for topic in st["rec_topics"]:
            self._record(topic)
        lo = k - _RESEND_STEPS
        for kk, topic, source, seq, cdr in self.journal.keyed_rows(min_k=lo):
            self._rec_keys.add((topic, source, seq))
            self.rec_counts[topic] = self.rec_counts.get(topic, 0) + 1
            if cdr is not None:  # recorded without MAC: sealed again for re-sends
                env = decode_envelope(string_from_cdr(cdr), topic)
                self.recent.setdefault(topic, []).append((kk, self.gate.wire(env)))
        print(f"clock: restarted from its checkpoint: resuming at wire step {k} (t = {st['t_ns'] / 1e9:.3f} s), "
              f"{sum(self.rec_counts.values())} envelopes already recorded", file=sys.stderr, flush=True)
        return k, int(st["t_ns"]), decode_step(st["msg"]), float(st["wall_s"])

    def _recorded_all(self) -> bool:
        return all(self.rec_counts.get(tp, 0) >= n for tp, n in self.totals.items())

    def _observations_recorded(self) -> bool:
        """The recorder holds every observation envelope the acks counted (the value series' points)."""
        return all(self.rec_counts.get(tp, 0) >= n for tp, n in self.totals.items() if tp.endswith("/observations"))

    def _missing(self) -> dict[str, int]:
        return {tp: n - self.rec_counts.get(tp, 0) for tp, n in self.totals.items() if self.rec_counts.get(tp, 0) < n}

    def _wait_recorded(self, msg: StepMsg) -> None:
        """Before checkpointing the next step: the recorder must hold every envelope counted so far.
        Every ``_REANNOUNCE_S`` without them the step is published again (not recorded): hosts that
        ran it re-send its envelopes."""
        spec = self.spec
        self._spin_reannouncing(self._recorded_all, spec.ack_timeout_s + spec.restart_wait_s, msg,
                                lambda: f"recorder is missing envelopes of step {msg.k}: {self._missing()}",
                                lambda: f"recorder misses {self._missing()} after step {msg.k}")

    def _spin_reannouncing(self, cond, timeout_s: float, msg: StepMsg, on_timeout, why) -> None:
        """:meth:`_spin_until`, publishing the step ``msg`` again every ``_REANNOUNCE_S`` while
        ``cond`` is false (hosts that ran it answer with their saved ack and re-send its envelopes);
        ``why()``: what is missing, for the stderr line of each re-announcement."""
        deadline = time.monotonic() + timeout_s
        while True:
            try:
                self._spin_until(cond, min(_REANNOUNCE_S, max(0.0, deadline - time.monotonic())), on_timeout)
                return
            except ClockError:
                if time.monotonic() >= deadline:
                    raise
            self.reannounces += 1
            print(f"clock: {why()}; step re-announced", file=sys.stderr, flush=True)
            self.step_pub.publish(String(data=self.gate.sealed(STEP_TOPIC, msg)))

    # -- the run ------------------------------------------------------------------------------------
    def run(self) -> int:
        spec = self.spec
        if self.resumed is not None:
            got = self._restore()
            if got is None:
                return 0
            k, t, msg, wall_done = got
        else:
            self._wait_ready()
            if not os.environ.get(ENV_RESTARTED):  # (a restarted clock's dead predecessor may linger in the graph)
                self._alone_on_domain()
            rec = 1 if (self.bag is not None or self.restart) else 0
            subs: dict[str, int] = {}
            for h in self.hellos.values():
                for topic, n in h.subscriptions.items():
                    subs[topic] = subs.get(topic, 0) + n
            if rec:
                for topic in subs:
                    self._record(topic)
                    subs[topic] += 1
            k, t = 0, self.t0_ns
            msg = StepMsg(k=0, t_ns=t, start=True, subs=subs, subs_default=rec)
            wall_done = 0.0
        wall0 = time.monotonic() - wall_done
        next_progress = time.monotonic() + spec.progress_period_s
        resumed_step = self.resumed is not None
        self.running = True
        while True:
            self.acks.clear()
            self.cur_k = k
            if self.journal is not None:
                self.journal.commit(k, self._state(k, t, msg, time.monotonic() - wall0))
                self.journal.k = k
            if self.restart and k % _RESEND_STEPS == 0:
                self._prune_recent()
            if spec.real_time_factor and not msg.start:
                due = wall0 + (t - self.t0_ns) / 1e9 / spec.real_time_factor
                self._spin_until(lambda: time.monotonic() >= due, float("inf"), lambda: "")
            self._publish_step(msg)
            # the first step of a restarted clock is published before every host's subscription has
            # matched the new publisher (and their acks before its subscription has): re-announced
            # until every ack is in (hosts that ran it answer with their saved ack)
            self._wait_acks(k, t, first=msg.start, reannounce=msg if resumed_step else None)
            resumed_step = False
            failed = [a for a in self.acks.values() if a.error]
            if failed:
                raise ClockError("; ".join(f"host {a.participant} failed at step {k}: {a.error}" for a in failed))
            if not msg.start:
                self.steps += 1
            sent: dict[str, int] = {}
            seq_end: dict[str, int] = {}
            wakes = []
            in_flight = None
            for a in self.acks.values():
                for topic, n in a.sent.items():
                    sent[topic] = sent.get(topic, 0) + n
                    self.totals[topic] = self.totals.get(topic, 0) + n
                seq_end.update(a.seq_end)
                wakes.append(a.next_wakeup_ns)
                if a.in_flight is not None:
                    in_flight = (in_flight or 0) + a.in_flight
            self.in_flight = in_flight
            if self.journal is not None:
                self._wait_recorded(msg)
            now = time.monotonic()
            if now >= next_progress:
                next_progress = now + spec.progress_period_s
                self._progress(t, now - wall0)
            if msg.final:
                break
            if msg.start:
                nt = t
            else:
                nt = next_step_ns(t, wakes, self.max_step_ns, self.horizon_ns)
            k, t = k + 1, nt
            msg = StepMsg(k=k, t_ns=t, final=t >= self.horizon_ns, sent=sent, seq_end=seq_end)
        # the recorder must hold everything before the bag closes
        if self.bag is not None:
            self._spin_until(self._recorded_all, spec.ack_timeout_s,
                             lambda: "recorder is missing envelopes: " + str(self._missing()))
        wall = time.monotonic() - wall0
        if self.metrics is not None:  # the series' last points (everything is recorded now)
            self.metrics.write(self.bag, t, in_flight=self.in_flight, final=True)
        if self.bag is not None and self.meta is not None:
            runtime = {"wall_s": wall, "steps": self.steps,
                       "real_time_factor": ((t - self.t0_ns) / 1e9 / wall) if wall > 0 else None}
            if self.journal is not None:
                runtime["clock_restarts"] = self.clock_restarts()
            self.bag.write_envelope(Envelope(t, "run", 1, "/run/meta", json.dumps(
                {"meta": self.meta, "runtime": runtime, "security": self.security()})))
        if self.journal is not None:
            self.journal.commit(k, pickle.dumps({"done": True}))
        self._shut_down_nodes()
        self._progress(t, wall, done=True)
        return 0

    def security(self) -> dict:
        """What the run's processes rejected: ``{"rejected_by_process": {process: {topic: {reason:
        n}}}}`` (the clock's own and each host's last ack; bringup/analysis/report.py sums it)."""
        by = {r: c for r, c in sorted(self.host_rejected.items()) if c}
        own = self.gate.rejections.counts()
        if own:
            by = {CLOCK_ROLE: own, **by}
        return {"rejected_by_process": by}

    def clock_restarts(self) -> int:
        """How many times this run's clock was restarted (0 without a journal)."""
        return self._incarnation

    def _wait_acks(self, k: int, t: int, first: bool = False, reannounce: StepMsg | None = None) -> None:
        """Every host's ack of step k within the ack deadline (then, with restarts, the restart wait);
        ``reannounce``: the step message, published again every ``_REANNOUNCE_S`` while acks miss."""
        spec = self.spec
        timeout = max(spec.ack_timeout_s, _FIRST_STEP_ACK_S) if first else spec.ack_timeout_s

        def all_acked() -> bool:
            return len(self.acks) == len(self.roles)

        def who() -> str:
            return (f"no ack for step {k} (t = {t / 1e9:.3f} s) within {{:g}} s from "
                    + self._who(r for r in self.roles if r not in self.acks))
        try:
            if reannounce is not None:
                self._spin_reannouncing(all_acked, timeout, reannounce, lambda: who().format(timeout),
                                        lambda: who().format(_REANNOUNCE_S) + " after the restart")
            else:
                self._spin_until(all_acked, timeout, lambda: who().format(timeout))
        except ClockError as exc:
            if not self.restart or isinstance(exc, LostStateError):
                raise
            print(f"clock: {exc}; waiting up to {spec.restart_wait_s:g} s for it to restart",
                  file=sys.stderr, flush=True)
            self._spin_until(all_acked, spec.restart_wait_s,
                             lambda: who().format(spec.ack_timeout_s + spec.restart_wait_s) + " (no restart)")

    def stop_hosts(self, reason: str = "") -> None:
        try:
            self.step_pub.publish(String(data=self.gate.sealed(STEP_TOPIC, StepMsg(k=0, t_ns=0, stop=True, reason=reason))))
            self.step_pub.wait_for_all_acked(Duration(seconds=2.0))
        except Exception:  # noqa: BLE001 - best effort on the way out
            pass

    def close(self, dds: bool = True) -> None:
        """Close the bag (or export the journal into it) and (``dds``) destroy the node and the
        context; a process that exits right after passes ``dds=False`` (bringup/engine/ros/host.py exit_now)."""
        try:
            if self.journal is not None:
                try:
                    if self.spec.bag_dir:
                        self.journal.export(self.spec.bag_dir, custom=self.bag_custom)
                finally:
                    self.journal.close()
            elif self.bag is not None:
                self.bag.close()
            if not dds:
                return
            self.executor.shutdown(timeout_sec=1.0)
            self.node.destroy_node()
        finally:
            if dds:
                rclpy.try_shutdown(context=self.ctx)


def run_clock(spec: RunSpec, on_closed=None) -> int:
    """Process entry of the clock role. Exit code 0 ok, 3 a host failed or went silent (named on
    stderr), 130 interrupted (hosts told to stop, bag closed). ``on_closed(rc)``, if given, runs once
    the bag is closed, before the process ends (a container's clock writes the run's report there);
    an exception in it is printed and makes the exit code 1."""
    # SIGUSR1 writes every thread's Python stack into the log (bringup/engine/ros/launcher.py, before a SIGKILL)
    faulthandler.register(signal.SIGUSR1, all_threads=True)
    clock = LockstepClock(spec)
    # every way a run is stopped (a terminal's SIGHUP or Ctrl-\\ reach every process of its group too):
    # the ordinary stop (bringup/stop_signals.py)
    for sig in STOP_SIGNALS:
        signal.signal(sig, clock.request_stop)
    try:
        rc = clock.run()
        clock.stop_hosts()
    except KeyboardInterrupt:
        clock.stop_hosts(INTERRUPTED)
        print("clock: interrupted; hosts told to stop, bag closed", file=sys.stderr)
        rc = 130
    except ClockError as exc:
        clock.stop_hosts(str(exc))
        print(f"clock: error: {exc}", file=sys.stderr)
        rc = 3
    except BaseException:
        clock.close()
        raise
    # the bag is closed here; the DDS participant is not destroyed (a FastDDS deadlock: exit_now)
    clock.close(dds=False)
    if on_closed is not None:
        try:
            on_closed(rc)
        except Exception as exc:  # noqa: BLE001 - the bag is safe; say what failed after it
            print(f"clock: error after the run: {type(exc).__name__}: {exc}", file=sys.stderr)
            rc = rc or 1
    exit_now(rc)
    return rc  # not reached
