"""Lockstep barrier of the ROS engine: the step/ack messages and the bookkeeping both ends share.

Pure module (no rclpy): the clock node (bringup/engine/ros/clock_node.py) and the participant host
(bringup/engine/ros/host.py) are thin adapters around it. It implements the rules of
msgs_json/envelope.py for participants spread over several OS processes, with one message out
(/sim/step) and one message back per process (/sim/ack) per step (docs/design.md section 7,
lockstep traps 3-6):

* wire index ``k``: ``k = 0`` is the *start phase* (every participant's ``start(t0)``), ``k >= 1``
  is engine step ``k - 1`` at ``t_ns``; ``final`` marks the step at the horizon (then ``finish``);
  ``stop`` (sent after the final ack, or on abort) tells every host to exit.
* count-based delivery (trap 5): each ack reports how many envelopes its process emitted per topic
  (``sent``) and every source's cumulative seq counter (``seq_end``); the next step message carries
  those (as deltas), so a receiver knows how many envelopes of the previous steps it must hold on
  each topic before it runs the step, and which early arrivals (``seq >= seq_end[src]``) belong to a
  later step (trap 6).
* rule 3, the step rule, is the engine contract's (bringup/engine/contract.py ``next_step_ns``): the
  clock applies it to the earliest wakeup the hosts acked.
* crash and restart: a host checkpoints after every step (bringup/engine/checkpoint.py) and, when
  restarted, says hello with ``resume_k`` = the last wire step it committed; the clock then re-sends
  (on :data:`RESEND_TOPIC`, :class:`ResendMsg`) the envelopes it recorded on that host's topics
  during the last few steps, and the host re-runs from ``resume_k + 1``. Re-running a step re-emits
  the same envelopes with the same (source, seq), so every receiver drops what it already holds
  (:meth:`TopicInbox.add` returns False for a duplicate): delivery stays exactly-once.
* clock restart: the clock checkpoints before publishing each step; a restarted clock
  publishes that step again. A host that already ran it (``k == done_k``) does not run it again: it
  re-publishes that step's envelopes and its saved ack (a duplicate ack is ignored by the clock, a
  duplicate envelope by every receiver). The clock may also re-announce the current step (same
  message, not recorded) when its recorder misses envelopes; hosts answer the same way.

Oracle: tests/ros/test_lockstep.py runs toy participants under this protocol over DDS and checks the
envelopes equal those of the in-process local engine (bringup/engine/local.py) for the same
participants; :class:`TopicInbox` is exercised by the same runs.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import msgspec

from msgs_json.auth import AuthError, RunAuth
from msgs_json.envelope import Envelope
from msgs_json.schemas import SimAck, SimStep
from msgs_json.wire import WireError, decode_envelope_mac, encode_envelope, string_from_cdr, without_mac

__all__ = [
    "ACK_TOPIC",
    "INTERRUPTED",
    "RESEND_TOPIC",
    "STEP_TOPIC",
    "AckMsg",
    "Gate",
    "LockstepError",
    "Rejections",
    "ResendMsg",
    "StepMsg",
    "TopicInbox",
    "decode_ack",
    "decode_resend",
    "decode_step",
    "encode_msg",
]

STEP_TOPIC = "/sim/step"
# The stop message's reason when the run was interrupted (Ctrl-C, SIGTERM, launcher gone): hosts exit 130.
INTERRUPTED = "interrupted"
ACK_TOPIC = "/sim/ack"
# Not recorded (the recorder skips /_lockstep/*): the clock's re-sends to a restarted host.
RESEND_TOPIC = "/_lockstep/resend"


class LockstepError(ValueError):
    """A protocol violation or a malformed step/ack text; the message says what and where."""


class StepMsg(SimStep, kw_only=True, frozen=True):
    """/sim/step: msgs_json SimStep plus what the hosts need to run it.

    ``sent``: envelopes emitted per topic in the previous wire step (k-1); ``seq_end``: per source,
    its seq counter after step k-1 (only sources that emitted); ``subs`` (k = 0 only): per topic,
    how many subscriptions must be matched before anything is published on it; ``subs_default``:
    the same for topics not listed (the recorder's own subscription); ``start``/``stop``: phases.
    """

    start: bool = False
    stop: bool = False
    reason: str = ""
    sent: dict[str, int] = {}
    seq_end: dict[str, int] = {}
    subs: dict[str, int] = {}
    subs_default: int = 0


class AckMsg(SimAck, kw_only=True, frozen=True):
    """/sim/ack: one per host process per step. ``participant`` is the host (role) name.

    ``hello`` (before the start phase): ``participants`` hosted and ``subscriptions`` (topic ->
    number of subscriptions this host holds). Otherwise ``next_wakeup_ns`` is the earliest wakeup of
    the host's participants, ``sent`` its emits per topic and ``seq_end`` its sources' seq counters.
    ``error`` (non-empty): the host failed this step and says why. ``resume_k`` (hello only): -1 for a
    fresh start, else the last wire step the host committed to its checkpoint before it restarted.
    ``in_flight``: the sum of the host's participants' ``StepResult.in_flight`` after this step
    (items held to emit later, e.g. bundle copies still travelling: what the local engine's progress
    shows), None when none reports one; the clock passes the sum on in its progress records.
    ``rejected``: what the host rejected so far, ``{topic: {reason: count}}`` (:class:`Rejections`);
    the clock writes the last one of each host into the run's /run/meta record (the report's
    ``security`` section).
    """

    hello: bool = False
    resume_k: int = -1
    participants: list[str] = []
    subscriptions: dict[str, int] = {}
    seq_end: dict[str, int] = {}
    error: str = ""
    in_flight: int | None = None
    rejected: dict[str, dict[str, int]] = {}


class ResendMsg(msgspec.Struct, kw_only=True, frozen=True, forbid_unknown_fields=True):
    """/_lockstep/resend: envelopes (wire texts, msgs_json/wire.py) the clock recorded on ``topic``,
    re-sent to the restarted host ``to``."""

    to: str
    topic: str
    wires: list[str] = []


_enc = msgspec.json.Encoder()
_resend_dec = msgspec.json.Decoder(ResendMsg)
_step_dec = msgspec.json.Decoder(StepMsg)
_ack_dec = msgspec.json.Decoder(AckMsg)


def encode_msg(msg: StepMsg | AckMsg | ResendMsg) -> str:
    return _enc.encode(msg).decode("utf-8")


def decode_step(text: str) -> StepMsg:
    try:
        return _step_dec.decode(text)
    except (msgspec.DecodeError, msgspec.ValidationError, ValueError) as exc:
        raise LockstepError(f"{STEP_TOPIC}: bad step message: {exc}") from None


def decode_ack(text: str) -> AckMsg:
    try:
        return _ack_dec.decode(text)
    except (msgspec.DecodeError, msgspec.ValidationError, ValueError) as exc:
        raise LockstepError(f"{ACK_TOPIC}: bad ack message: {exc}") from None


def decode_resend(text: str) -> ResendMsg:
    try:
        return _resend_dec.decode(text)
    except (msgspec.DecodeError, msgspec.ValidationError, ValueError) as exc:
        raise LockstepError(f"{RESEND_TOPIC}: bad resend message: {exc}") from None


class Rejections:
    """Messages a process rejected, counted per (topic, reason), and when to say so in its log.

    ``add`` returns a log line for the first rejection of each (topic, reason), then at most one
    line per ``period_s`` per (topic, reason) with how many came since and in all (a flood of junk
    is a few lines, not one per message); None otherwise. ``counts()`` is ``{topic: {reason: n}}``,
    what the process reports (hosts in their acks, the clock in the run's /run/meta record).
    """

    def __init__(self, period_s: float = 5.0, clock=time.monotonic):
        self.period_s = period_s
        self._clock = clock
        self._n: dict[tuple[str, str], int] = {}
        self._next: dict[tuple[str, str], float] = {}
        self._since: dict[tuple[str, str], int] = {}

    def add(self, topic: str, reason: str, detail: str) -> str | None:
        key = (topic, reason)
        n = self._n[key] = self._n.get(key, 0) + 1
        now = self._clock()
        if n == 1 or now >= self._next.get(key, 0.0):
            since = self._since.get(key, 0) + 1
            self._since[key] = 0
            self._next[key] = now + self.period_s
            if n == 1:
                return f"rejected ({reason}): {detail}"
            return f"rejected ({reason}) {since} on {topic} in the last {self.period_s:g} s, {n} so far: {detail}"
        self._since[key] = self._since.get(key, 0) + 1
        return None

    def total(self) -> int:
        return sum(self._n.values())

    def counts(self) -> dict[str, dict[str, int]]:
        out: dict[str, dict[str, int]] = {}
        for (topic, reason), n in sorted(self._n.items()):
            out.setdefault(topic, {})[reason] = n
        return out


class Gate:
    """What one process of a run lets in: only messages authenticated under the run key
    (msgs_json/auth.py); the rest is counted by topic and reason (:class:`Rejections`) and logged
    through ``log`` (rate-limited). The host and the clock both use it, and it seals what they send."""

    def __init__(self, run_key: bytes, log: Callable[[str], None]):
        self.auth = RunAuth(run_key)
        self.rejections = Rejections()
        self._log = log

    def reject(self, topic: str, reason: str, detail: str) -> None:
        line = self.rejections.add(topic, reason, detail)
        if line is not None:
            self._log(line)

    def _verified(self, text: str, topic: str) -> tuple[Envelope, str] | None:
        """The envelope in wire ``text`` and its MAC if it is the run's (MAC verified), else None
        (counted by reason)."""
        try:
            env, mac = decode_envelope_mac(text, topic)
            self.auth.verify(env, mac)
        except WireError as exc:
            self.reject(topic, "malformed", str(exc))
            return None
        except AuthError as exc:
            self.reject(topic, exc.reason, str(exc))
            return None
        return env, mac

    def envelope(self, text: str, topic: str) -> Envelope | None:
        """The envelope in wire ``text`` received on ``topic`` if it is the run's (MAC verified)."""
        got = self._verified(text, topic)
        return None if got is None else got[0]

    def cdr_text(self, topic: str, raw: bytes) -> str | None:
        """The text of a std_msgs/String received serialized (CDR), else None (counted malformed)."""
        try:
            return string_from_cdr(raw)
        except ValueError as exc:
            self.reject(topic, "malformed", f"{topic}: {exc}")
            return None

    def envelope_wire(self, text: str, topic: str) -> tuple[Envelope, str] | None:
        """:meth:`envelope` and the envelope's wire text without its MAC (what a bag records):
        ``text`` less its mac field when it was written by :meth:`wire`, else encoded again."""
        got = self._verified(text, topic)
        if got is None:
            return None
        env, mac = got
        return env, without_mac(text, mac) or encode_envelope(env)

    def text(self, topic: str, text: str) -> str | None:
        """A lockstep message's JSON text (its MAC checked and taken off), else None (counted)."""
        try:
            return self.auth.open(topic, text)
        except AuthError as exc:
            self.reject(topic, exc.reason, str(exc))
            return None

    def wire(self, env: Envelope) -> str:
        """The wire text of one of our envelopes, with its MAC."""
        return encode_envelope(env, self.auth.mac(env))

    def sealed(self, topic: str, msg: StepMsg | AckMsg | ResendMsg) -> str:
        return self.auth.seal(topic, encode_msg(msg))


@dataclass
class TopicInbox:
    """What one subscription has received, split by step using the sources' seq counters.

    ``expected`` = envelopes on this topic emitted in all steps before the current one (sum of the
    step messages' ``sent``); ``seq_end`` (shared by all inboxes of a host) = per source, the seq
    counter at the end of the previous step. The inbox is *ready* when it holds every one of them
    (received count of envelopes with ``seq < seq_end[src]`` equals ``expected``); :meth:`take`
    then hands out those not yet delivered, in (t_ns, source, seq) order, and keeps later ones.
    ``consumed`` = ``seq_end`` at the last :meth:`take`: an envelope with ``seq < consumed[src]``, or one
    already pending, is a duplicate (a restarted sender re-running a step, or a re-send) and is
    dropped by :meth:`add` (counted in ``duplicates``).
    """

    topic: str
    expected: int = 0
    delivered: int = 0
    pending: list[Envelope] = field(default_factory=list)
    consumed: dict[str, int] = field(default_factory=dict)
    duplicates: int = 0
    _keys: set[tuple[str, int]] = field(default_factory=set)

    def add(self, env: Envelope) -> bool:
        """Buffer ``env``; False (and counted) when it is a duplicate of one held or delivered."""
        key = (env.source, env.seq)
        if env.seq < self.consumed.get(env.source, 0) or key in self._keys:
            self.duplicates += 1
            return False
        self._keys.add(key)
        self.pending.append(env)
        return True

    def ready(self, seq_end: dict[str, int]) -> bool:
        have = self.delivered + sum(1 for e in self.pending if e.seq < seq_end.get(e.source, 0))
        if have > self.expected:
            raise LockstepError(
                f"{self.topic}: received {have} envelopes of past steps but only {self.expected} were sent"
            )
        return have == self.expected

    def missing(self, seq_end: dict[str, int]) -> int:
        have = self.delivered + sum(1 for e in self.pending if e.seq < seq_end.get(e.source, 0))
        return self.expected - have

    def take(self, seq_end: dict[str, int]) -> list[Envelope]:
        now, later = [], []
        for e in self.pending:
            (now if e.seq < seq_end.get(e.source, 0) else later).append(e)
        self.pending = later
        self.delivered += len(now)
        self.consumed = dict(seq_end)
        self._keys = {(e.source, e.seq) for e in later}
        now.sort(key=Envelope.sort_key)
        return now
