"""Deterministic discrete-event engine for the DTN alone: bundle agents + the link model.

Events are ordered by (t_ns, kind order, seq) (simpy-style); kinds: a bundle arrives at a node, a
bundle is created at its source (traffic), an agent wakes (transmission start, expiry). After each
event the affected agent is asked what its radio sends up to now (:meth:`BundleAgent.
transmissions_until`); each transmission goes to :class:`dtn_router.link.LinkModel`, whose copies
become arrival events and whose failures go back to the sender. Same inputs -> same event list.

It also computes the latency lower bound of each bundle: the larger of (a) its earliest
arrival over the plan with transmission and light time and no contention, and (b) the time its
source's radio, sending the source's bundles one at a time in creation order, would finish it.

Beside it, :func:`store_forward_bound_mean`: a lower bound on the MEAN latency that holds for every
routing and send order which delivers every bundle within its TTL. Bundle i leaves its source no
earlier, summed over the source's bundles, than the creation-order finish b_i above (equal-size
bundles on one radio: every work-conserving order gives the same set of finish times, idling or
relaying for others only delays them), and then still needs h_i - 1 further transmissions and h_i
light times, h_i = the fewest hops over contacts open at some time in [created, created + TTL]. So
sum(latency) >= sum(b_i + h_i * light + (h_i - 1) * tx). The per-bundle bound above takes max(a, b)
instead of that sum: on the drawn two-bundle chain of tests/unit/test_dtn_des.py the optimal schedule is 1.27x it.

How we know it is right: conservation on every run (created = delivered + dropped + held), tests in
tests/unit/test_dtn_des.py on drawn plans with hand-worked delivery times, and the study's inputs.
"""

from __future__ import annotations

import heapq
import itertools
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from orbit_clock.contact_plan import ContactPlan
from sat_node.dtn.agent import AgentConfig, BundleAgent, ttl_s_for_priority
from sat_node.dtn.cgr import ContactGraph
from sat_node.dtn.stats import dtn_report
from sat_node.dtn.traffic import TrafficItem

from .link import LinkModel

__all__ = ["DtnRun", "run_dtn", "latency_lower_bounds", "store_forward_bound_mean"]

_NS = 1_000_000_000
_ARRIVE, _CREATE, _WAKE = 0, 1, 2


@dataclass
class DtnRun:
    agents: dict[str, BundleAgent]
    link: LinkModel
    events: list = field(default_factory=list)
    created_ids: dict = field(default_factory=dict)  # traffic index -> bundle id
    wall_s: float = 0.0
    end_ns: int = 0

    def held(self) -> int:
        return sum(a.held_count() for a in self.agents.values())

    def discarded(self) -> dict[str, int]:
        """Copies discarded by :meth:`BundleAgent.overheard` (no event record), by reason."""
        return {"not_next_hop": sum(a.counters["discarded.not_next_hop"] for a in self.agents.values())}

    def report(self, lower_bound_s: dict[str, float] | None = None) -> dict:
        """The dtn.* figures of this run (:func:`sat_node.dtn.stats.dtn_report`)."""
        return dtn_report(self.events, held=self.held(), lower_bound_s=lower_bound_s, discarded=self.discarded())


def _payload(item: TrafficItem, size: int) -> bytes:
    head = f'{{"packet_id":"{item.packet_id}","region":"{item.region}","t_s":{item.t_s}}}'.encode()
    return head + b" " * max(0, size - len(head))


def run_dtn(plan: ContactPlan, traffic: list[TrafficItem], *, config: AgentConfig | None = None,
            truth: ContactPlan | None = None, horizon_ns: int | None = None, payload_bytes: int = 160,
            dump_dir=None, dump_count: int = 100) -> DtnRun:
    """Run the DTN on ``plan`` (what agents believe; ``truth`` defaults to it) with ``traffic``.
    ``dump_dir``: write the encoded bytes of the first ``dump_count`` bundles created there
    (``<bundle id>.bpv7``, as they stand at creation: primary, BIB, priority, hop count, payload)."""
    t0 = time.perf_counter()
    config = config or AgentConfig()
    graph = ContactGraph(plan)
    nodes = sorted(set(plan.nodes) | {t.source for t in traffic} | {t.dest for t in traffic})
    events: list = []
    agents = {n: BundleAgent(n, graph, config, on_event=events.append, keep_events=False) for n in nodes}
    link = LinkModel(truth or plan)
    run = DtnRun(agents, link, events)
    heap: list = []
    seq = itertools.count()
    for i, item in enumerate(traffic):
        heapq.heappush(heap, (int(round(item.t_s * _NS)), _CREATE, next(seq), i))
    if horizon_ns is None:
        horizon_ns = int(max([c.end_s for c in plan.contacts] + [t.t_s for t in traffic] + [0.0]) * _NS) \
            + int(max(config.ttl_s_by_priority.values()) * _NS)
    wake_at: dict[str, int] = {}

    def service(name: str, now: int) -> None:
        a = agents[name]
        a.expire(now)
        for tx in a.transmissions_until(now):
            out = link.transmit(tx.sender, tx.next_hop, tx.start_ns, tx.bits)
            if not out.ok:
                a.transmission_failed(tx, max(now, tx.start_ns))
            for cp in out.copies:
                heapq.heappush(heap, (cp.arrival_ns, _ARRIVE, next(seq), (cp.node, tx.bundle_bytes, tx.sender)))
        nxt = a.next_event_ns()
        if nxt is not None and nxt <= horizon_ns:
            nxt = max(nxt, now + (0 if nxt > now else 1))
            if wake_at.get(name) is None or nxt < wake_at[name] or wake_at[name] <= now:
                wake_at[name] = nxt
                heapq.heappush(heap, (nxt, _WAKE, next(seq), name))

    now = 0
    while heap:
        t, kind, _s, data = heapq.heappop(heap)
        if t > horizon_ns:
            break
        now = t
        if kind == _CREATE:
            item = traffic[data]
            bid = agents[item.source].originate(_payload(item, payload_bytes), item.dest, item.priority, t)
            run.created_ids[data] = bid
            if dump_dir is not None and len(run.created_ids) <= dump_count:
                raw = agents[item.source].bundle_bytes(bid)
                if raw is not None:
                    (Path(dump_dir) / f"{bid}.bpv7").write_bytes(raw)
            service(item.source, t)
        elif kind == _ARRIVE:
            node, raw, sender = data
            a = agents.get(node)
            if a is not None and not a.overheard(raw, t):  # a copy for another node is only counted
                status = a.receive(raw, sender, t)
                if status == "queued":  # nothing else changes what the agent's radio does
                    service(node, t)
        else:
            if wake_at.get(data) == t:
                wake_at[data] = None
            service(data, t)
    for name, a in agents.items():
        a.expire(now)
        a._settle(horizon_ns)
    run.end_ns = now
    run.wall_s = time.perf_counter() - t0
    return run


def latency_lower_bounds(plan: ContactPlan, traffic: list[TrafficItem], bundle_bits: int,
                         created_ids: dict[int, str]) -> dict[str, float]:
    """bundle id -> lower bound on its latency [s] (see the module docstring); inf when unreachable."""
    graph = ContactGraph(plan)
    cache: dict[tuple[str, float], dict[str, float]] = {}
    radio_free: dict[str, float] = {}
    rate_by_src: dict[str, float] = {}
    for c in plan.contacts:
        rate_by_src[c.src] = max(rate_by_src.get(c.src, 0.0), c.rate_bps)
    out = {}
    for i, item in sorted(enumerate(traffic), key=lambda x: x[1].t_s):  # the radio serves in creation order
        key = (item.source, item.t_s)
        if key not in cache:
            cache[key] = graph.earliest_arrivals(item.source, item.t_s, bundle_bits)
        a = cache[key].get(item.dest, float("inf")) - item.t_s
        rate = rate_by_src.get(item.source)
        if rate:
            leave = max(item.t_s, radio_free.get(item.source, 0.0)) + bundle_bits / rate
            radio_free[item.source] = leave
            b = leave - item.t_s
        else:
            b = float("inf")
        if i in created_ids:
            out[created_ids[i]] = max(a, b)
    return out


def store_forward_bound_mean(plan: ContactPlan, traffic: list[TrafficItem], bundle_bits: int,
                             ttl_s_by_priority: dict[int, float]) -> float | None:
    """Lower bound [s] on the mean latency of ANY routing and send order that delivers every bundle
    within its TTL (module docstring); the mean is over bundles that some contact path can deliver
    within their TTL at all, None when there are none. The per-bundle terms are not bounds one by one:
    only their sum is (a policy may send any one bundle earlier than creation order would)."""
    if not plan.contacts:
        return None
    names = plan.nodes
    idx = {n: i for i, n in enumerate(names)}
    start = np.array([c.start_s for c in plan.contacts])
    end = np.array([c.end_s for c in plan.contacts])
    src = np.array([idx[c.src] for c in plan.contacts])
    dst = np.array([idx[c.dst] for c in plan.contacts])
    tx_min = bundle_bits / max(c.rate_bps for c in plan.contacts)
    light_min = min(c.range_light_s for c in plan.contacts)
    rate_by_src: dict[str, float] = {}
    for c in plan.contacts:
        rate_by_src[c.src] = max(rate_by_src.get(c.src, 0.0), c.rate_bps)
    hops_cache: dict[tuple[float, float, str], list[int]] = {}
    radio_free: dict[str, float] = {}
    total, count = 0.0, 0
    for item in sorted(traffic, key=lambda it: it.t_s):  # the radio serves in creation order (stable)
        rate = rate_by_src.get(item.source)
        if not rate or item.dest not in idx:
            continue
        leave = max(item.t_s, radio_free.get(item.source, 0.0)) + bundle_bits / rate
        radio_free[item.source] = leave
        ttl = ttl_s_for_priority(item.priority, ttl_s_by_priority)
        key = (item.t_s, ttl, item.source)
        if key not in hops_cache:
            hops_cache[key] = _fewest_hops(idx[item.source], len(names), src, dst,
                                           (start < item.t_s + ttl) & (end > item.t_s))
        h = hops_cache[key][idx[item.dest]]
        if h < 0:  # no contact path within the TTL: no policy delivers it
            continue
        total += (leave - item.t_s) + h * light_min + (h - 1) * tx_min
        count += 1
    return total / count if count else None


def _fewest_hops(origin: int, n: int, src: np.ndarray, dst: np.ndarray, mask: np.ndarray) -> list[int]:
    """Breadth-first hop counts from ``origin`` over the contacts in ``mask`` (-1: unreachable)."""
    adj: list[set[int]] = [set() for _ in range(n)]
    for a, b in zip(src[mask].tolist(), dst[mask].tolist()):
        adj[a].add(b)
    hops = [-1] * n
    hops[origin] = 0
    frontier = [origin]
    while frontier:
        nxt = []
        for u in frontier:
            for v in adj[u]:
                if hops[v] < 0:
                    hops[v] = hops[u] + 1
                    nxt.append(v)
        frontier = nxt
    return hops
