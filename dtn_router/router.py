"""The ISL medium as a lockstep participant: bundles cross only during contacts (docs/design.md section 5).

Reads every satellite's ``/sat_XX/dtn/out`` (raw BPv7 bytes, stamped with the transmission's start
time by the sending agent), checks the transmission against the truth contact plan with
dtn_router/link.py (for each intended next hop named in the bundle's next-hops block - several for
a multicast transmission - a contact from the sender covers it, the sender's radio is free, the
transmission ends before the contact does), and delivers a copy to every satellite in contact with
the sender at that time (broadcast medium) on ``/sat_YY/dtn/in``, stamped with its arrival time
(start + bits / rate + light time). The bits on air are the scenario's bundle size plus the copy's
recipient-list overhead (sat_node/dtn/routing_blocks.py overhead_bits), read from the bytes. A delivery waits in the router until the step that
reaches its arrival time (contract rule 2: nothing is emitted stamped in the future), and the router
asks to be woken exactly then.

With ``overheard`` (the receivers' forwarding, ``multicast`` or ``unicast``; what ``for_world`` passes),
a copy its receiver's agent would only count (it names other next hops: sat_node/dtn/overhearing.py
``only_counted``) is not an envelope of its own: at the step that reaches its arrival it is counted,
and each receiver gets one ``/sat_YY/dtn/overheard`` (msgs_json CopiesOverheard: how many, stamped
with the latest of their arrivals) in place of them. The receiver counts that number where it would
have counted each copy (DtnPort), at the same step, so every counter and event of the run is the
same; a receiver that would have had any such copy in a step has this one message in it, so an
event-driven receiver is called at the same steps. Without ``overheard`` every copy is an envelope.

A transmission the truth plan does not carry (the contact ends before its last bit - e.g. an ISL
cut the agents' predicted plan does not know -, no contact to the next hop, the sender's radio still
busy) is not delivered to anyone; the sender is told on ``/sat_XX/dtn/status``
(msgs_json TransmissionFailed) at the time the attempt ended, at the first step at or after that
time - and the router then asks for the next step at once, so the sender learns of it 1 ns later
whatever the step length -; its agent takes the bundle back and re-routes it (Nag et al. rely on CGR's contact plan; the status path is what a real medium's missing
acknowledgement gives). Inputs that are not bundles of a known satellite are rejected and counted
by reason (``rejected_by_reason``).

The truth plan is the agents' plan with the run's faults (ISL cuts, extra light time:
orbit_clock/contact_faults.py), the same the contact-window announcer publishes
(orbit_clock/contact_announcer.py). After each step the router reports how many copies it still
holds (``StepResult.in_flight``: accepted, arrival ahead), which both engines show as progress.

Oracle: tests/unit/test_overheard_counts.py runs the same senders through a medium with and
without ``overheard`` and checks that the receivers end with the same counters and events, and that
the copies kept as envelopes are, message by message, those the receivers do not only count. The system test checks from the bag that every delivery on /sat_YY/dtn/in lies inside a
contact from its sender with the link delay (tests/system/test_engines_equal.py).
"""

from __future__ import annotations

import heapq
import itertools

from dtn_router.link import LinkModel
from msgs_json import codec
from msgs_json import schemas as S
from msgs_json import topics as T
from msgs_json.envelope import Emit, Envelope, LiveState, StepResult
from orbit_clock.contact_faults import truth_plan as with_faults
from orbit_clock.contact_plan import ContactPlan, node_name, node_number
from sat_node.dtn.bpv7 import BundleError, decode_bundle
from sat_node.dtn.overhearing import FORWARDINGS_COUNTED, only_counted
from sat_node.dtn.routing_blocks import overhead_bits, peek_next_hops

__all__ = ["RouterLogic", "ROUTER_NAME"]

ROUTER_NAME = "dtn_router"
_NS = 1_000_000_000


class RouterLogic:
    """The medium between the nodes ``sats``; ``plan``: the truth contact plan; ``bundle_bits``:
    the size of a bundle on the link (the study's 2000 bits); ``overheard``: the receivers'
    forwarding, to send the copies they only count as counts (module docstring; None: every copy)."""

    name = ROUTER_NAME

    def __init__(self, sats, plan: ContactPlan, bundle_bits: int, *, overheard: str | None = None):
        if overheard is not None and overheard not in FORWARDINGS_COUNTED:
            raise ValueError(f"overheard={overheard!r}: None or one of {', '.join(FORWARDINGS_COUNTED)}")
        self.overheard = overheard
        self.sats = list(sats)
        self._sat_set = frozenset(self.sats)
        self.bits = int(bundle_bits)
        self.link = LinkModel(plan)
        # (arrival_ns, receiver, order, bytes); bytes None: a copy the receiver only counts (``overheard``)
        self.pending: list[tuple[int, str, int, bytes | None]] = []
        self._order = itertools.count()
        self.rejected = 0
        self.rejected_by_reason: dict[str, int] = {}
        self.failures: dict[str, int] = {}
        self.status_pending: list[tuple[int, int, str, str]] = []  # (t_ns, order, sender, json text)
        # topic names per satellite, made once (~200k copies per paper run go out on them)
        self._in_topic = {s: T.dtn_in_topic(s) for s in self.sats}
        self._out_topic = {s: T.dtn_out_topic(s) for s in self.sats}
        self._status_topic = {s: T.dtn_status_topic(s) for s in self.sats}
        self._overheard_topic = {s: T.dtn_overheard_topic(s) for s in self.sats}
        self._number = {s: node_number(s) for s in self.sats}
        self.copies_counted = 0  # copies sent as counts (on /sat_YY/dtn/overheard) instead of envelopes

    @classmethod
    def for_world(cls, world, *, extra_delay_s: float = 0.0,
                  cuts: list[tuple[str, str, float, float]] | None = None) -> "RouterLogic":
        """The medium of a scenario's world (bringup/scenario/world.py): its satellites, its ISL plan
        with the run's faults, its bundle size."""
        plan = with_faults(world.isl_plan, cuts=cuts, extra_delay_s=extra_delay_s)
        isl = world.scenario.isl
        return cls(world.sat_names, plan, isl.bundle_bits, overheard=isl.forwarding)

    def subscriptions(self) -> list[str]:
        return [T.dtn_out_topic(s) for s in self.sats]

    def start(self, t0_ns: int) -> StepResult:
        return StepResult([], self._wakeup(t0_ns), len(self.pending))

    def step(self, t_ns: int, inbox: list[Envelope]) -> StepResult:
        for env in inbox:
            self._transmit(env)
        emits = []
        counted: dict[str, list[int]] = {}  # receiver -> [copies only counted, latest arrival]
        while self.pending and self.pending[0][0] <= t_ns:
            arrival, receiver, _, data = heapq.heappop(self.pending)
            if data is None:
                c = counted.get(receiver)
                if c is None:
                    counted[receiver] = [1, arrival]
                else:
                    c[0] += 1
                    c[1] = arrival  # (popped in arrival order)
                continue
            emits.append(Emit(self._in_topic[receiver], data, arrival))
        for receiver, (n, last) in counted.items():
            msg = S.CopiesOverheard(sat=receiver, t_ns=last, copies=n)
            emits.append(Emit(self._overheard_topic[receiver], codec.encode(msg), last))
            self.copies_counted += n
        reported = False
        while self.status_pending and self.status_pending[0][0] <= t_ns:
            at, _, sender, text = heapq.heappop(self.status_pending)
            emits.append(Emit(self._status_topic[sender], text, at))
            reported = True
        wake = self._wakeup(t_ns)
        if reported:  # the sender learns of a failure at the very next step, whatever the step length
            wake = t_ns + 1
        return StepResult(emits, wake, len(self.pending))

    def finish(self, t_ns: int) -> list[Emit]:
        return []

    def live_state(self, t_ns: int) -> LiveState:
        """What the medium shows while a ROS run goes on (msgs_json.envelope.LiveState): the bundle
        copies travelling, failed transmissions and rejected inputs by reason. Reads only."""
        v: dict[str, int | float | str] = {"in_flight": len(self.pending), "status_pending": len(self.status_pending),
                                           "rejected_messages": self.rejected}
        v.update((f"failed.{k}", n) for k, n in self.failures.items())
        v.update((f"rejected.{k}", n) for k, n in self.rejected_by_reason.items())
        msg = f"{len(self.pending)} bundle copies in flight, {sum(self.failures.values())} transmissions failed"
        if self.rejected:
            msg += f", {self.rejected} inputs rejected"
        return LiveState(None, v, 1 if self.rejected else 0, msg)

    def _transmit(self, env: Envelope) -> None:
        if not isinstance(env.data, bytes):
            return self._reject("not_bytes")
        if env.topic != self._out_topic.get(env.source):
            return self._reject("unknown_sender")
        try:
            hops = tuple(node_name(nh) for nh in peek_next_hops(env.data))
            bits = self.bits + overhead_bits(env.data)
        except (BundleError, ValueError):
            return self._reject("malformed")
        if not hops:
            return self._reject("no_next_hop")
        if not all(h in self._sat_set for h in hops):
            return self._reject("unknown_next_hop")
        out = self.link.transmit(env.source, hops[0] if len(hops) == 1 else hops, env.t_ns, bits)
        if not out.ok:
            for h, reason in out.failed.items():
                self.failures[reason] = self.failures.get(reason, 0) + 1
                self._tell_failed(env, h, reason, out.end_ns)
            if len(out.failed) == len(hops):  # nobody it was meant for got it: no copy goes out
                return
        fw = self.overheard
        if fw is None:
            for cp in out.copies:
                heapq.heappush(self.pending, (cp.arrival_ns, cp.node, next(self._order), env.data))
            return
        nhs = tuple(self._number[h] for h in hops)
        number = self._number
        for cp in out.copies:
            data = None if only_counted(fw, nhs, number[cp.node]) else env.data
            heapq.heappush(self.pending, (cp.arrival_ns, cp.node, next(self._order), data))

    def _reject(self, reason: str) -> None:
        self.rejected += 1
        self.rejected_by_reason[reason] = self.rejected_by_reason.get(reason, 0) + 1

    def _tell_failed(self, env: Envelope, next_hop: str, reason: str, end_ns: int) -> None:
        """Queue a TransmissionFailed for the sender (one per next hop that missed it), stamped when
        the attempt ended."""
        try:
            bid = decode_bundle(env.data).bundle_id
        except (BundleError, ValueError):
            return self._reject("malformed")
        reason = reason if reason in ("contact_ended", "no_contact", "radio_busy") else "other"
        at = max(int(end_ns), env.t_ns)
        msg = S.TransmissionFailed(sat=env.source, t_ns=at, bundle_id=bid, next_hop=next_hop,
                                   start_ns=env.t_ns, reason=reason)
        heapq.heappush(self.status_pending, (at, next(self._order), env.source, codec.encode(msg)))

    def _wakeup(self, t_ns: int) -> int | None:
        cands = []
        if self.pending:
            cands.append(self.pending[0][0])
        if self.status_pending:
            cands.append(self.status_pending[0][0])
        cands = [c for c in cands if c > t_ns]
        return min(cands) if cands else None
