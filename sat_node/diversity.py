"""The optional spatial-diversity term of a planner's value (``value.spatial_diversity_weight``).

Nag et al. (ICAPS SPARK 2019) value an observation by Eq. 1 alone in their results and name a
spatial-diversity term - more value for observing GPs far from those observed recently - as an
option without a formula precise enough to implement, as this project reads the study. This module
is the project's reading of it, off by default (weight 0) and a switch for sensitivity runs:

    absval'(g) = absval(g) * (1 + w * (1 - exp(-d(g) / L)))

``d(g)``: the straight-line distance [km] from GP ``g`` to the nearest GP the planner knows was
observed (executed, by anyone it heard of) within ``window`` before the plan's start (infinite when
none was: every GP then gets the same factor 1 + w, and the plan is Eq. 1's); ``w``:
``value.spatial_diversity_weight``; ``L``: ``value.spatial_diversity_km``; ``window``:
``value.spatial_diversity_window_min``. A GP next to a recent look keeps its Eq. 1 value, one
several ``L`` away gains up to the factor 1 + w. The term shapes what a planner chooses only: the
report scores every run by Eq. 1 (bringup/analysis/report.py), so runs with and without it compare
on the same value.

How we know it is right (tests/unit/test_diversity.py): the factor of hand-placed GPs worked out by
hand; a plan with weight 0 equals the plan without the term; with a weight, of two GPs of equal value
the planner takes the one far from a recent look where without it takes the near one.
"""

from __future__ import annotations

import numpy as np

__all__ = ["diversity_factor", "recent_observed_gps"]


def diversity_factor(gp_km: np.ndarray, recent_km: np.ndarray, weight: float, length_km: float) -> np.ndarray:
    """``1 + weight * (1 - exp(-d / length_km))`` per GP of ``gp_km`` [G, 3], ``d`` the distance to
    the nearest of ``recent_km`` [R, 3] (all ``1 + weight`` when R = 0)."""
    gp = np.asarray(gp_km, dtype=np.float64).reshape(-1, 3)
    rec = np.asarray(recent_km, dtype=np.float64).reshape(-1, 3)
    if not (weight >= 0 and length_km > 0):
        raise ValueError(f"spatial diversity: weight must be >= 0 and length > 0 km, got {weight}, {length_km}")
    if rec.shape[0] == 0:
        return np.full(gp.shape[0], 1.0 + weight)
    d = np.sqrt(((gp[:, None, :] - rec[None, :, :]) ** 2).sum(axis=2)).min(axis=1)
    return 1.0 + weight * (1.0 - np.exp(-d / length_km))


def recent_observed_gps(known, t0_s: float, window_s: float) -> np.ndarray:
    """The GPs of executed observations in ``known`` at times in [t0_s - window_s, t0_s]."""
    gps = {int(k.gp) for k in known if not k.planned and t0_s - window_s <= k.t_s <= t0_s}
    return np.array(sorted(gps), dtype=np.int64)
