"""priority_order on the region table's arrays orders the satellites as the dict sort did.

Oracle: priority_order as first written (kept here): next_access_s's dict without the source,
sorted by (time, name), cut at max_priority. Random windows (several per satellite, overlapping,
names out of index order so that the name breaks ties differently from the index), at window
edges and between them (ties of times at t: satellites in access), with and without a source
(one of the satellites, one with no window there, one not in the constellation), every
max_priority; and the paper scenario's windows.
"""

from __future__ import annotations

import numpy as np

from orbit_clock import access_windows, build_constellation, ground_points, next_access_s, priority_order
from orbit_clock.access import AccessWindows


def _as_first_written(windows, region, t_s, *, source=None, max_priority=15):
    nxt = next_access_s(windows, region, t_s)
    nxt.pop(source, None)
    order = sorted(nxt.items(), key=lambda kv: (kv[1], kv[0]))
    if max_priority is not None:
        order = order[:max_priority]
    return [(name, k + 1) for k, (name, _) in enumerate(order)]


def test_priority_order_equals_the_dict_sort_on_random_windows():
    rng = np.random.default_rng(17)
    compared = 0
    for _ in range(60):
        n_sat, n_gp, n_w = int(rng.integers(1, 30)), int(rng.integers(1, 6)), int(rng.integers(0, 80))
        names = [f"sat_{int(x)}" for x in rng.permutation(np.arange(100, 100 + n_sat))]
        start = rng.integers(0, 900, n_w).astype(float)
        w = AccessWindows(names, sat=rng.integers(0, n_sat, n_w), gp=rng.integers(0, n_gp, n_w), start_s=start,
                          end_s=start + rng.integers(1, 200, n_w), min_off_nadir_deg=np.zeros(n_w),
                          gp_region=rng.integers(0, 2, n_gp), region_names=["A", "B"])
        times = np.concatenate([w.start_s, w.end_s, rng.uniform(-10, 1200, 5)])
        for region in (0, "B"):
            for t in times[:20]:
                for source in (None, names[int(rng.integers(0, n_sat))], "sat_99"):
                    for mp in (None, 1, 3, 15):
                        got = priority_order(w, region, float(t), source=source, max_priority=mp)
                        assert got == _as_first_written(w, region, float(t), source=source, max_priority=mp)
                        compared += 1
    assert compared > 10000


def test_priority_order_equals_the_dict_sort_on_the_paper_windows(paper_scenario):
    c = build_constellation(paper_scenario)
    g = ground_points(paper_scenario)
    w = access_windows(c, g, 0.0, paper_scenario.scenario.horizon_s, 55.0)
    seen = 0
    for region in g.region_names:
        for t in np.linspace(0.0, paper_scenario.scenario.horizon_s, 40):
            for source in (None, "sat_21", c.names[-1]):
                got = priority_order(w, region, float(t), source=source)
                assert got == _as_first_written(w, region, float(t), source=source)
                seen += len(got)
    assert seen > 100
