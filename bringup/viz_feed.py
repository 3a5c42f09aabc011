"""Feeds the visualisation topics of a run into its bag at a modest rate (issue 5).

``VizFeed(world, period_s)`` writes, every ``period_s`` of sim time, one NavSatFix per satellite and
the constellation MarkerArray (bringup/viz.py): satellite positions from SGP4, ground points
coloured by their OSSE value at that time, and the ISL links open then (truth contact plan). Both
engines call it with the step times, so a bag opened in Foxglove shows the constellation moving and
the links coming and going.
"""

from __future__ import annotations

import numpy as np

__all__ = ["VizFeed"]

_NS = 1_000_000_000


class VizFeed:
    def __init__(self, world, period_s: float = 60.0):
        self.world = world
        self.period_ns = int(round(period_s * _NS))
        self.next_ns = 0
        self.written = 0
        self._contacts = sorted(world.isl_plan.contacts, key=lambda c: c.start_s)

    def due(self, t_ns: int) -> bool:
        return t_ns >= self.next_ns

    def write(self, bag, t_ns: int) -> int:
        """Write the visualisation of instant ``t_ns`` if due; returns messages written."""
        from bringup.viz import write_viz

        if t_ns < self.next_ns:
            return 0
        self.next_ns = (t_ns // self.period_ns + 1) * self.period_ns
        w = self.world
        t_s = t_ns / _NS
        r = w.sat_positions_ecef_km(t_s)
        links = [(c.src, c.dst) for c in self._contacts if c.start_s <= t_s < c.end_s]
        vals = w.osse.value_at(np.arange(w.n_gp), np.full(w.n_gp, min(t_s, w.osse.horizon_s - 1e-6)))
        n = write_viz(bag, w.sat_names, r, t_ns, gp_ecef_km=w.gps.ecef_km, gp_values=vals, links=links)
        self.written += n
        return n
