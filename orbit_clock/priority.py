"""Bundle priority order: who reaches a region next (Nag et al. 2019, section 4; DESIGN.md section 1).

An observation of a region at time t is sent to the satellites that will image that region next:
priority 1 = the satellite whose next access to the region (any of its GPs) begins first after t,
2 = the one after, and so on up to ``max_priority`` (15 in the study: its traffic files never hold a
priority above 15). A satellite already in access at t counts from t. Satellites with no access
to the region before the end of the windows' horizon are not destinations; the source is excluded.
Ties break by satellite name so the order is deterministic.

How we know it is right (tests/unit/test_orbit_isl.py): a hand-built set of windows with the
expected order, and on the paper scenario the brute-force check "every satellite's first window
start after t" sorted.
"""

from __future__ import annotations

import numpy as np

from orbit_clock.access import AccessWindows

__all__ = ["next_access_s", "priority_order"]


def next_access_s(windows: AccessWindows, region, t_s: float) -> dict[str, float]:
    """Per satellite name, the time [s] its next access to ``region`` (name or index) starts
    (t_s if it is in access at t_s); satellites with none before the horizon end are absent."""
    r = windows.region_id(region)
    m = (windows.region == r) & (windows.end_s > t_s)
    if not np.any(m):
        return {}
    sat = windows.sat[m]
    start = np.maximum(windows.start_s[m], t_s)
    best = np.full(len(windows.sat_names), np.inf)
    np.minimum.at(best, sat, start)
    return {windows.sat_names[i]: float(best[i]) for i in np.flatnonzero(np.isfinite(best))}


def priority_order(windows: AccessWindows, region, t_s: float, *, source: str | None = None,
                   max_priority: int | None = 15) -> list[tuple[str, int]]:
    """[(sat_name, priority)] with priority 1 = next on scene over ``region`` after t_s [s]."""
    nxt = next_access_s(windows, region, t_s)
    nxt.pop(source, None)
    order = sorted(nxt.items(), key=lambda kv: (kv[1], kv[0]))
    if max_priority is not None:
        order = order[:max_priority]
    return [(name, k + 1) for k, (name, _) in enumerate(order)]
