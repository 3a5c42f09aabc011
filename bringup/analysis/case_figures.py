"""Which case a run is: the field's time scales, the ground network, the look cadence (report.json).

The study's case is told by figures, not by a word, so every report carries them:

* osse.osse_resolution_min - the OSSE's time resolution (the study's "transiency": the value slot
  and Eq. 1's zero window); osse.decorrelation_min - the transient field's decorrelation, measured
  on its drawing step; osse.flash_floods - whether the field has its flash floods
  (ground_station/osse_sources.py).
* osse.rel_change_at_info_age.{mean,median} - the field's relative change of GP values
  (ground_station/osse_stats.py relative_change_by_lag) read at ``info_age_s`` = the run's
  knowledge.info_age_s.median: what a planner that knows each GP as of its median information age
  would err by, to set beside value.assumed_error_* (a centralized run's age is the ground's).
* ground.passes, ground.passes_per_orbit, ground.orbit_period_s, ground.stations - the ground
  network's passes (orbit_clock/ground_passes.py pass_figures; the study assumed two an orbit);
  ground.uplinks, ground.uplinks_per_orbit - the uplinks the run sent after its start (centralized
  mode; None without any), per satellite and orbit.
* looks.in_pass_interval_s - the interval from each look to the same satellite's next under 60 s:
  histogram in whole seconds, mode, its share, median (bringup/analysis/cadence.py; the study's
  traffic files: 9 s).

How we know it is right: tests/unit/test_ground_network.py (passes and uplinks per orbit of the
paper scenario, 2 +- 0.3; the cadence against the study's traffic files; pass_figures on a hand-made
plan), tests/unit/test_osse_resolution.py (the relative change against brute force).
"""

from __future__ import annotations

import math
from collections import defaultdict

import numpy as np

from bringup.analysis.cadence import cadence_figures
from ground_station.osse_stats import relative_change_at
from orbit_clock.ground_passes import orbit_period_s, pass_figures

__all__ = ["case_figures", "ground_meta"]

_NS = 1_000_000_000


def _mean_period_s(world) -> float:
    """The constellation's orbital period [s]: the Walker shell's circular orbit, or for a fleet with
    catalogue satellites the mean of their SGP4 mean motions (``no_kozai`` [rad/min])."""
    walker = world.scenario.walker
    if walker is not None and not isinstance(world.scenario.constellation, list):
        return orbit_period_s(walker.altitude_km)
    return float(np.mean([2.0 * math.pi / r.no_kozai * 60.0 for r in world.constellation.satrecs]))


def ground_meta(world) -> dict:
    """The ground network's pass figures of a run of ``world`` (for the run's metadata)."""
    sc = world.scenario
    out = pass_figures(world.ground_plan, world.sat_names, sc.scenario.horizon_s, _mean_period_s(world))
    out["stations"] = [s.name for s in sc.ground.stations]
    return out


def case_figures(obs: list, meta, uplinks: list[tuple[str, int]], info_age_s: float | None) -> dict:
    """``{"osse", "ground", "looks"}`` of a run: its observations, its metadata (RunMeta: the field
    and ground figures, n_sats, horizon_s), the (satellite, t_ns) of its uplinks, its median
    information age [s]."""
    n_sats, horizon_s = meta.n_sats, meta.horizon_s
    o = dict(meta.osse or {})
    curve = o.pop("rel_change_by_slot_lag", None)
    res = o.get("osse_resolution_min")
    if curve and res:
        o["rel_change_at_info_age"] = {
            "info_age_s": info_age_s,
            "mean": relative_change_at(curve["mean"], 60.0 * res, info_age_s),
            "median": relative_change_at(curve["median"], 60.0 * res, info_age_s)}
    g = dict(meta.ground or {})
    period = g.get("orbit_period_s")
    later = sum(1 for _sat, t in uplinks if t > 0)
    g["uplinks"] = later
    orbits = n_sats * horizon_s / period if period else None
    g["uplinks_per_orbit"] = (later / orbits) if orbits and uplinks else None
    by_sat: dict[str, list[float]] = defaultdict(list)
    for x in obs:
        by_sat[x.sat].append(x.t_ns / _NS)
    return {"osse": o, "ground": g, "looks": {"in_pass_interval_s": cadence_figures(by_sat)}}
