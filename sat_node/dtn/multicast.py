"""Multicast bundle agent: one bundle per observation to its recipient list over the broadcast medium.

The study's satellites "broadcast" a bundle for every observation with a prioritised recipient list
(Nag et al., section 4); its simulator sent one unicast bundle per recipient (sat_node/dtn/agent.py
keeps that model). Here one bundle carries the whole list (sat_node/dtn/routing_blocks.py: imc group
destination, ION's IMC block, per-recipient priority and lifetime, the next-hop split), following
ION's IPN multicast (imcfw.c: each destination is routed by CGR and the destinations are grouped by
the entry node of their best route) with one change the broadcast ISL allows: instead of a clone per
entry node, ONE transmission serves every entry node whose route leaves now, and its next-hops block
tells each of them which recipients it is now responsible for.

Per node, for each bundle it holds, a set of recipients it is responsible for (each recipient of a
bundle is the responsibility of exactly one node at a time):

* :meth:`MulticastAgent.originate_many` - the observation's bundle with every recipient;
* :meth:`MulticastAgent.receive` - a copy that does not name this node among its next hops is
  discarded and counted (``overheard``); otherwise, of the recipients listed under this node: itself
  is delivered (once; a second copy is a duplicate), those whose deadline has passed are dropped
  (``ttl``, counted per recipient), the others are added to what it holds (one it already holds is a
  duplicate); a copy that adds nothing is discarded as a duplicate;
* :meth:`MulticastAgent.transmissions_until` - when the radio is free, the held bundles are taken by
  their most urgent remaining recipient (strict priority, then creation; or the earliest virtual
  deadline with ``priority_delay_s``). For a bundle, each remaining recipient is routed by CGR
  (cgr.py; the recipient's own deadline, the previous node excluded, the bits already waiting for a
  contact counted as SABR backlog; the recipients that share all of that but the deadline are routed
  by one search, which gives each the route of its own: ContactGraph.routes); a recipient no route
  reaches in time is dropped (``no_route``).
  The recipients whose best route leaves on a contact open now are grouped by that contact's node
  (the next hop), and ONE transmission carries them all, lasting the bundle's on-air bits over the
  slowest of those contacts. Recipients whose route waits for a later contact stay; a bundle with no
  recipient leaving now is parked until that contact (or any new outgoing contact) opens.
* :meth:`MulticastAgent.transmission_failed` (the medium's report for one next hop): that next
  hop's recipients come back, re-routed without that contact; :meth:`settle`: the served recipients
  leave this node (and its persistent store) for good.

Persistence: the store (store.py) keeps one row per bundle with exactly the recipients this node is
responsible for (queued or in flight, until settled), rewritten whenever that set changes; after a
kill the node reloads them and routes them again. A recipient is settled only once delivered or
dropped with a reason, as in the unicast agent.

Why one module: the agent's steps (originate, receive, decide and send, settle, fail, expire, resume)
all act on one set of per-bundle recipient sets and one radio queue; routing is cgr.py's, the codec
bpv7.py's and routing_blocks.py's, the store store.py's, as for the unicast agent.

Accounting is per (bundle, recipient) pair: a BundleEvent names the recipient (``dest``), its
priority and deadline; conservation is pairs created = delivered + dropped (by reason) + held.

How we know it is right: drawn plans stepped by hand (tests/unit/test_multicast.py: one transmission
for three recipients behind two next hops in view, two when they are not, per-recipient deadlines, a
receiver that is not a next hop discards, duplicates), random plans against an independent brute
force of each recipient's earliest arrival (multicast never later than unicast on an empty network,
conservation), the DTN-alone runs with both forwarding modes (tests/unit/test_dtn_alone.py) and a
kill -9 with a partially served bundle (tests/faults/test_restart_unit.py).
"""

from __future__ import annotations

import bisect
import heapq
import itertools
import math
from collections import Counter
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from orbit_clock.contact_plan import ContactPlan, node_name, node_number

from .agent import AgentConfig, BundleAgent, BundleEvent, Transmission, buffered_routes, ttl_s_for_priority
from .bpsec import IntegrityError, add_bib
from .bpv7 import Bundle, BundleError, decode_bundle, encode_bundle, ipn, remember_sent
from .cgr import ContactGraph
from .rx_policy import admit
from .routing_blocks import (IMC_BLOCK, NEXT_HOPS_BLOCK, OBSERVATION_GROUP, RECIPIENTS_BLOCK, next_hops_of,
                             overhead_bits_of, peek_next_hops, recipients_of, set_routing)
from .store import BundleStore, StoredBundle

__all__ = ["MulticastAgent", "new_agent"]

_NS = 1_000_000_000
_NEVER = 1 << 62
# bytes of recently received copies -> (the key they were verified with, or None unverified; the
# decoded bundle; its recipients by node; its next-hops split): one transmission reaches every next
# hop in view, and what receive() reads of a copy is a pure function of its bytes and the key, so
# the agents of one process decode, verify and parse each transmission once. receive() never alters
# the decoded bundle (it copies it before keeping it), nor does the port (DtnPort.receive).
_VERIFIED: dict[bytes, tuple] = {}
_VERIFIED_MAX = 1024


@dataclass
class _Rcpt:
    """One recipient this node is responsible for."""

    num: int
    name: str
    priority: int
    life_ms: int
    deadline_ns: int
    from_node: str | None = None  # the node it came from (not routed back there)


@dataclass
class _MHeld:
    bundle: Bundle
    bid: str
    created_ns: int
    queued: dict = field(default_factory=dict)  # recipient number -> _Rcpt, waiting to be sent from here
    flying: dict = field(default_factory=dict)  # start_ns -> {next hop name: [_Rcpt]} sent, not settled
    tx_contact: dict = field(default_factory=dict)  # start_ns -> {next hop name: contact}
    excluded: set = field(default_factory=set)  # contacts that failed
    ver: int = 0
    ready_ns: int = 0
    parked: dict = field(default_factory=dict)  # contact -> (priority, bits) counted as backlog there
    is_parked: bool = False
    received_ns: int = 0

    def rank_key(self, delays) -> tuple:
        if delays is None:
            return (min(r.priority for r in self.queued.values()), self.created_ns)
        return min((self.created_ns + int(delays[r.priority - 1] * _NS), r.priority) for r in self.queued.values())


class MulticastAgent:
    """The bundle agent of node ``node`` in multicast forwarding (module docstring). Same interface
    as :class:`sat_node.dtn.agent.BundleAgent` for the port (sat_node/dtn/port.py)."""

    def __init__(self, node: str, plan: ContactPlan | ContactGraph, config: AgentConfig, *,
                 store: BundleStore | None = None, on_event: Callable[[BundleEvent], None] | None = None,
                 keep_events: bool = True):
        self.node = node
        self.number = node_number(node)
        if not isinstance(config, AgentConfig):
            raise TypeError(f"agent {node}: config must be an AgentConfig (it carries the BPSec key), got "
                            f"{type(config).__name__}")
        self.config = config
        self.graph = plan if isinstance(plan, ContactGraph) else ContactGraph(plan, self.config.hop_limit)
        if not self.config.bundle_bits:
            raise ValueError(f"{node}: multicast forwarding needs a nominal bundle size (AgentConfig.bundle_bits)")
        self.store = store
        self.on_event = on_event
        self.events: list[BundleEvent] | None = [] if keep_events else None
        self.counters: Counter = Counter()
        self.last_error = ""
        self.rx_counts: Counter[str] = Counter()  # rx.* of sat_node/dtn/rx_policy.py
        self.last_received: Bundle | None = None
        self._held: dict[str, _MHeld] = {}
        self._ready: list = []  # (rank, order, bid, ver): candidates for the next radio decision
        self._ready_at: list = []  # (ready_ns, order, bid, ver): the same entries by the time they are ready
        self._wake: list = []  # (ready_ns, order, bid, ver): bundles parked until then
        self._order = itertools.count()
        self._delivered: set[str] = set()
        self._sent: list = []  # (Transmission) in send order, not settled
        self._parked_bits: dict[int, list] = {}  # contact -> bits waiting for it, by priority
        self._expiry: list = []  # (deadline_ns, bid, recipient number)
        self._out_starts = self.graph.out_starts_l.get(node, [])
        n_contacts = len(self.graph.contacts)
        self._backlog_buf = np.zeros(n_contacts, dtype=np.float64)  # all 0 between queries (_route)
        self._excluded_buf = np.zeros(n_contacts, dtype=np.bool_)  # all False between queries
        self.cgr_queries = 0  # route searches run: a measure of the routing work
        self.radio_free_ns = 0
        sd = self.config.settle_delay_s
        self._settle_ns = None if sd is None else int(round(sd * 1e9))
        self._seq = 0 if store is None else store.get_meta("seq")
        if store is not None:
            self._resume()

    # ---------------------------------------------------------------- helpers
    def _emit(self, t_ns, kind, bid, r: _Rcpt | None = None, reason="", created_ns=0, *, priority=0, dest=""):
        if r is not None:
            priority, dest, deadline = r.priority, r.name, r.deadline_ns
        else:
            deadline = 0
        ev = BundleEvent(t_ns, kind, self.node, bid, priority, dest, created_ns, reason, deadline)
        self.counters[kind if kind not in ("dropped", "discarded") else f"{kind}.{reason}"] += 1
        if self.events is not None:
            self.events.append(ev)
        if self.on_event is not None:
            self.on_event(ev)

    def _created_ns(self, b: Bundle) -> int:
        return (b.creation_ms - self.config.epoch_dtn_ms) * 1_000_000

    def held_count(self) -> int:
        """(bundle, recipient) pairs this node is responsible for (queued or in flight)."""
        return sum(len(h.queued) + sum(len(rs) for split in h.flying.values() for rs in split.values())
                   for h in self._held.values())

    def held_pairs(self) -> set[tuple[str, str]]:
        """(bundle id, recipient) of every recipient this node is responsible for."""
        return {(h.bid, r.name) for h in self._held.values() for r in self._all_rcpts(h)}

    def bundle_bytes(self, bundle_id: str) -> bytes | None:
        """Encoded bytes of a bundle this node holds, with the recipients it is responsible for."""
        h = self._held.get(bundle_id)
        return None if h is None else self._encode_held(h)

    def _all_rcpts(self, h: _MHeld) -> list[_Rcpt]:
        out = list(h.queued.values())
        for split in h.flying.values():
            for rs in split.values():
                out += rs
        return out

    def _encode_held(self, h: _MHeld) -> bytes:
        set_routing(h.bundle, [(r.num, r.priority, r.life_ms) for r in self._all_rcpts(h)], None)
        return encode_bundle(h.bundle)

    def _persist(self, h: _MHeld) -> None:
        """Store row of ``h``: the recipients this node is responsible for (deleted when none is left)."""
        if self.store is None:
            return
        rs = self._all_rcpts(h)
        if not rs:
            self.store.delete(h.bid)
            return
        self.store.put(StoredBundle(h.bid, self._encode_held(h), min(r.priority for r in rs), str(OBSERVATION_GROUP),
                                    max(r.deadline_ns for r in rs), h.received_ns))

    def _forget_if_done(self, h: _MHeld) -> None:
        if not h.queued and not h.flying:
            self._unpark(h)
            self._held.pop(h.bid, None)
        self._persist(h)

    # ---------------------------------------------------------------- entry points
    def originate(self, payload: bytes, dest: str, priority: int, now_ns: int) -> str:
        return self.originate_many(payload, [(dest, priority)], now_ns)

    def originate_many(self, payload: bytes, dests, now_ns: int) -> str:
        """The bundle of one observation for every ``(node name, priority 1..15)`` of ``dests``."""
        rcpts = {}
        for dest, prio in dests:
            if not 1 <= int(prio) <= 15:
                raise ValueError(f"bundle priority {prio}: must be 1..15")
            if dest == self.node:
                raise ValueError(f"bundle from {self.node} to itself")
            num = node_number(dest)
            if num in rcpts:
                raise ValueError(f"recipient {dest} twice")
            life_ms = int(round(ttl_s_for_priority(int(prio), self.config.ttl_s_by_priority) * 1000))
            rcpts[num] = (dest, int(prio), life_ms)
        if not rcpts:
            raise ValueError("a bundle needs at least one recipient")
        b = Bundle(dest=OBSERVATION_GROUP, src=ipn(self.number, 1),
                   creation_ms=self.config.epoch_dtn_ms + now_ns // 1_000_000, seq=self._seq,
                   lifetime_ms=max(v[2] for v in rcpts.values()), payload=bytes(payload))
        self._seq += 1
        if self.store is not None:
            self.store.set_meta("seq", self._seq)
        b.hop_count = (self.config.hop_limit, 0)
        add_bib(b, self.config.key, ipn(self.number, 0))
        created = self._created_ns(b)
        h = _MHeld(b, b.bundle_id, created, received_ns=now_ns)
        for num, (name, prio, life) in sorted(rcpts.items()):
            r = _Rcpt(num, name, prio, life, created + life * 1_000_000)
            self._emit(now_ns, "created", h.bid, r, created_ns=created)
            h.queued[num] = r
        self._held[h.bid] = h
        for r in h.queued.values():
            heapq.heappush(self._expiry, (r.deadline_ns, h.bid, r.num))
        self._requeue(h, now_ns)
        self._persist(h)
        return h.bid

    def overheard(self, bundle_bytes: bytes, now_ns: int) -> bool:
        """True (counted in ``counters['discarded.not_next_hop']``, no event) when the copy names next
        hops and this node is not one of them; False otherwise (then call :meth:`receive`)."""
        if not isinstance(bundle_bytes, bytes):
            return False
        try:
            nhs = peek_next_hops(bundle_bytes)
        except BundleError:
            return False
        if not nhs or self.number in nhs:
            return False
        self._settle_by_time(now_ns)
        self.last_received = None
        self.counters["discarded.not_next_hop"] += 1
        return True

    def overheard_count(self, copies: int, now_ns: int) -> None:
        """``copies`` copies for other next hops, counted at once (the medium's CopiesOverheard): the
        effect of that many :meth:`overheard` calls that return True, the last at ``now_ns``."""
        self._settle_by_time(now_ns)
        self.last_received = None
        self.counters["discarded.not_next_hop"] += int(copies)

    def receive(self, bundle_bytes: bytes, from_node: str, now_ns: int) -> str:
        """A copy heard on the medium; returns what happened: delivered (this node was a recipient and
        got it now), queued, discarded.* or dropped.*."""
        self._settle_by_time(now_ns)
        self.last_received = None
        key = self.config.key if self.config.verify_integrity else None
        ck = (key, self.config.foreign, self.config.foreign_priority)  # what the check depended on
        hit = _VERIFIED.get(bundle_bytes) if type(bundle_bytes) is bytes else None
        if hit is not None and hit[0] == ck:  # the same bytes, checked the same way, by another node here
            _key, b, rs, split, rx = hit
            self.rx_counts.update(rx)  # what admit counted for these bytes, counted here too
            if split and self.number not in split:
                self._emit(now_ns, "discarded", "?", reason="not_next_hop")
                return "discarded.not_next_hop"
            self.last_received = b
        else:
            try:
                nhs = peek_next_hops(bundle_bytes)
                if nhs and self.number not in nhs:
                    self._emit(now_ns, "discarded", "?", reason="not_next_hop")
                    return "discarded.not_next_hop"
                b = decode_bundle(bundle_bytes)
                self.last_received = b
            except BundleError as exc:
                self._emit(now_ns, "dropped", "?", reason="integrity")
                self.last_error = str(exc)
                return "dropped.integrity"
            try:
                rx = Counter()
                try:
                    rcpts = admit(b, key, self.config.foreign, self.config.foreign_priority, rx)
                finally:
                    self.rx_counts.update(rx)
                rs = {r[0]: r for r in rcpts}
                split = next_hops_of(b, rcpts)
            except (IntegrityError, BundleError, ValueError) as exc:
                self.last_error = str(exc)
                self._emit(now_ns, "dropped", b.bundle_id, reason="integrity")
                return "dropped.integrity"
            if type(bundle_bytes) is bytes:
                if len(_VERIFIED) >= _VERIFIED_MAX:
                    _VERIFIED.clear()
                _VERIFIED[bundle_bytes] = (ck, b, rs, split, rx)
        mine = split.get(self.number, tuple(rs)) if split else tuple(rs)
        bid = b.bundle_id
        created = self._created_ns(b)
        h = self._held.get(bid)
        held_nums = set() if h is None else {r.num for r in self._all_rcpts(h)}
        prev = b.previous_node
        from_name = node_name(prev[0]) if prev is not None and prev[0] != self.number else None
        new: list[_Rcpt] = []
        delivered = False
        dup = 0
        limit, count = b.hop_count or (self.config.hop_limit, 0)
        for num in mine:
            _n, prio, life = rs[num]
            r = _Rcpt(num, node_name(num), prio, life, created + life * 1_000_000, from_name)
            if num == self.number:
                if bid in self._delivered:
                    dup += 1
                elif now_ns >= r.deadline_ns:
                    self._delivered.add(bid)  # (counted once: a later copy is a duplicate)
                    self._emit(now_ns, "dropped", bid, r, "ttl", created)
                else:
                    self._delivered.add(bid)
                    self._emit(now_ns, "delivered", bid, r, created_ns=created)
                    delivered = True
            elif num in held_nums:
                dup += 1
            elif now_ns >= r.deadline_ns:
                self._emit(now_ns, "dropped", bid, r, "ttl", created)
            elif count + 1 > limit:
                self._emit(now_ns, "dropped", bid, r, "hop_limit", created)
            else:
                new.append(r)
        if new:
            if h is None:
                b = b.copy()  # (last_received stays as received)
                b.blocks = [blk for blk in b.blocks if blk.type not in (IMC_BLOCK, RECIPIENTS_BLOCK, NEXT_HOPS_BLOCK)]
                b.hop_count = (limit, count + 1)
                h = self._held[bid] = _MHeld(b, bid, created, received_ns=now_ns)
            for r in new:
                h.queued[r.num] = r
                heapq.heappush(self._expiry, (r.deadline_ns, bid, r.num))
            self._requeue(h, now_ns)
            self._persist(h)
        if delivered:
            return "delivered"
        if new:
            return "queued"
        if not mine:
            self._emit(now_ns, "discarded", bid, reason="other", created_ns=created)
            return "discarded.other"
        if dup:
            self._emit(now_ns, "discarded", bid, reason="duplicate", created_ns=created,
                       priority=min(rs[n][1] for n in mine), dest=node_name(mine[0]))
            return "discarded.duplicate"
        return "dropped.ttl"

    # ---------------------------------------------------------------- queueing
    def _requeue(self, h: _MHeld, now_ns: int) -> None:
        """Make ``h`` a candidate at the next radio decision (from ``now_ns``)."""
        self._unpark(h)
        h.ver += 1
        if not h.queued:
            return
        h.ready_ns = now_ns
        order = next(self._order)
        heapq.heappush(self._ready, (h.rank_key(self.config.priority_delay_s), order, h.bid, h.ver))
        heapq.heappush(self._ready_at, (now_ns, order, h.bid, h.ver))

    def _park(self, h: _MHeld, until_ns: int, waits: dict) -> None:
        """Park ``h`` until ``until_ns``; ``waits``: contact -> (priority, bits) counted as backlog."""
        h.ver += 1
        h.ready_ns = until_ns
        h.parked = waits
        h.is_parked = True
        for c, (p, bits) in waits.items():
            byp = self._parked_bits.get(c)
            if byp is None:
                byp = self._parked_bits[c] = [0] * 16
            byp[p] += bits
        heapq.heappush(self._wake, (until_ns, next(self._order), h.bid, h.ver))

    def _unpark(self, h: _MHeld) -> None:
        h.is_parked = False
        for c, (p, bits) in h.parked.items():
            byp = self._parked_bits[c]
            byp[p] -= bits
            if not any(byp):
                del self._parked_bits[c]
        h.parked = {}

    def _routes(self, h: _MHeld, rs: list, s: int, bits: int) -> list:
        """The CGR routes of recipients ``rs`` at ``s`` (in that order; None: no route in time), one
        search per set of recipients whose query differs only in destination and deadline: the same
        node they came from (not routed back there) and the same first-hop backlog (the bits parked
        at their priority or higher; every priority shares it when nothing is parked)."""
        parked = self._parked_bits
        sig_of: dict[int, tuple] = {}
        groups: dict[tuple, list[int]] = {}
        for i, r in enumerate(rs):
            sig = sig_of.get(r.priority)
            if sig is None:
                sig = sig_of[r.priority] = tuple(sum(byp[: r.priority + 1]) for byp in parked.values())
            groups.setdefault((sig, r.from_node), []).append(i)
        out: list = [None] * len(rs)
        n0 = self.graph.searches
        for ii in groups.values():
            r0 = rs[ii[0]]
            found = buffered_routes(self.graph, self.node, [(rs[i].name, rs[i].deadline_ns / _NS) for i in ii],
                                    s / _NS, bits, parked, r0.priority, h.excluded, r0.from_node,
                                    self.config.hop_tolerance_s, self._backlog_buf, self._excluded_buf)
            for i, route in zip(ii, found):
                out[i] = route
        self.cgr_queries += self.graph.searches - n0
        return out

    def _next_decision_ns(self) -> int | None:
        while self._wake and self._stale(self._wake[0]):
            heapq.heappop(self._wake)
        while self._ready_at and self._stale(self._ready_at[0]):
            heapq.heappop(self._ready_at)
        cands = []
        if self._ready_at:
            cands.append(self._ready_at[0][0])
        if self._wake:
            cands.append(self._wake[0][0])
        if not cands:
            return None
        return max(min(cands), self.radio_free_ns)

    def _stale(self, entry) -> bool:
        h = self._held.get(entry[2])
        return h is None or h.ver != entry[3] or not h.queued

    def _decide(self, s: int) -> Transmission | None:
        """At ``s`` (radio free): the most urgent bundle with a recipient whose best route leaves now
        goes, in one transmission to every next hop leaving now (module docstring)."""
        while self._wake and self._wake[0][0] <= s:
            e = heapq.heappop(self._wake)
            if not self._stale(e):
                self._requeue(self._held[e[2]], s)
        later = []  # candidates not ready yet at s (requeued after it)
        tx = None
        while self._ready:
            e = heapq.heappop(self._ready)
            if self._stale(e):
                continue
            h = self._held[e[2]]
            if h.ready_ns > s:
                later.append(e)
                continue
            tx = self._try_send(h, s)
            if tx is not None:
                break
        for e in later:
            heapq.heappush(self._ready, e)
        return tx

    def _try_send(self, h: _MHeld, s: int) -> Transmission | None:
        bits = self.config.bundle_bits + self._overhead_estimate(h)
        groups: dict[str, list] = {}  # next hop -> [first contact, recipients]
        waits: dict[int, tuple[int, int]] = {}
        wait_until = _NEVER
        dropped = False
        rs = sorted(h.queued.values(), key=lambda x: (x.priority, x.num))
        routes = iter(self._routes(h, [r for r in rs if s < r.deadline_ns], s, bits))
        for r in rs:
            if s >= r.deadline_ns:
                del h.queued[r.num]
                self._emit(s, "dropped", h.bid, r, "ttl", h.created_ns)
                dropped = True
                continue
            route = next(routes)
            if route is None:  # cannot arrive before its deadline any more: drop it now
                del h.queued[r.num]
                self._emit(s, "dropped", h.bid, r, "no_route", h.created_ns)
                dropped = True
                continue
            c = route.contacts[0]
            start_ns = math.ceil(self.graph.start_l[c] * _NS)
            if start_ns > s:
                wait_until = min(wait_until, start_ns)
                p, bb = waits.get(c, (r.priority, 0))
                waits[c] = (min(p, r.priority), bits)
                continue
            g = groups.setdefault(route.next_hop, [c, []])
            g[1].append(r)
        if dropped:
            self._forget_if_done(h)
        if not groups:
            if h.queued:
                starts = self._out_starts
                k = bisect.bisect_right(starts, s / _NS)
                nxt = math.ceil(starts[k] * _NS) if k < len(starts) else wait_until
                self._park(h, max(s + 1, min(wait_until, nxt)), waits)
            else:
                h.ver += 1
            return None
        return self._send(h, groups, s)

    def _overhead_estimate(self, h: _MHeld) -> int:
        """On-air overhead bits if every queued recipient went in one transmission (an upper bound of
        any transmission of them: fewer recipients never encode longer)."""
        rs = list(h.queued.values())
        return overhead_bits_of([(r.num, r.priority, r.life_ms) for r in rs], {self.number: tuple(r.num for r in rs)})

    def _send(self, h: _MHeld, groups: dict, s: int) -> Transmission | None:
        b = h.bundle
        b.previous_node = ipn(self.number, 0)
        served = [r for _c, rs in groups.values() for r in rs]
        split = {node_number(nh): tuple(r.num for r in rs) for nh, (_c, rs) in groups.items()}
        rcpts = [(r.num, r.priority, r.life_ms) for r in served]
        set_routing(b, rcpts, split)
        data = encode_bundle(b)
        bits = self.config.bundle_bits + overhead_bits_of(rcpts, split)  # = overhead_bits(data), not parsed
        rate = min(self.graph.rate_l[c] for c, _rs in groups.values())
        end = s + math.ceil(bits / rate * _NS)
        late = [c for c, _rs in groups.values() if end > self.graph.end_l[c] * _NS]
        if late:  # rounding: a contact closes first - route again without it
            h.excluded.update(late)
            self._requeue(h, s)
            return None
        for r in served:
            del h.queued[r.num]
        remember_sent(data, b)  # the next hops in this process decode the copy without parsing it
        h.flying[s] = {nh: rs for nh, (_c, rs) in groups.items()}
        h.tx_contact[s] = {nh: c for nh, (c, _rs) in groups.items()}
        nhs = tuple(sorted(groups, key=node_number))
        first = min(served, key=lambda r: (r.priority, r.num))
        tx = Transmission(data, nhs[0], s, end, bits, self.node, h.bid, groups[nhs[0]][0], nhs)
        self._sent.append(tx)
        self.radio_free_ns = end
        self.counters["air_ns"] += end - s
        self.counters["bits_on_air"] += bits
        self._emit(s, "forwarded", h.bid, None, created_ns=h.created_ns, priority=first.priority, dest=first.name)
        self._requeue(h, s)
        return tx

    def transmissions_until(self, t_ns: int) -> list[Transmission]:
        """Transmissions this radio starts at or before ``t_ns`` (in order)."""
        out: list[Transmission] = []
        self._settle_by_time(t_ns)
        while True:
            s = self._next_decision_ns()
            if s is None or s > t_ns:
                break
            tx = self._decide(s)
            if tx is not None:
                out.append(tx)
        return out

    # ---------------------------------------------------------------- after the transmission
    def _settle_by_time(self, now_ns: int) -> None:
        if self._settle_ns is None:
            return
        while self._sent and self._sent[0].end_ns + self._settle_ns <= now_ns:
            self.settle(self._sent[0])

    def settle(self, tx: Transmission) -> bool:
        """``tx`` got through to the next hops that did not fail: their recipients leave this node."""
        h = self._held.get(tx.bundle_id)
        if tx in self._sent:
            self._sent.remove(tx)
        if h is None or tx.start_ns not in h.flying:
            return False
        del h.flying[tx.start_ns]
        h.tx_contact.pop(tx.start_ns, None)
        self._forget_if_done(h)
        return True

    def in_flight(self, bundle_id: str, start_ns: int | None = None) -> Transmission | None:
        for tx in self._sent:
            if tx.bundle_id == bundle_id and (start_ns is None or tx.start_ns == start_ns):
                return tx
        return None

    def transmission_failed(self, tx: Transmission, now_ns: int, next_hop: str | None = None) -> None:
        """The medium says ``tx`` did not reach ``next_hop`` (None: any of them): its recipients come
        back to this node and are routed again without that contact."""
        h = self._held.get(tx.bundle_id)
        if h is None or tx.start_ns not in h.flying:
            return
        split = h.flying[tx.start_ns]
        hops = list(split) if next_hop is None else [next_hop]
        back = []
        for nh in hops:
            rs = split.pop(nh, None)
            if rs is None:
                continue
            self.counters["tx_failed"] += 1
            h.excluded.add(h.tx_contact[tx.start_ns][nh])
            back += rs
        if not split:
            del h.flying[tx.start_ns]
            h.tx_contact.pop(tx.start_ns, None)
            if tx in self._sent:
                self._sent.remove(tx)
        for r in back:
            if now_ns >= r.deadline_ns:
                self._emit(now_ns, "dropped", h.bid, r, "ttl", h.created_ns)
            else:
                h.queued[r.num] = r
                heapq.heappush(self._expiry, (r.deadline_ns, h.bid, r.num))
        if h.queued:
            self._requeue(h, now_ns)
        self._forget_if_done(h)

    def expire(self, now_ns: int) -> int:
        """Drop queued recipients whose deadline has passed; returns how many."""
        n = 0
        while self._expiry and self._expiry[0][0] <= now_ns:
            dl, bid, num = heapq.heappop(self._expiry)
            h = self._held.get(bid)
            if h is None:
                continue
            r = h.queued.get(num)
            if r is None or r.deadline_ns != dl:
                continue
            del h.queued[num]
            self._emit(dl, "dropped", bid, r, "ttl", h.created_ns)
            n += 1
            if h.queued and not h.is_parked:  # its most urgent recipient may have changed
                self._requeue(h, h.ready_ns)
            self._forget_if_done(h)
        return n

    def next_event_ns(self) -> int | None:
        """Earliest time this agent needs to act: a radio decision or a recipient's deadline."""
        cands = []
        nxt = self._next_decision_ns()
        if nxt is not None:
            cands.append(nxt)
        while self._expiry and (self._expiry[0][1] not in self._held
                                or self._expiry[0][2] not in self._held[self._expiry[0][1]].queued):
            heapq.heappop(self._expiry)
        if self._expiry:
            cands.append(self._expiry[0][0])
        if self._sent and self.store is not None and self._settle_ns is not None:
            cands.append(self._sent[0].end_ns)
        return min(cands) if cands else None

    # ---------------------------------------------------------------- persistence
    def _resume(self) -> None:
        """Reload every stored bundle (the recipients this node was responsible for) and route them again."""
        for sb in self.store.load_all():
            try:
                b = decode_bundle(sb.data)
                rs = recipients_of(b)
            except BundleError:
                self.store.delete(sb.bundle_id)
                continue
            created = self._created_ns(b)
            h = _MHeld(b, sb.bundle_id, created, received_ns=sb.received_ns)
            prev = b.previous_node
            from_name = node_name(prev[0]) if prev is not None and prev[0] != self.number else None
            for num, prio, life in rs:
                h.queued[num] = _Rcpt(num, node_name(num), prio, life, created + life * 1_000_000, from_name)
                heapq.heappush(self._expiry, (created + life * 1_000_000, h.bid, num))
            self._held[h.bid] = h
            self._requeue(h, sb.received_ns)


def new_agent(node: str, plan: ContactPlan | ContactGraph, config: AgentConfig, **kw):
    """The bundle agent of ``config.forwarding``: :class:`MulticastAgent` or the unicast
    :class:`sat_node.dtn.agent.BundleAgent` (one bundle per recipient, the study simulator's model)."""
    if config.forwarding == "multicast":
        return MulticastAgent(node, plan, config, **kw)
    return BundleAgent(node, plan, config, **kw)
