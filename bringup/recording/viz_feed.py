"""Feeds the visualisation topics of a run into its bag at a modest rate.

``VizFeed(world, period_s)`` writes, every ``period_s`` of sim time (default: the scenario's
``[viz] period_s``), one NavSatFix per satellite, the constellation MarkerArray
(bringup/recording/viz_messages.py: satellite positions from SGP4, ground points coloured by their
OSSE value at that time, the ISL links open then, from the truth contact plan) and the TF tree on
``/tf`` (earth -> each satellite's orbit frame, bringup/recording/viz_frames.py); once, at its first
frame, the ground stations on ``/tf_static``. Both engines call it with the step times, so a bag
opened in Foxglove shows the constellation moving and the links coming and going. ``frame(t_ns,
stamp_ns)`` gives the same messages as (topic, msgtype, CDR) without a bag: the ROS engine's clock
publishes them live.

The ground-point marker (500 cubes coloured by value, most of a frame's bytes) goes out only when
its colours change (the OSSE field is piecewise constant, 15-min slots in the paper scenario) and at
least every ``gp_keyframe_s``: a marker with lifetime 0 stays shown until replaced
(visualization_msgs/Marker), so the picture is the same. Frames are written as CDR bytes directly
(bringup/recording/viz_messages.py ``viz_cdr``, byte-identical to rosbags' serialization,
tests/unit/test_viz_fast.py). The links open at a frame come from arrays of contact start/end times
(the same test as a scan of the contacts, in the same order; tests/unit/test_speed_paths.py), and
the marker's link list from the open contacts' satellite indices on arrays
(viz_messages.py ``link_ends_indexed``: ~100 000 links in view for 1000 satellites; the frames'
bytes equal those made from the name pairs, tests/unit/test_viz_fast.py).
"""

from __future__ import annotations

import numpy as np

from bringup.recording.viz_frames import TF_TYPE, satellite_tf, station_tf, tf_cdr
from bringup.recording.viz_messages import link_ends_indexed, name_ranks, viz_cdr
from msgs_json.topics import TF, TF_STATIC

__all__ = ["VizFeed"]

_NS = 1_000_000_000


class VizFeed:
    def __init__(self, world, period_s: float | None = None, gp_keyframe_s: float = 600.0):
        self.world = world
        if period_s is None:
            period_s = world.scenario.viz.period_s
        self.period_ns = int(round(period_s * _NS))
        self.gp_keyframe_ns = int(round(gp_keyframe_s * _NS))
        self._gp_vals: np.ndarray | None = None  # colours last sent, and when
        self._gp_ns = 0
        self.next_ns = 0
        self.written = 0
        self._contacts = sorted(world.isl_plan.contacts, key=lambda c: c.start_s)
        # the open-link test on arrays (the same comparisons as a scan of the contact list)
        self._starts = np.array([c.start_s for c in self._contacts], dtype=np.float64)
        self._ends = np.array([c.end_s for c in self._contacts], dtype=np.float64)
        self._pairs = [(c.src, c.dst) for c in self._contacts]
        # the same contacts' ends as satellite indices (None: a contact names another node, then
        # the frames take the name pairs, and the marker's check names it)
        names = getattr(world, "sat_names", None)
        idx = {n: i for i, n in enumerate(names or ())}
        self._ab = None
        if names is not None and all(a in idx and b in idx for a, b in self._pairs):
            self._ab = (np.array([idx[a] for a, _b in self._pairs], dtype=np.int64),
                        np.array([idx[b] for _a, b in self._pairs], dtype=np.int64))
            self._ranks = name_ranks(names)

    def _open_at(self, t_s: float) -> np.ndarray:
        return np.flatnonzero((self._starts <= t_s) & (t_s < self._ends))

    def links_at(self, t_s: float) -> list[tuple[str, str]]:
        """(src, dst) of the ISL contacts open at ``t_s`` (start <= t_s < end), by start time."""
        pairs = self._pairs
        return [pairs[i] for i in self._open_at(t_s).tolist()]

    def link_kw(self, t_s: float) -> dict:
        """The marker's links at ``t_s``: ``link_ends`` on arrays when every contact joins two
        satellites of the world, else ``links`` (name pairs)."""
        if self._ab is None:
            return {"links": self.links_at(t_s)}
        i = self._open_at(t_s)
        return {"link_ends": link_ends_indexed(*self._ranks, self._ab[0][i], self._ab[1][i])}

    def due(self, t_ns: int) -> bool:
        return t_ns >= self.next_ns

    def write(self, bag, t_ns: int) -> int:
        """Write the visualisation of instant ``t_ns`` if due, stamped with the bag's instant
        (``bag.epoch_ns + t_ns``); returns messages written."""
        msgs = self.frame(t_ns, getattr(bag, "epoch_ns", 0) + t_ns)
        for topic, msgtype, cdr in msgs:
            bag.write_raw(topic, msgtype, cdr, t_ns)
        return len(msgs)

    def frame(self, t_ns: int, stamp_ns: int) -> list[tuple[str, str, bytes]]:
        """The visualisation of instant ``t_ns`` if due (else []): (topic, msgtype, CDR) with header
        stamps ``stamp_ns`` (the UTC instant); the first frame also holds /tf_static."""
        if t_ns < self.next_ns:
            return []
        self.next_ns = (t_ns // self.period_ns + 1) * self.period_ns
        w = self.world
        t_s = t_ns / _NS
        r = w.sat_positions_ecef_km(t_s)
        links = self.link_kw(t_s)
        vals = w.osse.value_at(np.arange(w.n_gp), np.full(w.n_gp, min(t_s, w.osse.horizon_s - 1e-6)))
        if (self._gp_vals is None or t_ns - self._gp_ns >= self.gp_keyframe_ns
                or not np.array_equal(vals, self._gp_vals)):
            self._gp_vals, self._gp_ns = vals, t_ns
            gp = {"gp_ecef_km": w.gps.ecef_km, "gp_values": vals}
        else:
            gp = {}
        out = viz_cdr(w.sat_names, r, stamp_ns, **links, **gp)
        # the orbit frames' velocity: central difference of the Earth-fixed track over 1 s
        ahead, behind = w.sat_positions_ecef_km(t_s + 0.5), w.sat_positions_ecef_km(t_s - 0.5)
        out.append((TF, TF_TYPE, tf_cdr(satellite_tf(w.sat_names, r, ahead - behind, stamp_ns))))
        if self.written == 0:
            stations = w.scenario.ground.stations
            if stations:
                out.append((TF_STATIC, TF_TYPE, tf_cdr(station_tf(stations, stamp_ns))))
        self.written += len(out)
        return out
