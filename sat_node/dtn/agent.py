"""The bundle agent of one node: accepts, stores, routes, queues and transmits BPv7 bundles.

RFC 9171 section 5 (bundle processing) with contact graph routing (cgr.py, CCSDS 734.3-B-1) for the
forwarding decision, driven in explicit time steps (no clock, no threads, no global state), so N
agents live in one process:

* :meth:`BundleAgent.originate` - a new bundle from this node (creation, TTL by priority, BIB);
* :meth:`BundleAgent.receive` - bytes from the medium: copies whose next-hop block names another
  node are discarded and counted (broadcast medium), malformed or failing the BIB are dropped
  (``integrity``), duplicates discarded and counted, expired dropped (``ttl``), ours delivered,
  others routed and queued;
* :meth:`BundleAgent.overheard` - the cheap first look at a heard copy: one whose next-hop block
  names another node is counted (``counters['discarded.not_next_hop']``) with no event record and
  True is returned; anything else goes to :meth:`receive` (the satellite does this for the ~200k
  copies of a paper run); :meth:`BundleAgent.overheard_count` counts many such copies at once (the
  medium's count of them, sat_node/dtn/overhearing.py);
* :meth:`BundleAgent.transmissions_until` - what the one radio sends up to ``t_ns``. The next hop is
  chosen at transmission time, not at enqueue time: whenever the radio is free, held bundles are
  taken in send order (priority 1 first, then creation time; or, with ``priority_delay_s``, the
  earliest virtual deadline creation + delay(priority); :func:`deadline_delays` makes that the
  earliest expiry), each routed by CGR from that instant; the
  first whose best route leaves on a contact open now is sent. Bundles that route alike (same
  destination, excluded previous node and excluded contacts) form a group; a group whose best route
  waits for a contact not open yet is parked until that contact - or any other outgoing contact of
  this node - opens, and its bits count as backlog on that contact for later routing decisions
  (SABR's queued backlog, per first-hop contact). A bundle that can no longer arrive before its
  lifetime ends is dropped at once (``no_route``) rather than carried to its TTL; expired ones
  are dropped (``ttl``);
* :meth:`BundleAgent.transmission_failed` - the medium reports a failure: the bundle goes back and
  is re-routed without that contact; :meth:`BundleAgent.settle` - no report can come any more, the
  bundle is gone; :meth:`expire`, :meth:`next_event_ns`, ``counters``, ``events``.

Priority and lifetime travel in the bundle's recipients block (one recipient: the destination),
the intended next hop in its next-hops block (sat_node/dtn/routing_blocks.py: private block types
200 and 201, off ION's codes); TTL comes from priority (the study: P1 900 s, P2-3 1800 s, P4-15
3000 s). The forwarding node writes its own EID in the previous-node block and increments the
hop count (limit 32). ``hop_tolerance_s`` (default 0) lets CGR prefer fewer hops among routes
arriving within that tolerance of the earliest (what it does on the study's inputs: README, "The
DTN alone on the study's own inputs").

Why one module: RFC 9171 section 5's processing steps (receive, forward, transmit, expire, the
failure path) all act on one bundle store and one set of queues; the routing decision itself is in
cgr.py, the codec in bpv7.py, the store in store.py.

Conservation (tested): created = delivered + dropped (by reason) + held (queued or in flight).

Bundles are 'forwarded' when their transmission starts; the sender forgets them (and deletes them
from the persistent store) only when the transmission has ended without a failure report (BPv7
without custody transfer), so a process killed mid-transmission still has the bundle: by time
(``settle_delay_s`` after the end), or, with ``settle_delay_s=None``, when the holder says so
(:meth:`BundleAgent.settle`: the lockstep port knows from the engine contract when no report can
still come).

How we know it is right: hand-stepped agents on drawn plans (tests/unit/test_agent.py: delivery
times, priority order, parking until a contact opens, TTL, integrity, failures), the
DTN-alone runs' hand-worked latencies and conservation (tests/unit/test_dtn_alone.py), SIGKILL mid-air
(tests/unit/test_store.py), and the study's whole runs against the per-bundle lower bound.
"""

from __future__ import annotations

import bisect
import heapq
import itertools
import math
from collections import Counter
from dataclasses import dataclass, field, replace
from operator import attrgetter
from typing import Callable, NamedTuple

import numpy as np

from orbit_clock.contact_plan import ContactPlan, node_name, node_number

from .bpsec import IntegrityError, add_bib
from .rx_policy import FOREIGN_POLICIES, admit
from .bpv7 import (
    BIB_BLOCK,
    PAPER_EPOCH_DTN_MS,
    Bundle,
    BundleError,
    decode_bundle,
    encode_bundle,
    ipn,
    remember_sent,
)
from .cgr import ContactGraph
from .routing_blocks import RECIPIENTS_BLOCK, peek_next_hops, remember_unicast_peek, set_routing
from .store import BundleStore, StoredBundle

__all__ = ["BundleAgent", "AgentConfig", "Transmission", "BundleEvent", "ttl_s_for_priority",
           "MIN_KEY_BYTES", "DROP_REASONS", "SEND_ORDERS", "FORWARDINGS", "deadline_delays", "peek_next_hop"]

DROP_REASONS = ("ttl", "integrity", "no_route", "hop_limit", "other")
# Send orders (AgentConfig.for_policy): strict priority (the study's), earliest expiry first, or
# oldest first ("fifo": priority ignored, the no-priority case beside the study's Fig. 5)
SEND_ORDERS = ("priority", "deadline", "fifo")
FORWARDINGS = ("multicast", "unicast")
_NS = 1_000_000_000
# next hops of recently heard bytes: a broadcast copy reaches every node in view, and the peek is a
# pure function of the (immutable) bytes, so each transmission is parsed once per process.
_PEEK_CACHE: dict[bytes, tuple] = {}
_NEVER = 1 << 62
_MISSING = object()
_READY_NS = attrgetter("ready_ns")


def deadline_delays(ttl_s_by_priority: dict[int, float]) -> tuple[float, ...]:
    """``AgentConfig.priority_delay_s`` for earliest-expiry-first sending (each priority's TTL)."""
    return tuple(ttl_s_for_priority(p, ttl_s_by_priority) for p in range(1, 16))


def peek_next_hop(data: bytes) -> int | None:
    """The one next hop a unicast copy names (None: none; a copy naming several is not unicast and
    raises BundleError)."""
    nhs = peek_next_hops(data)
    if len(nhs) > 1:
        raise BundleError(f"a unicast copy names {len(nhs)} next hops")
    return nhs[0] if nhs else None


# Shortest BIB key accepted (128 bits).
MIN_KEY_BYTES = 16


def ttl_s_for_priority(priority: int, ttl_s_by_priority: dict[int, float]) -> float:
    for p in sorted(ttl_s_by_priority):
        if priority <= p:
            return ttl_s_by_priority[p]
    return ttl_s_by_priority[max(ttl_s_by_priority)]


@dataclass(frozen=True)
class AgentConfig:
    """key: the constellation's BIB key (BIB-HMAC-SHA2, at least 16 bytes; required: it comes from
    the deployment, never from the code); ttl_s_by_priority: {max priority: TTL [s]} (the study's:
    P1 900 s, P2-3 1800 s, P4-15 3000 s); bundle_bits: the size used for link timing (None: the
    encoded size); epoch_dtn_ms: the scenario epoch in DTN time [ms]; hop_limit: hop-count block."""

    key: bytes
    ttl_s_by_priority: dict = field(default_factory=lambda: {1: 900.0, 3: 1800.0, 15: 3000.0})
    bundle_bits: int | None = 2000
    epoch_dtn_ms: int = PAPER_EPOCH_DTN_MS
    hop_limit: int = 32
    verify_integrity: bool = True
    hop_tolerance_s: float = 0.0
    # How long after a transmission's end the agent still expects a failure report from the medium
    # before it forgets the bundle [s]; None: never by time - whoever feeds the agent the medium's
    # reports settles each transmission when no report can come any more (BundleAgent.settle; the
    # lockstep port does, sat_node/dtn/port.py).
    settle_delay_s: float | None = 0.0
    priority_delay_s: tuple | None = None
    # "unicast": one bundle per recipient (this module's BundleAgent, the study simulator's model);
    # "multicast": one bundle per observation to its recipient list (sat_node/dtn/multicast.py)
    forwarding: str = "unicast"
    # bundles without the constellation's BIB and recipients block (sat_node/dtn/rx_policy.py):
    # "refuse" (dropped as integrity) or "accept" (ordinary unicast bundles at foreign_priority)
    foreign: str = "refuse"
    foreign_priority: int = 15

    def __post_init__(self) -> None:
        if self.foreign not in FOREIGN_POLICIES:
            raise ValueError(f"foreign {self.foreign!r}: one of {', '.join(FOREIGN_POLICIES)}")
        if not 1 <= self.foreign_priority <= 15:
            raise ValueError(f"foreign priority {self.foreign_priority}: 1..15")
        if not isinstance(self.key, bytes) or len(self.key) < MIN_KEY_BYTES:
            n = len(self.key) if isinstance(self.key, bytes) else type(self.key).__name__
            raise ValueError(f"BPSec key: bytes of length >= {MIN_KEY_BYTES} needed, got {n}")

    @classmethod
    def for_policy(cls, send_order: str = "priority", hop_tolerance_s: float = 0.0, **kw) -> "AgentConfig":
        """A config for one of :data:`SEND_ORDERS` (``deadline``: each priority's delay is its TTL,
        so the earliest expiry goes first; ``fifo``: every delay 0, so the oldest bundle goes first
        whatever its priority, which orders only bundles created at the same instant) and a CGR hop tolerance [s]; other fields from ``kw``
        (``forwarding``: one of :data:`FORWARDINGS`)."""
        if send_order not in SEND_ORDERS:
            raise ValueError(f"send order {send_order!r}: one of {', '.join(SEND_ORDERS)}")
        if kw.get("forwarding", "unicast") not in FORWARDINGS:
            raise ValueError(f"forwarding {kw['forwarding']!r}: one of {', '.join(FORWARDINGS)}")
        if not hop_tolerance_s >= 0.0:
            raise ValueError(f"hop tolerance {hop_tolerance_s!r} s: must be >= 0")
        cfg = cls(hop_tolerance_s=float(hop_tolerance_s), **kw)
        if send_order == "deadline":
            cfg = replace(cfg, priority_delay_s=deadline_delays(cfg.ttl_s_by_priority))
        elif send_order == "fifo":  # every priority's delay 0: creation time alone orders the bundles
            cfg = replace(cfg, priority_delay_s=(0.0,) * 15)
        return cfg


class Transmission(NamedTuple):
    """One radio transmission: encoded bundle (its next-hop block set), intended next hop,
    [start_ns, end_ns] of the sender's radio, the bits it takes, the contact index (in the agent's plan)."""

    bundle_bytes: bytes
    next_hop: str
    start_ns: int
    end_ns: int
    bits: int
    sender: str
    bundle_id: str
    contact: int
    next_hops: tuple = ()  # every next hop a multicast transmission serves (next_hop is the first)


class BundleEvent(NamedTuple):
    """For the report: kind in created|forwarded|delivered|dropped|discarded; reason for dropped /
    discarded; created_ns of the bundle, priority, destination."""

    t_ns: int
    kind: str
    node: str
    bundle_id: str
    priority: int
    dest: str
    created_ns: int
    reason: str = ""
    deadline_ns: int = 0  # the (bundle, recipient) pair's deadline (created: creation + its TTL); 0 unknown


@dataclass(slots=True)
class _Held:
    bundle: Bundle
    priority: int
    dest: str
    expiry_ns: int
    created_ns: int
    ready_ns: int
    contact: int = -1
    excluded: set = field(default_factory=set)
    excluded_node: str | None = None  # the node it came from (no ping-pong)
    bits: int = 0
    group: object = None
    route_memo: tuple | None = None  # (t_ns, parked version, len(excluded), Route | None)
    bid: str = ""  # the bundle's id (bundle.bundle_id: its source, creation time and sequence never change here)


class _Group:
    """Bundles that route alike (same destination, excluded node and excluded contacts), in
    (priority, creation, arrival order). A group whose best route waits for a contact that is not
    open yet is parked until that contact (or any new outgoing contact) opens."""

    __slots__ = ("key", "heap", "n", "ready_ns", "parked_c", "parked_bits")

    def __init__(self, key):
        self.key = key
        self.heap: list = []
        self.n = 0
        self.ready_ns = 0
        self.parked_c = -1
        self.parked_bits: Counter = Counter()  # priority -> bits counted on the parked contact


def buffered_route(graph, node: str, dest: str, t_s: float, bits: int, deadline_s: float,
                   parked: dict, priority: int, excluded_contacts, excluded_node, hop_tolerance_s: float,
                   backlog_buf: np.ndarray, excluded_buf: np.ndarray):
    """:func:`buffered_routes` to one destination."""
    return buffered_routes(graph, node, [(dest, deadline_s)], t_s, bits, parked, priority, excluded_contacts,
                           excluded_node, hop_tolerance_s, backlog_buf, excluded_buf)[0]


def buffered_routes(graph, node: str, dests, t_s: float, bits: int, parked: dict, priority: int,
                    excluded_contacts, excluded_node, hop_tolerance_s: float, backlog_buf: np.ndarray,
                    excluded_buf: np.ndarray) -> list:
    """CGR routes to ``dests`` [(node, deadline [s])] from one search (ContactGraph.routes), with the
    per-contact inputs in the agent's reusable buffers: the bits parked on each contact at this
    priority or higher (SABR's first-hop backlog) and the excluded contacts are set for this query
    and cleared after it (a fresh array per query would cost O(contacts) each: the graph is the
    constellation's, shared by the process). Both agents route through it."""
    fb = None
    fb_set = []
    if parked:
        fb = backlog_buf
        for c, byp in parked.items():
            x = sum(byp[: priority + 1])
            if x > 0:
                fb[c] = x
                fb_set.append(c)
    excluded = None
    if excluded_contacts:
        excluded = excluded_buf
        excluded[list(excluded_contacts)] = True
    try:
        return graph.routes(node, dests, t_s, bits, excluded=excluded,
                            excluded_nodes=(excluded_node,) if excluded_node else (),
                            first_backlog_bits=fb, hop_tolerance_s=hop_tolerance_s)
    finally:
        if fb_set:
            fb[fb_set] = 0.0
        if excluded is not None:
            excluded[list(excluded_contacts)] = False


class BundleAgent:
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
        self.store = store
        self.on_event = on_event
        self.events: list[BundleEvent] = [] if keep_events else None
        self.counters: Counter = Counter()
        self.last_error = ""
        self.rx_counts: Counter[str] = Counter()  # rx.* of sat_node/dtn/rx_policy.py
        self._held: dict[str, _Held] = {}
        self._groups: dict[tuple, _Group] = {}
        self._order = itertools.count()
        self._seen: set[str] = set()
        self._in_flight: dict[str, tuple[Transmission, _Held]] = {}
        self._parked: dict[int, list] = {}  # contact -> bits waiting for it, by priority (index 0..15)
        self._version = 0  # bumped whenever _parked changes (route memo key)
        self._route_memo: tuple = (-1, -1, {})  # (t_ns, version, {routing key: (Route | None, deadline_s)})
        self._expiry_heap: list = []
        self._out_starts = self.graph.out_starts_l.get(node, [])
        n_contacts = len(self.graph.contacts)
        self._backlog_buf = np.zeros(n_contacts, dtype=np.float64)  # all 0 between queries (_route)
        self._excluded_buf = np.zeros(n_contacts, dtype=np.bool_)  # all False between queries
        self.radio_free_ns = 0
        # (the radio's next decision time,) as transmissions_until left it; None once anything that
        # moves it may have happened (a group queued, left or forgotten): next_event_ns then computes it
        self._decision_after: tuple | None = None
        sd = self.config.settle_delay_s
        self._settle_ns = None if sd is None else int(round(sd * 1e9))
        self._settle_at = _NEVER  # when the oldest transmission in flight is settled (O(1) check per copy heard)
        self.last_received: Bundle | None = None  # what the last receive() decoded (None: nothing)
        self.cgr_queries = 0  # route searches run (memo hits aside): a measure of the routing work
        # nodes outside the constellation that this agent's graph names (``ipn_<N>``: the ground
        # segment, a gateway's peer): their numbers resolve to those names
        self._outside = {node_number(n): n for n in self.graph.node_index if n.startswith("ipn_")}
        self._seq = 0 if store is None else store.get_meta("seq")
        if store is not None:
            self._resume()

    # ---------------------------------------------------------------- helpers
    def _emit(self, t_ns, kind, h: _Held | None, bundle_id, reason="", priority=0, dest="", created_ns=0):
        if h is not None:
            priority, dest, created_ns = h.priority, h.dest, h.created_ns
        deadline = h.expiry_ns if h is not None else 0
        ev = BundleEvent(t_ns, kind, self.node, bundle_id, priority, dest, created_ns, reason, deadline)
        self.counters[kind if kind not in ("dropped", "discarded") else f"{kind}.{reason}"] += 1
        if self.events is not None:
            self.events.append(ev)
        if self.on_event is not None:
            self.on_event(ev)

    def _name_of(self, number: int, default=_MISSING) -> str | None:
        """The node name of an ipn node number: a satellite's, or a node outside the constellation
        that this agent's graph names; else ValueError (or ``default``)."""
        name = self._outside.get(number)
        if name is not None:
            return name
        try:
            return node_name(number)
        except ValueError:
            if default is _MISSING:
                raise
            return default

    def _bits(self, data: bytes) -> int:
        return self.config.bundle_bits or 8 * len(data)

    def _created_ns(self, b: Bundle) -> int:
        return (b.creation_ms - self.config.epoch_dtn_ms) * 1_000_000

    def bundle_bytes(self, bundle_id: str) -> bytes | None:
        """Encoded bytes of a bundle this node holds (None if it does not)."""
        h = self._held.get(bundle_id)
        if h is None and bundle_id in self._in_flight:
            h = self._in_flight[bundle_id][1]
        return None if h is None else encode_bundle(h.bundle)

    def held_count(self) -> int:
        """Bundles this node still holds (queued or in flight)."""
        return len(self._held) + len(self._in_flight)

    def held_pairs(self) -> set[tuple[str, str]]:
        """(bundle id, recipient) of every bundle this node still holds (queued or in flight)."""
        return {(bid, h.dest) for bid, h in self._held.items()} | {
            (bid, h.dest) for bid, (_tx, h) in self._in_flight.items()}

    # ---------------------------------------------------------------- entry points
    def originate(self, payload: bytes, dest: str, priority: int, now_ns: int) -> str:
        """Create a bundle for ``dest`` (node name) with ``priority`` 1..15; returns its id."""
        if not (1 <= int(priority) <= 15):
            raise ValueError(f"bundle priority {priority}: must be 1..15")
        if dest == self.node:
            raise ValueError(f"bundle from {self.node} to itself")
        ttl_s = ttl_s_for_priority(int(priority), self.config.ttl_s_by_priority)
        b = Bundle(dest=ipn(node_number(dest), 1), src=ipn(self.number, 1),
                   creation_ms=self.config.epoch_dtn_ms + now_ns // 1_000_000, seq=self._seq,
                   lifetime_ms=int(round(ttl_s * 1000)), payload=bytes(payload))
        self._seq += 1
        if self.store is not None:
            self.store.set_meta("seq", self._seq)
        set_routing(b, [(node_number(dest), int(priority), b.lifetime_ms)], None)
        b.hop_count = (self.config.hop_limit, 0)
        add_bib(b, self.config.key, ipn(self.number, 0))
        bid = b.bundle_id
        h = _Held(b, int(priority), dest, self._created_ns(b) + int(ttl_s * _NS), self._created_ns(b), now_ns, bid=bid)
        self._emit(now_ns, "created", h, bid)
        self._accept(h, now_ns)
        return bid

    def overheard(self, bundle_bytes: bytes, now_ns: int) -> bool:
        """True (and counted in ``counters['discarded.not_next_hop']``, with no BundleEvent) when
        ``bundle_bytes`` is a copy whose next-hop block names another node; False otherwise (then
        call :meth:`receive`, which decides everything else). Same effect on the agent as
        ``receive`` of such a copy, minus the event record: a broadcast medium brings ~200k of them
        per paper run, and the satellite reports them as one counter (DtnCounters) anyway."""
        if not isinstance(bundle_bytes, bytes):
            return False
        nh = _PEEK_CACHE.get(bundle_bytes, _MISSING)
        if nh is _MISSING:
            try:
                nh = peek_next_hop(bundle_bytes)
            except BundleError:
                return False
            if len(_PEEK_CACHE) >= 4096:
                _PEEK_CACHE.clear()
            _PEEK_CACHE[bundle_bytes] = nh
        if nh is None or nh == self.number:
            return False
        self._settle(now_ns)
        self.last_received = None
        self.counters["discarded.not_next_hop"] += 1
        return True

    def overheard_count(self, copies: int, now_ns: int) -> None:
        """``copies`` copies for other next hops, counted at once (the medium's CopiesOverheard): the
        effect of that many :meth:`overheard` calls that return True, the last at ``now_ns``."""
        self._settle(now_ns)
        self.last_received = None
        self.counters["discarded.not_next_hop"] += int(copies)

    def receive(self, bundle_bytes: bytes, from_node: str, now_ns: int) -> str:
        """A copy heard on the medium; returns what happened (delivered, queued, discarded.*, dropped.*)."""
        self._settle(now_ns)
        self.last_received = None
        try:
            nh = _PEEK_CACHE.get(bundle_bytes, _MISSING) if isinstance(bundle_bytes, bytes) else _MISSING
            if nh is _MISSING:
                nh = peek_next_hop(bundle_bytes)
                if isinstance(bundle_bytes, bytes):
                    if len(_PEEK_CACHE) >= 4096:
                        _PEEK_CACHE.clear()
                    _PEEK_CACHE[bundle_bytes] = nh
            if nh is not None and nh != self.number:  # a copy for another node: discard unchecked
                self._emit(now_ns, "discarded", None, "?", reason="not_next_hop")
                return "discarded.not_next_hop"
            b = decode_bundle(bundle_bytes)
            self.last_received = b
        except BundleError as exc:
            self._emit(now_ns, "dropped", None, "?", reason="integrity")
            self.last_error = str(exc)
            return "dropped.integrity"
        try:
            c = self.config
            foreign = b.block(BIB_BLOCK) is None and b.block(RECIPIENTS_BLOCK) is None
            (_node, priority, _life), = admit(b, c.key if c.verify_integrity else None, c.foreign,
                                              c.foreign_priority, self.rx_counts)
            try:
                dest = self._name_of(b.dest[0])
            except ValueError:
                self.rx_counts["rx.unknown_destination"] += 1  # no node of that number in this agent's graph
                raise
        except (IntegrityError, BundleError, ValueError) as exc:
            self.last_error = str(exc)
            self._emit(now_ns, "dropped", None, b.bundle_id, reason="integrity")
            return "dropped.integrity"
        created = self._created_ns(b)
        bid = b.bundle_id
        h = _Held(b, priority, dest, created + b.lifetime_ms * 1_000_000, created, now_ns, bid=bid)
        if bid in self._held or bid in self._in_flight or bid in self._seen:
            # a copy of one we hold, or of one delivered here: discard. A bundle that comes back to a
            # relay that already forwarded it is accepted again (hop limit bounds any loop).
            self._emit(now_ns, "discarded", h, bid, reason="duplicate")
            return "discarded.duplicate"
        if now_ns >= h.expiry_ns:
            self._emit(now_ns, "dropped", h, bid, reason="ttl")
            return "dropped.ttl"
        if b.dest[0] == self.number:
            self._seen.add(bid)
            self._emit(now_ns, "delivered", h, bid)
            return "delivered"
        limit, count = b.hop_count or (self.config.hop_limit, 0)
        if count + 1 > limit:
            self._emit(now_ns, "dropped", h, bid, reason="hop_limit")
            return "dropped.hop_limit"
        if foreign:  # admitted by this node's policy: it signs it as the security source (RFC 9172 3.5), so
            # the nodes after it - which take a recipients block only with the BIB - accept it
            add_bib(b, c.key, ipn(self.number, 0))
            self.rx_counts["rx.foreign_signed"] += 1
        b.hop_count = (limit, count + 1)
        prev = b.previous_node
        if prev is not None:
            h.excluded_node = self._name_of(prev[0], None)
        return self._accept(h, now_ns)

    def _accept(self, h: _Held, now_ns: int) -> str:
        bid = h.bid
        h.bits = self.config.bundle_bits or 8 * len(encode_bundle(h.bundle))
        self._held[bid] = h
        if self.store is not None:
            self.store.put(StoredBundle(bid, encode_bundle(h.bundle), h.priority, h.dest, h.expiry_ns, now_ns))
        heapq.heappush(self._expiry_heap, (h.expiry_ns, bid))
        return self._enqueue(h, now_ns)

    def _enqueue(self, h: _Held, now_ns: int) -> str:
        """Check that a route exists (else drop ``no_route`` now) and put the bundle in its group."""
        self._decision_after = None
        bid = h.bid
        h.ready_ns = now_ns
        t = max(now_ns, self.radio_free_ns)
        r = self._route(h, t)
        if r is None:
            self._forget(bid)
            self._emit(now_ns, "dropped", h, bid, reason="no_route")
            return "dropped.no_route"
        key = (h.dest, h.excluded_node, frozenset(h.excluded))
        g = self._groups.get(key)
        new = g is None
        if new:
            g = self._groups[key] = _Group(key)
            g.ready_ns = now_ns
        elif g.parked_c < 0:
            g.ready_ns = max(g.ready_ns, now_ns)
        h.group = g
        g.n += 1
        heapq.heappush(g.heap, (*self._rank(h), next(self._order), bid))
        if g.parked_c >= 0:
            self._park_add(g.parked_c, h.priority, h.bits)
            g.parked_bits[h.priority] += h.bits
        elif new:  # its own group: if its best route waits for a contact not open yet, park it now
            self._maybe_park(g, r.contacts[0], t)
        return "queued"

    def _rank(self, h: _Held) -> tuple:
        """Send order: strict priority then creation time, or with ``priority_delay_s`` the earliest
        virtual deadline (creation + the priority's delay) first, then priority."""
        d = self.config.priority_delay_s
        if d is None:
            return (h.priority, h.created_ns)
        return (h.created_ns + int(d[h.priority - 1] * _NS), h.priority)

    def _maybe_park(self, g: _Group, c: int, s: int) -> bool:
        """Park ``g`` if its best first contact ``c`` is not open at ``s``: until it opens, or until
        any other outgoing contact opens first (which may offer a better route)."""
        start_ns = math.ceil(self.graph.start_l[c] * _NS)
        if start_ns <= s:
            return False
        starts = self._out_starts
        k = bisect.bisect_right(starts, s / _NS)
        nxt = math.ceil(starts[k] * _NS) if k < len(starts) else start_ns
        self._park(g, c, max(s + 1, min(start_ns, nxt)))
        return True

    def _route(self, h: _Held, t_ns: int):
        """CGR from this node at ``t_ns`` (the radio free then), after the bits already waiting for
        each contact that is not open yet (equal or higher priority). Memoised per (time, state),
        for the bundle and for every bundle that routes alike at that instant (same destination,
        exclusions, size and - while contacts have bits parked for them - priority): the query differs
        only in the deadline (the bundle's expiry), and with no hop tolerance a route found under
        one deadline is the answer under any deadline it meets, no route under a deadline is the
        answer under any earlier one (the search only prunes labels arriving after the deadline)."""
        memo = h.route_memo  # exclusions only grow: their count tells whether the memo predates one
        if memo is not None and memo[0] == t_ns and memo[1] == self._version and memo[2] == len(h.excluded):
            return memo[3]
        shared = self._route_memo
        if shared[0] != t_ns or shared[1] != self._version:
            shared = self._route_memo = (t_ns, self._version, {})
        key = (h.dest, h.excluded_node, tuple(sorted(h.excluded)) if h.excluded else (), h.bits,
               h.priority if self._parked else 0)
        hit = shared[2].get(key)
        deadline_s = h.expiry_ns / _NS
        if hit is not None and self.config.hop_tolerance_s == 0.0:
            r, d = hit
            if (r is not None and r.arrival_s <= deadline_s) or (r is None and deadline_s <= d):
                h.route_memo = (t_ns, self._version, len(h.excluded), r)
                return r
        self.cgr_queries += 1
        r = buffered_route(self.graph, self.node, h.dest, t_ns / _NS, h.bits, deadline_s, self._parked,
                           h.priority, h.excluded, h.excluded_node, self.config.hop_tolerance_s,
                           self._backlog_buf, self._excluded_buf)
        h.route_memo = (t_ns, self._version, len(h.excluded), r)
        shared[2][key] = (r, deadline_s)
        return r

    def _park_add(self, c: int, priority: int, bits: int) -> None:
        byp = self._parked.get(c)
        if byp is None:
            byp = self._parked[c] = [0] * 16
        byp[priority] += bits
        self._version += 1

    def _park(self, g: _Group, c: int, until_ns: int) -> None:
        self._decision_after = None
        g.parked_c = c
        g.ready_ns = until_ns
        for *_k, bid in g.heap:
            h = self._held.get(bid)
            if h is not None and h.group is g:
                g.parked_bits[h.priority] += h.bits
        for p, bits in g.parked_bits.items():
            self._park_add(c, p, bits)

    def _unpark(self, g: _Group) -> None:
        self._decision_after = None
        if g.parked_c < 0:
            return
        byp = self._parked[g.parked_c]
        for p, bits in g.parked_bits.items():
            byp[p] -= bits
        if not any(byp):
            del self._parked[g.parked_c]
        g.parked_c = -1
        g.parked_bits = Counter()
        self._version += 1

    def _leave_group(self, h: _Held) -> None:
        self._decision_after = None
        g = h.group
        if g is None:
            return
        h.group = None
        g.n -= 1
        if g.parked_c >= 0:
            g.parked_bits[h.priority] -= h.bits
            byp = self._parked[g.parked_c]
            byp[h.priority] -= h.bits
            self._version += 1
            if g.n == 0:
                self._unpark(g)
        if g.n == 0:
            del self._groups[g.key]

    def _forget(self, bid: str) -> None:
        self._decision_after = None
        h = self._held.pop(bid, None)
        if h is not None:
            self._leave_group(h)
        if self.store is not None:
            self.store.delete(bid)

    # ---------------------------------------------------------------- radio
    def _head(self, g: _Group):
        while g.heap:
            bid = g.heap[0][-1]
            h = self._held.get(bid)
            if h is not None and h.group is g:
                return h
            heapq.heappop(g.heap)  # stale entry (dropped, sent or re-grouped)
        return None

    def _next_decision_ns(self) -> int | None:
        """When the radio next chooses what to send: it is free and some group is ready."""
        if not self._groups:
            return None
        ready = min(map(_READY_NS, self._groups.values()))
        return max(ready, self.radio_free_ns)

    def _decide(self, s: int) -> Transmission | None:
        """At ``s`` (radio free): the highest-priority bundle whose best route leaves now goes; groups
        whose best route waits for a contact not yet open are parked until it (or a new contact) opens."""
        for g in list(self._groups.values()):
            if g.parked_c >= 0 and g.ready_ns <= s:
                self._unpark(g)
        ready = []
        for g in self._groups.values():
            if g.ready_ns <= s:
                h = self._head(g)
                if h is not None:
                    ready.append((g.heap[0], g))
        ready.sort(key=lambda x: x[0])
        for _k, g in ready:
            while True:
                h = self._head(g)
                if h is None:
                    break
                bid = h.bid
                if s >= h.expiry_ns:
                    self._forget(bid)
                    self._emit(s, "dropped", h, bid, reason="ttl")
                    continue
                r = self._route(h, s)
                if r is None:  # cannot arrive before its lifetime ends any more: drop it now
                    self._forget(bid)
                    self._emit(s, "dropped", h, bid, reason="no_route")
                    continue
                c = r.contacts[0]
                if self._maybe_park(g, c, s):
                    break
                tx = self._send(h, c, s)
                if tx is not None:
                    return tx
        return None

    def _send(self, h: _Held, c: int, s: int) -> Transmission | None:
        bid = h.bid
        h.bundle.previous_node = ipn(self.number, 0)
        dnum = node_number(h.dest)
        b = h.bundle
        split = {node_number(self.graph.contacts[c].dst): (dnum,)}
        set_routing(b, [(dnum, h.priority, b.lifetime_ms)], split)
        data = encode_bundle(h.bundle)
        bits = self._bits(data)
        end = s + math.ceil(bits / self.graph.rate_l[c] * _NS)
        if end > self.graph.end_l[c] * _NS:  # rounding: the contact closes first - re-route without it
            self._leave_group(h)
            h.excluded.add(c)
            del self._held[bid]
            self._held[bid] = h
            self._enqueue(h, s)
            return None
        self._leave_group(h)
        del self._held[bid]
        h.contact = c
        # the copies' readers (the medium, the nodes in view) in this process need not parse them
        remember_sent(data, b)
        remember_unicast_peek(data, b, split)
        tx = Transmission(data, self.graph.contacts[c].dst, s, end, bits, self.node, bid, c,
                          (self.graph.contacts[c].dst,))
        self._in_flight[bid] = (tx, h)
        if len(self._in_flight) == 1:
            self._reset_settle_at()
        self.radio_free_ns = end
        self._emit(s, "forwarded", h, bid)
        return tx

    def transmissions_until(self, t_ns: int) -> list[Transmission]:
        """Transmissions this radio starts at or before ``t_ns`` (in order). The next hop is chosen
        when the radio is free (at transmission time), not when the bundle was queued."""
        out: list[Transmission] = []
        self._settle(t_ns)
        self._decision_after = None
        while True:
            s = self._next_decision_ns()
            if s is None or s > t_ns:
                break
            tx = self._decide(s)
            if tx is not None:
                out.append(tx)
        self._decision_after = (s,)  # what the loop's last look found: nothing changed since
        return out

    def _settle(self, now_ns: int) -> None:
        """Transmissions that have ended without a failure report are done: only now is the bundle
        removed from the persistent store (a process killed mid-transmission still has it)."""
        if now_ns < self._settle_at:
            return
        settle_ns = self._settle_ns
        # _in_flight is in send order, and the one radio's transmissions end in that order (each starts
        # after the previous one's end; a failed one leaves and is sent again later, at the end): the
        # settled ones are a prefix, so stop at the first that is not (this runs on every copy heard).
        done = []
        for bid, (tx, _h) in self._in_flight.items():
            if tx.end_ns + settle_ns > now_ns:
                break
            done.append(bid)
        for bid in done:
            del self._in_flight[bid]
            if self.store is not None:
                self.store.delete(bid)
        self._reset_settle_at()

    def _reset_settle_at(self) -> None:
        if self._in_flight and self._settle_ns is not None:
            self._settle_at = next(iter(self._in_flight.values()))[0].end_ns + self._settle_ns
        else:
            self._settle_at = _NEVER

    def settle(self, tx: Transmission) -> bool:
        """``tx`` got through (no failure report can come any more): the bundle leaves this node and
        its persistent store. False (nothing done) when ``tx`` is not in flight (it failed)."""
        item = self._in_flight.get(tx.bundle_id)
        if item is None or item[0] != tx:
            return False
        del self._in_flight[tx.bundle_id]
        if self.store is not None:
            self.store.delete(tx.bundle_id)
        self._reset_settle_at()
        return True

    def in_flight(self, bundle_id: str, start_ns: int | None = None) -> Transmission | None:
        """The transmission of ``bundle_id`` not yet settled (sent, no verdict from the medium); with
        ``start_ns``, only the one started then."""
        item = self._in_flight.get(bundle_id)
        if item is None or (start_ns is not None and item[0].start_ns != start_ns):
            return None
        return item[0]

    def transmission_failed(self, tx: Transmission, now_ns: int, next_hop: str | None = None) -> None:
        """The medium says ``tx`` did not get through: take the bundle back, re-route without that contact."""
        item = self._in_flight.pop(tx.bundle_id, None)
        if item is None:
            return
        self._decision_after = None
        self._reset_settle_at()
        _tx, h = item
        self.counters["tx_failed"] += 1
        h.excluded.add(tx.contact)
        self._held[tx.bundle_id] = h
        if now_ns >= h.expiry_ns:
            self._forget(tx.bundle_id)
            self._emit(now_ns, "dropped", h, tx.bundle_id, reason="ttl")
            return
        self._enqueue(h, now_ns)

    def expire(self, now_ns: int) -> int:
        """Drop held bundles whose lifetime is over; returns how many."""
        n = 0
        while self._expiry_heap and self._expiry_heap[0][0] <= now_ns:
            exp, bid = heapq.heappop(self._expiry_heap)
            h = self._held.get(bid)
            if h is None or h.expiry_ns != exp:
                continue
            self._forget(bid)
            self._emit(exp, "dropped", h, bid, reason="ttl")
            n += 1
        return n

    def next_event_ns(self) -> int | None:
        """Earliest time this agent needs to act (a transmission decision or an expiry), or None;
        with a persistent store also the end of a transmission (its bundle leaves the store then)."""
        cands = []
        memo = self._decision_after
        nxt = memo[0] if memo is not None else self._next_decision_ns()
        if nxt is not None:
            cands.append(nxt)
        while self._expiry_heap and self._expiry_heap[0][1] not in self._held:
            heapq.heappop(self._expiry_heap)
        if self._expiry_heap:
            cands.append(self._expiry_heap[0][0])
        if self._in_flight and self.store is not None and self._settle_ns is not None:
            cands.append(min(tx.end_ns for tx, _h in self._in_flight.values()))
        return min(cands) if cands else None

    # ---------------------------------------------------------------- persistence
    def _resume(self) -> None:
        """Reload every stored bundle after a restart and route it again."""
        for sb in self.store.load_all():
            try:
                b = decode_bundle(sb.data)
            except BundleError:
                self.store.delete(sb.bundle_id)
                continue
            created = self._created_ns(b)
            h = _Held(b, sb.priority, sb.dest, sb.expiry_ns, created, sb.received_ns, bid=b.bundle_id)
            if b.previous_node is not None and b.previous_node[0] != self.number:
                h.excluded_node = self._name_of(b.previous_node[0], None)
            h.bits = self.config.bundle_bits or 8 * len(sb.data)
            self._held[sb.bundle_id] = h
            heapq.heappush(self._expiry_heap, (h.expiry_ns, sb.bundle_id))
            self._enqueue(h, sb.received_ns)
