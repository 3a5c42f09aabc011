"""The report's ``dtn.*`` figures (DESIGN.md section 6) from a list of bundle events.

Input: :class:`sat_node.dtn.agent.BundleEvent` records of every agent (created, forwarded,
delivered, dropped(reason), discarded(reason)) and optionally the per-bundle lower bound on latency.
Latency is delivery time minus creation time [s]; a bundle counts once as delivered (its first
delivery). Drop reasons map to the report's keys: ttl, integrity, other (no_route, hop_limit and
anything else, also listed one by one under ``dtn.dropped_detail``).

How we know it is right: tests/unit/test_dtn_alone.py on hand-worked chains (per-priority medians,
the mean against its lower bound, delivery ratio, copies discarded, conservation).
"""

from __future__ import annotations

from collections import Counter, defaultdict

import numpy as np

__all__ = ["dtn_report"]


def _pct(x, q):
    return float(np.percentile(np.asarray(x, dtype=float), q)) if len(x) else None


def dtn_report(events, *, lower_bound_s: dict[str, float] | None = None, held: int | None = None,
               discarded: dict[str, int] | None = None) -> dict:
    """Flat dict of dtn.* figures. ``lower_bound_s``: bundle id -> latency bound [s]; ``held``: bundles
    still held by agents at the end (for the conservation figure); ``discarded``: copies discarded
    without an event record, by reason (the agents' ``overheard`` counters)."""
    created: dict[str, object] = {}
    delivered: dict[str, object] = {}
    drops: Counter = Counter()
    dropped_ids = set()
    discarded = Counter(discarded or {})
    for ev in events:
        if ev.kind == "created":
            created[ev.bundle_id] = ev
        elif ev.kind == "delivered":
            delivered.setdefault(ev.bundle_id, ev)
        elif ev.kind == "dropped":
            drops[ev.reason] += 1
            dropped_ids.add(ev.bundle_id)
        elif ev.kind == "discarded":
            discarded[ev.reason] += 1
    lat = {bid: (ev.t_ns - ev.created_ns) / 1e9 for bid, ev in delivered.items()}
    lat_list = list(lat.values())
    n_created = len(created)
    in_ttl = sum(1 for bid, ev in delivered.items()
                 if bid in created and lat[bid] <= _ttl_of(created[bid]))
    out = {
        "dtn.bundles_created": n_created,
        "dtn.bundles_delivered": len(delivered),
        "dtn.delivery_ratio": (len(delivered) / n_created) if n_created else None,
        "dtn.delivered_within_ttl_ratio": (in_ttl / n_created) if n_created else None,
        "dtn.latency_s.mean": float(np.mean(lat_list)) if lat_list else None,
        "dtn.latency_s.median": _pct(lat_list, 50),
        "dtn.latency_s.p95": _pct(lat_list, 95),
        "dtn.latency_s.max": float(np.max(lat_list)) if lat_list else None,
        "dtn.dropped.ttl": drops["ttl"],
        "dtn.dropped.integrity": drops["integrity"],
        "dtn.dropped.other": sum(v for k, v in drops.items() if k not in ("ttl", "integrity")),
        "dtn.copies_discarded": sum(discarded.values()),
    }
    for k, v in sorted(drops.items()):
        out[f"dtn.dropped_detail.{k}"] = v
    for k, v in sorted(discarded.items()):
        out[f"dtn.copies_discarded_detail.{k}"] = v
    by_p = defaultdict(list)
    n_by_p = Counter()
    for bid, ev in created.items():
        n_by_p[ev.priority] += 1
    for bid, ev in delivered.items():
        by_p[ev.priority].append(lat[bid])
    for p in range(1, 16):
        xs = by_p.get(p, [])
        out[f"dtn.latency_s_by_priority.{p}.median"] = _pct(xs, 50)
        out[f"dtn.latency_s_by_priority.{p}.p95"] = _pct(xs, 95)
        out[f"dtn.latency_s_by_priority.{p}.max"] = float(max(xs)) if xs else None
        out[f"dtn.latency_s_by_priority.{p}.count"] = len(xs)
        out[f"dtn.latency_s_by_priority.{p}.created"] = n_by_p.get(p, 0)
    if lower_bound_s is not None:
        lb = [v for v in lower_bound_s.values() if np.isfinite(v)]
        out["dtn.latency_s.lower_bound_mean"] = float(np.mean(lb)) if lb else None
        both = [lower_bound_s[b] for b in lat if b in lower_bound_s and np.isfinite(lower_bound_s[b])]
        out["dtn.latency_s.lower_bound_mean_delivered"] = float(np.mean(both)) if both else None
    if held is not None:
        out["dtn.bundles_held_at_end"] = held
        out["dtn.conservation_ok"] = n_created == len(delivered) + len(dropped_ids & set(created)) + held
    return out


def _ttl_of(ev) -> float:
    return getattr(ev, "ttl_s", float("inf")) or float("inf")
