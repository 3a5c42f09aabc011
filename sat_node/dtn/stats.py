"""The report's ``dtn.*`` figures (docs/design.md section 6) from a list of bundle events.

Input: :class:`sat_node.dtn.agent.BundleEvent` records of every agent (created, forwarded,
delivered, dropped(reason), discarded(reason)) and optionally a lower bound on latency per pair.
Everything is counted per (bundle, recipient) pair - an observation's news for one recipient: one
bundle per pair with unicast forwarding, one bundle for all of an observation's recipients with
multicast (sat_node/dtn/multicast.py); ``dtn.bundles_created`` / ``dtn.bundles_delivered`` count
pairs (their meaning with unicast), ``dtn.bundles_originated`` the bundles. Latency is delivery time
minus creation time [s]; a pair counts once as delivered (its first delivery); within TTL: delivered
by the pair's deadline (creation + its priority's TTL). Drop reasons map to the report's keys: ttl,
integrity, other (no_route, hop_limit and anything else, also listed one by one under
``dtn.dropped_detail``); drops are counted per pair (a malformed copy names none: ``integrity``).
Conservation: pairs created = delivered + dropped (with a reason) + held at the end.

How we know it is right: tests/unit/test_dtn_alone.py on hand-worked chains (per-priority medians,
the mean against its lower bound, delivery ratio, copies discarded, conservation), and the same
figures bit for bit whatever the order of the events (test_report_does_not_depend_on_event_order).
"""

from __future__ import annotations

import math
from collections import Counter, defaultdict

import numpy as np

__all__ = ["dtn_report"]


def _pct(x, q):
    return float(np.percentile(np.asarray(x, dtype=float), q)) if len(x) else None


def dtn_report(events, *, lower_bound_s: dict | None = None, held: int | None = None,
               discarded: dict[str, int] | None = None) -> dict:
    """Flat dict of dtn.* figures. ``lower_bound_s``: (bundle id, recipient) -> latency bound [s];
    ``held``: pairs still held by agents at the end (for the conservation figure); ``discarded``: copies
    discarded without an event record, by reason (the agents' ``overheard`` counters)."""
    created: dict[tuple, object] = {}
    delivered: dict[tuple, object] = {}
    drops: Counter = Counter()
    dropped_ids = set()
    discarded = Counter(discarded or {})
    forwarded = 0
    for ev in events:
        key = (ev.bundle_id, ev.dest)
        if ev.kind == "created":
            created[key] = ev
        elif ev.kind == "delivered":
            delivered.setdefault(key, ev)
        elif ev.kind == "dropped":
            drops[ev.reason] += 1
            dropped_ids.add(key)
        elif ev.kind == "discarded":
            discarded[ev.reason] += 1
        elif ev.kind == "forwarded":
            forwarded += 1
    lat = {k: (ev.t_ns - ev.created_ns) / 1e9 for k, ev in delivered.items()}
    # summed in the pairs' order, not the events': a floating-point mean depends on the order, and two
    # engines (or processes) interleave same-time events differently
    lat_list = [lat[k] for k in sorted(lat)]
    n_created = len(created)
    in_ttl = sum(1 for k, ev in delivered.items()
                 if k in created and (not created[k].deadline_ns or ev.t_ns <= created[k].deadline_ns))
    out = {
        "dtn.bundles_created": n_created,
        "dtn.bundles_originated": len({k[0] for k in created}),
        "dtn.transmissions": forwarded,
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
    for ev in created.values():
        n_by_p[ev.priority] += 1
    for k, ev in delivered.items():
        by_p[ev.priority].append(lat[k])
    for p in range(1, 16):
        xs = by_p.get(p, [])
        out[f"dtn.latency_s_by_priority.{p}.median"] = _pct(xs, 50)
        out[f"dtn.latency_s_by_priority.{p}.p95"] = _pct(xs, 95)
        out[f"dtn.latency_s_by_priority.{p}.max"] = float(max(xs)) if xs else None
        out[f"dtn.latency_s_by_priority.{p}.count"] = len(xs)
        out[f"dtn.latency_s_by_priority.{p}.created"] = n_by_p.get(p, 0)
    if lower_bound_s is not None:
        lb = [v for v in lower_bound_s.values() if math.isfinite(v)]
        out["dtn.latency_s.lower_bound_mean"] = float(np.mean(lb)) if lb else None
        both = [lower_bound_s[b] for b in lat if b in lower_bound_s and math.isfinite(lower_bound_s[b])]
        out["dtn.latency_s.lower_bound_mean_delivered"] = float(np.mean(both)) if both else None
    if held is not None:
        out["dtn.bundles_held_at_end"] = held
        out["dtn.conservation_ok"] = n_created == len(delivered) + len((dropped_ids & set(created)) - set(delivered)) \
            + held
    return out
