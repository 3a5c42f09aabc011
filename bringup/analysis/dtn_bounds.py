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

Both serve each source's radio in creation order whatever the order of the traffic list. With
``per_observation=True`` (multicast forwarding: one bundle per observation, a traffic row) a source's
radio has one job per observation instead of one per (observation, recipient) pair, each at least
bundle_bits long. The mean bound then weighs observation o by its n_o deliverable recipients: in
any schedule the k-th smallest finish time is at least the k-th creation-order finish F_k and job o
finishes no earlier than t_o + one transmission, so sum_o n_o f_o >= the least sum_o n_o max(F_k(o),
t_o + tx) over the ways to give the jobs distinct ranks k(o) (an assignment problem, solved exactly
with scipy's linear_sum_assignment).

:func:`floor_mean` - the any-policy floor: each (observation, recipient) pair needs at least its fewest
hops (over contacts open within its TTL) times one transmission and one light time, whatever the
forwarding, queueing or load.

How we know it is right: tests/unit/test_dtn_alone.py - hand-worked bounds on drawn chains, and on
random plans every run that delivers all its bundles within their TTLs has a mean latency at or above
:func:`store_forward_bound_mean`; each item's fewest hops (:func:`hops_within_ttl`) and the one-to-all
earliest arrivals against plain per-item searches on random plans.
"""

from __future__ import annotations

import numpy as np

from orbit_clock.contact_plan import ContactPlan
from sat_node.dtn.agent import ttl_s_for_priority
from sat_node.dtn.cgr import ContactGraph
from sat_node.dtn.traffic import TrafficItem

__all__ = ["floor_mean", "hops_within_ttl", "latency_lower_bounds", "store_forward_bound_mean"]


def latency_lower_bounds(plan: ContactPlan, traffic: list[TrafficItem], bundle_bits: int,
                         created_ids: dict[int, str], *, per_observation: bool = False) -> dict[tuple[str, str], float]:
    """(bundle id, recipient) -> lower bound on its latency [s] (module docstring); inf when
    unreachable. ``created_ids``: traffic index -> bundle id (only those get a bound). The source's
    radio term counts one bundle per traffic item (unicast forwarding's load)."""
    graph = ContactGraph(plan)
    cache: dict[tuple[str, float], dict[str, float]] = {}
    radio_free: dict[str, float] = {}
    rate_by_src: dict[str, float] = {}
    for c in plan.contacts:
        rate_by_src[c.src] = max(rate_by_src.get(c.src, 0.0), c.rate_bps)
    out = {}
    done: dict[tuple, float] = {}  # observation -> when its one bundle leaves (per_observation)
    for i, item in sorted(enumerate(traffic), key=lambda x: x[1].t_s):  # the radio serves in creation order
        key = (item.source, item.t_s)
        if key not in cache:
            cache[key] = graph.earliest_arrivals(item.source, item.t_s, bundle_bits)
        a = cache[key].get(item.dest, float("inf")) - item.t_s
        rate = rate_by_src.get(item.source)
        if rate:
            obs = (item.source, item.row, item.t_s)
            if per_observation and obs in done:
                leave = done[obs]
            else:
                leave = max(item.t_s, radio_free.get(item.source, 0.0)) + bundle_bits / rate
                radio_free[item.source] = done[obs] = leave
            b = leave - item.t_s
        else:
            b = float("inf")
        if i in created_ids:
            out[(created_ids[i], item.dest)] = max(a, b)
    return out


def store_forward_bound_mean(plan: ContactPlan, traffic: list[TrafficItem], bundle_bits: int,
                             ttl_s_by_priority: dict[int, float], *, per_observation: bool = False,
                             hops: list[int] | None = None) -> float | None:
    """Lower bound [s] on the mean latency of ANY routing and send order that delivers every bundle
    within its TTL (module docstring); the mean is over bundles that some contact path can deliver
    within their TTL at all, None when there are none. The per-bundle terms are not bounds one by one:
    only their sum is (a policy may send any one bundle earlier than creation order would).
    ``hops``: :func:`hops_within_ttl` of the same arguments, when the caller has it already."""
    if not plan.contacts:
        return None
    if per_observation:
        return _per_observation_bound(plan, traffic, bundle_bits, ttl_s_by_priority, hops)
    known = set(plan.nodes)
    tx_min, light_min, rate_by_src, hops = _bound_inputs(plan, traffic, bundle_bits, ttl_s_by_priority, hops)
    radio_free: dict[str, float] = {}
    total, count = 0.0, 0
    for item, h in sorted(zip(traffic, hops), key=lambda x: x[0].t_s):  # the radio serves in creation order
        rate = rate_by_src.get(item.source)
        if not rate or item.dest not in known:
            continue
        leave = max(item.t_s, radio_free.get(item.source, 0.0)) + bundle_bits / rate
        radio_free[item.source] = leave
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


def hops_within_ttl(plan: ContactPlan, traffic: list[TrafficItem], ttl_s_by_priority: dict[int, float]) -> list[int]:
    """Per traffic item: its fewest hops over contacts open within [created, created + TTL] (-1: none)."""
    names = plan.nodes
    idx = {n: i for i, n in enumerate(names)}
    start = np.array([c.start_s for c in plan.contacts])
    end = np.array([c.end_s for c in plan.contacts])
    src = np.array([idx[c.src] for c in plan.contacts])
    dst = np.array([idx[c.dst] for c in plan.contacts])
    cache: dict[tuple, list[int]] = {}
    out = []
    for item in traffic:
        if item.source not in idx or item.dest not in idx:
            out.append(-1)
            continue
        ttl = ttl_s_for_priority(item.priority, ttl_s_by_priority)
        key = (item.t_s, ttl, item.source)
        if key not in cache:
            cache[key] = _fewest_hops(idx[item.source], len(names), src, dst, (start < item.t_s + ttl) & (end > item.t_s))
        out.append(cache[key][idx[item.dest]])
    return out


def floor_mean(plan: ContactPlan, traffic: list[TrafficItem], bundle_bits: int,
               ttl_s_by_priority: dict[int, float], *, hops: list[int] | None = None) -> float | None:
    """The any-policy floor [s] (module docstring): mean over the pairs some contact path reaches
    within their TTL of fewest hops x (one transmission + one light time), shortest of the plan.
    ``hops``: :func:`hops_within_ttl` of the same arguments, when the caller has it already."""
    if not plan.contacts:
        return None
    tx_min = bundle_bits / max(c.rate_bps for c in plan.contacts)
    light_min = min(c.range_light_s for c in plan.contacts)
    if hops is None:
        hops = hops_within_ttl(plan, traffic, ttl_s_by_priority)
    hops = [h for h in hops if h > 0]
    return float(np.mean(hops)) * (tx_min + light_min) if hops else None


def _bound_inputs(plan: ContactPlan, traffic: list[TrafficItem], bundle_bits: int,
                  ttl_s_by_priority: dict[int, float], hops: list[int] | None = None):
    """What both store-and-forward bounds start from: the fastest transmission time, the shortest light
    time, each source's fastest rate and each bundle's fewest hops within its TTL."""
    tx_min = bundle_bits / max(c.rate_bps for c in plan.contacts)
    light_min = min(c.range_light_s for c in plan.contacts)
    rate_by_src: dict[str, float] = {}
    for c in plan.contacts:
        rate_by_src[c.src] = max(rate_by_src.get(c.src, 0.0), c.rate_bps)
    if hops is None:
        hops = hops_within_ttl(plan, traffic, ttl_s_by_priority)
    return tx_min, light_min, rate_by_src, hops


def _per_observation_bound(plan: ContactPlan, traffic: list[TrafficItem], bundle_bits: int,
                           ttl_s_by_priority: dict[int, float], hops: list[int] | None = None) -> float | None:
    """store_forward_bound_mean with one radio job per observation (module docstring)."""
    tx_min, light_min, rate_by_src, hops = _bound_inputs(plan, traffic, bundle_bits, ttl_s_by_priority, hops)
    obs: dict[tuple, list] = {}  # (source, row, t) -> [t, n deliverable pairs]
    total, count = 0.0, 0
    for item, h in zip(traffic, hops):
        if h < 0 or not rate_by_src.get(item.source):
            continue
        o = obs.setdefault((item.source, item.row, item.t_s), [item.t_s, 0])
        o[1] += 1
        total += (h - 1) * tx_min + h * light_min
        count += 1
    if not count:
        return None
    from scipy.optimize import linear_sum_assignment  # here: only this bound needs scipy (its import is slow)

    by_src: dict[str, list] = {}
    for (src, _row, _t), (t, n) in obs.items():
        by_src.setdefault(src, []).append((t, n))
    for src, jobs in by_src.items():
        d = bundle_bits / rate_by_src[src]
        jobs.sort()
        free = 0.0
        finishes = []
        for t, _n in jobs:
            free = max(t, free) + d
            finishes.append(free)
        t = np.array([j[0] for j in jobs])
        n = np.array([j[1] for j in jobs], dtype=float)
        cost = n[:, None] * np.maximum(np.array(finishes)[None, :], (t + d)[:, None])
        rows, cols = linear_sum_assignment(cost)
        total += float(cost[rows, cols].sum() - (n * t).sum())
    return total / count
