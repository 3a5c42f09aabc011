"""Bundle priority order: who reaches a region next (Nag et al. 2019, section 4; docs/design.md section 1).

An observation of a region at time t is sent to the satellites that will image that region next:
priority 1 = the satellite whose next access to the region (any of its GPs) begins first after t,
2 = the one after, and so on up to ``max_priority`` (15 in the study: its traffic files never hold a
priority above 15). A satellite already in access at t counts from t. Satellites with no access
to the region before the end of the windows' horizon are not destinations; the source is excluded.
Ties break by satellite name so the order is deterministic.

How we know it is right (tests/unit/test_orbit_isl.py): a hand-built set of windows with the
expected order, and on the paper scenario the brute-force check "every satellite's first window
start after t" sorted. :func:`priority_order` sorts the region table's arrays (by time, then the
name's rank) instead of a dict of every satellite: tests/unit/test_priority_order.py compares it with
the dict sort of :func:`next_access_s` (as first written) on random windows and sources.
"""

from __future__ import annotations

import numpy as np

from orbit_clock.access import AccessWindows

__all__ = ["next_access_s", "priority_order"]


def next_access_s(windows: AccessWindows, region, t_s: float) -> dict[str, float]:
    """Per satellite name, the time [s] its next access to ``region`` (name or index) starts
    (t_s if it is in access at t_s); satellites with none before the horizon end are absent.

    That is, per satellite, max(t_s, the earliest start among its windows over the region that end
    after t_s). Each region's windows are put once in a table (:func:`_region_table`: per satellite,
    its window ends in order and the earliest start of the windows ending at or after each), so a
    query costs O(satellites x windows per satellite over the region), not a pass over every window
    of the constellation (a query per observation: tests/unit/test_orbit_isl.py
    test_next_access_equals_the_definition_on_random_windows)."""
    r = windows.region_id(region)
    names, ends, min_start = _region_table(windows, r)
    if len(names) == 0:
        return {}
    k = np.sum(ends <= t_s, axis=1)  # per satellite: its windows that have ended by t_s
    first = min_start[np.arange(len(names)), k]
    ok = np.isfinite(first)
    return {names[i]: max(float(first[i]), float(t_s)) for i in np.flatnonzero(ok)}


def _region_table(windows: AccessWindows, r: int):
    """(satellite names, ends [n, K] ascending per row padded with +inf, earliest start of the
    windows from each column on [n, K + 1], +inf past the last) for the satellites with windows over
    region ``r``, in satellite index order; made once per (windows, region)."""
    cache = windows.__dict__.setdefault("_next_access_tables", {})
    tab = cache.get(r)
    if tab is None:
        m = windows.region == r
        sat, start, end = windows.sat[m], windows.start_s[m], windows.end_s[m]
        order = np.lexsort((end, sat))
        sat, start, end = sat[order], start[order], end[order]
        ids, first, counts = np.unique(sat, return_index=True, return_counts=True)
        K = int(counts.max(initial=0))
        ends = np.full((len(ids), K), np.inf)
        min_start = np.full((len(ids), K + 1), np.inf)
        for i, (f, c) in enumerate(zip(first, counts)):
            ends[i, :c] = end[f:f + c]
            min_start[i, :c] = np.minimum.accumulate(start[f:f + c][::-1])[::-1]
        tab = cache[r] = ([windows.sat_names[int(i)] for i in ids], ends, min_start)
    return tab


def _name_ranks(windows: AccessWindows, r: int) -> tuple[np.ndarray, dict[str, int]]:
    """Per row of :func:`_region_table`'s region ``r``: its satellite name's rank in string order;
    and name -> row."""
    cache = windows.__dict__.setdefault("_next_access_ranks", {})
    got = cache.get(r)
    if got is None:
        names = _region_table(windows, r)[0]
        rank = np.empty(len(names), np.int64)
        rank[sorted(range(len(names)), key=names.__getitem__)] = np.arange(len(names))
        got = cache[r] = (rank, {n: i for i, n in enumerate(names)})
    return got


def priority_order(windows: AccessWindows, region, t_s: float, *, source: str | None = None,
                   max_priority: int | None = 15) -> list[tuple[str, int]]:
    """[(sat_name, priority)] with priority 1 = next on scene over ``region`` after t_s [s].

    :func:`next_access_s`'s times sorted by (time, name), on the region table's arrays (a query per
    observation, each over every satellite of the constellation)."""
    r = windows.region_id(region)
    names, ends, min_start = _region_table(windows, r)
    if len(names) == 0:
        return []
    k = np.sum(ends <= t_s, axis=1)
    first = min_start[np.arange(len(names)), k]
    rank, row_of = _name_ranks(windows, r)
    ok = np.isfinite(first)
    if source in row_of:
        ok[row_of[source]] = False
    rows = np.flatnonzero(ok)
    when = np.maximum(first[rows], float(t_s))  # next_access_s's max(first, t_s)
    rows = rows[np.lexsort((rank[rows], when))]
    if max_priority is not None:
        rows = rows[:max_priority]
    return [(names[i], k + 1) for k, i in enumerate(rows.tolist())]
