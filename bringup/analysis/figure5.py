"""The study's Figure 5 in kind: bundle latency by priority against the access gaps by priority.

Nag et al., "Autonomous Scheduling of Agile Spacecraft Constellations with Delay Tolerant Networking
for Reactive Imaging" (ICAPS SPARK 2019), section 5, Fig. 5: an observation of a region is sent to
the satellites that reach that region next (priority 1 = the next one, docs/design.md section 1). Whether
the implicit consensus works depends on whether a bundle arrives *before* its destination reaches
the region: its latency must be shorter than the gap between the observation and the destination's
next access. This module puts the two side by side.

Definitions, per bundle (one bundle = one observation x one destination; from the run's
``/sat_XX/dtn/events``):

* latency_s  = first delivery time - creation time (delivered bundles only);
* gap_s      = start of the destination's next access to the observed GP's region after the
  creation time, minus the creation time (``orbit_clock.next_access_s`` on the World's access
  windows; 0 when the destination is already over the region; bundles whose destination never
  reaches the region again are left out of the gaps);
* arrived before = delivered and delivery time <= creation time + gap_s. The *implicit-consensus
  margin* of a priority is the fraction of its bundles (delivered or not, with a gap) that arrived
  before; ``margin_fraction_delivered`` is the same among delivered bundles only.
* arrived before the plan (optional, with ``replan_period_s``): delivered no later than the
  destination's last replan at or before its next access (replans at t = 0, P, 2P, ... as
  sat_node/satellite.py does), i.e. in time to shape the plan it flies over the region with;
  ``plan_margin_fraction`` is that fraction of the bundles with a gap. A bundle that beats the
  access but not that replan cannot prevent a duplicate observation.

How we know it is right: tests/unit/test_figure5.py - hand-built access windows and bundle events
with the gaps, latencies and fractions worked out by hand, and on a small real run a brute-force
recomputation of every gap from the raw window arrays (min over the destination's windows of the
region with end > t of max(start, t)).
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bringup.recording.bag import BagReader
from msgs_json import codec
from orbit_clock import next_access_s

__all__ = ["BundleRow", "bundle_rows", "bundle_rows_from_bag", "figure5_data", "figure5_summary",
           "plot_figure5"]

_NS = 1_000_000_000


@dataclass
class BundleRow:
    """One bundle of a run: created by ``src`` for ``dst`` at ``created_ns`` (observation of ``gp``)."""

    bundle_id: str
    src: str
    dst: str
    priority: int
    created_ns: int
    gp: int
    delivered_ns: int | None = None


def bundle_rows(events) -> list[BundleRow]:
    """One row per (bundle, recipient) pair - a bundle of unicast forwarding, a recipient of a
    multicast bundle - from decoded msgs_json bundle events (any order). The first delivery counts;
    deliveries of pairs whose creation is not in ``events`` are ignored."""
    rows: dict[tuple[str, str], BundleRow] = {}
    deliveries: dict[tuple[str, str], int] = {}
    for m in events:
        tag = type(m).__struct_config__.tag
        if tag == "created":
            if (m.bundle_id, m.dst) not in rows:
                rows[(m.bundle_id, m.dst)] = BundleRow(m.bundle_id, m.src, m.dst, int(m.priority), int(m.creation_ns),
                                                       int(m.gp))
        elif tag == "delivered":
            t = int(m.t_ns)
            key = (m.bundle_id, m.sat)
            if key not in deliveries or t < deliveries[key]:
                deliveries[key] = t
    for key, t in deliveries.items():
        if key in rows:
            rows[key].delivered_ns = t
    return sorted(rows.values(), key=lambda r: (r.created_ns, r.bundle_id, r.dst))


def bundle_rows_from_bag(bag_dir) -> list[BundleRow]:
    """Bundles of a run from its bag (``/sat_XX/dtn/events``)."""
    with BagReader(bag_dir) as bag:
        topics = [t.topic for t in bag.topics() if t.topic.endswith("/dtn/events")]
        events = [codec.decode(e.topic, e.data) for e in bag.envelopes(topics)] if topics else []
    return bundle_rows(events)


def _gap_s(windows, region: int, dst: str, t_s: float, cache: dict) -> float | None:
    key = (region, t_s)
    nxt = cache.get(key)
    if nxt is None:
        nxt = next_access_s(windows, region, t_s)
        cache[key] = nxt
    s = nxt.get(dst)
    return None if s is None else max(0.0, s - t_s)


def figure5_data(rows: list[BundleRow], access, gp_region, replan_period_s: float | None = None) -> dict:
    """Per priority: latencies [s], gaps [s] and the implicit-consensus margin.

    ``access``: orbit_clock.AccessWindows (with its GP -> region table); ``gp_region``: region index
    of every GP id (``World.ctx.gps.region_index``). Returns
    ``{"by_priority": {p: {"latency_s": [...], "gap_s": [...], "count", "delivered", "with_gap",
    "arrived_before", "margin_fraction", "margin_fraction_delivered"}}, "overall": {...}}``.
    """
    by: dict[int, dict] = defaultdict(lambda: {"latency_s": [], "gap_s": [], "count": 0, "delivered": 0,
                                               "with_gap": 0, "arrived_before": 0, "delivered_with_gap": 0,
                                               "arrived_before_plan": 0})
    cache: dict = {}
    for r in rows:
        d = by[r.priority]
        d["count"] += 1
        t_s = r.created_ns / _NS
        gap = _gap_s(access, int(gp_region[r.gp]), r.dst, t_s, cache)
        lat = None if r.delivered_ns is None else (r.delivered_ns - r.created_ns) / _NS
        if lat is not None:
            d["delivered"] += 1
            d["latency_s"].append(lat)
        if gap is not None:
            d["with_gap"] += 1
            d["gap_s"].append(gap)
            if lat is not None:
                d["delivered_with_gap"] += 1
                if lat <= gap:
                    d["arrived_before"] += 1
                if replan_period_s and lat <= (np.floor((t_s + gap) / replan_period_s) * replan_period_s) - t_s:
                    d["arrived_before_plan"] += 1
    out: dict = {"by_priority": {}}
    tot = {"count": 0, "delivered": 0, "with_gap": 0, "arrived_before": 0, "delivered_with_gap": 0,
           "arrived_before_plan": 0}
    for p in sorted(by):
        d = by[p]
        for k in tot:
            tot[k] += d[k]
        d["margin_fraction"] = d["arrived_before"] / d["with_gap"] if d["with_gap"] else None
        d["margin_fraction_delivered"] = (d["arrived_before"] / d["delivered_with_gap"]
                                          if d["delivered_with_gap"] else None)
        d["plan_margin_fraction"] = (d["arrived_before_plan"] / d["with_gap"]
                                     if d["with_gap"] and replan_period_s else None)
        out["by_priority"][p] = d
    tot["margin_fraction"] = tot["arrived_before"] / tot["with_gap"] if tot["with_gap"] else None
    tot["margin_fraction_delivered"] = (tot["arrived_before"] / tot["delivered_with_gap"]
                                        if tot["delivered_with_gap"] else None)
    tot["plan_margin_fraction"] = (tot["arrived_before_plan"] / tot["with_gap"]
                                   if tot["with_gap"] and replan_period_s else None)
    out["overall"] = tot
    return out


def figure5_summary(data: dict) -> dict:
    """JSON-friendly medians per priority (no raw arrays), for report.json / compare output."""
    rows = {}
    for p, d in data["by_priority"].items():
        lat = np.asarray(d["latency_s"], float)
        gap = np.asarray(d["gap_s"], float)
        rows[str(p)] = {
            "count": d["count"], "delivered": d["delivered"],
            "latency_s_median": float(np.median(lat)) if lat.size else None,
            "gap_s_median": float(np.median(gap)) if gap.size else None,
            "margin_fraction": d["margin_fraction"],
            "margin_fraction_delivered": d["margin_fraction_delivered"],
            "plan_margin_fraction": d["plan_margin_fraction"],
        }
    return {"by_priority": rows, "overall": dict(data["overall"])}


def plot_figure5(path: Path, data: dict, title: str | None = None) -> Path:
    """Box plots per priority (bringup/analysis/figures.py figure_latency_vs_gaps) with the margin on top."""
    # here, not at the top: matplotlib costs ~0.27 s to import (python -X importtime); the data and
    # summary above serve compare --json and the tests without it
    from bringup.analysis import figures as plots

    bp = data["by_priority"]
    o = data["overall"]
    mf = o.get("margin_fraction")
    pf = o.get("plan_margin_fraction")
    title = title or ("Bundle latency vs access gaps by priority"
                      + (f": {100 * mf:.0f} % of bundles arrived before the destination reached the region"
                         if mf is not None else "")
                      + (f", {100 * pf:.0f} % before its plan for it" if pf is not None else ""))
    return plots.plot_latency_vs_gaps(
        path, {p: d["latency_s"] for p, d in bp.items()}, {p: d["gap_s"] for p, d in bp.items()},
        before_fraction_by_priority={p: d["margin_fraction"] for p, d in bp.items()
                                     if d["margin_fraction"] is not None},
        title=title)
