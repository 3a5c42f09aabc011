"""Lower bounds on DTN latency for a contact plan and a traffic table (what no routing can beat).

:func:`latency_lower_bounds` - per bundle, the larger of (a) its earliest arrival over the plan with
transmission and light time and no contention (contact graph routing's earliest arrival,
sat_node/dtn/cgr.py) and (b) the time its source's radio, sending the source's bundles one at a time
in creation order, would finish it. Each is a bound for that bundle under no contention at relays;
their mean is the study's reference figure for the latency of the DTN (``lower_bound_mean``).

:func:`store_forward_bound_mean` - a lower bound on the MEAN latency that holds for every routing
and send order which delivers every bundle within its TTL. Bundle i leaves its source no earlier,
summed over the source's bundles, than the creation-order finish b_i above (equal-size bundles on
one radio: every work-conserving order gives the same set of finish times, idling or relaying for
others only delays them), and then still needs h_i - 1 further transmissions and h_i light times,
h_i = the fewest hops over contacts open at some time in [created, created + TTL]. So
sum(latency) >= sum(b_i + h_i * light + (h_i - 1) * tx). The per-bundle bound above takes max(a, b)
instead of that sum: on the drawn two-bundle chain of tests/unit/test_dtn_alone.py the optimal
schedule is 1.27x it.

Both serve each source's radio in creation order whatever the order of the traffic list.

How we know it is right: tests/unit/test_dtn_alone.py - hand-worked bounds on drawn chains, and on
random plans every run that delivers all its bundles within their TTLs has a mean latency at or above
:func:`store_forward_bound_mean`.
"""

from __future__ import annotations

import numpy as np

from orbit_clock.contact_plan import ContactPlan
from sat_node.dtn.agent import ttl_s_for_priority
from sat_node.dtn.cgr import ContactGraph
from sat_node.dtn.traffic import TrafficItem

__all__ = ["latency_lower_bounds", "store_forward_bound_mean"]


def latency_lower_bounds(plan: ContactPlan, traffic: list[TrafficItem], bundle_bits: int,
                         created_ids: dict[int, str]) -> dict[str, float]:
    """bundle id -> lower bound on its latency [s] (module docstring); inf when unreachable.
    ``created_ids``: traffic index -> bundle id (only those get a bound)."""
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
