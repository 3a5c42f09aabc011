"""How much work a run will be, estimated before its world is built; past the limits refused unless ``--force``.

Memory has its estimate (bringup/scenario/limits.py); CPU needs one too: ``--sats 1000 --planes 1
--hours 0.001`` fits in memory, but its 1000 satellites in one ring all see each other (136 thousand
ISL links at once), each satellite's router and CGR (sat_node/dtn) work over every one of them, and
the run did not finish 3.6 s of sim time in 300 s. Nothing said so before the world was built.

The figures (:func:`estimate_work`, from the scenario alone, in well under a second):

* **ISL links in view**: the satellite pairs within ``isl.max_range_km`` with line of sight
  (orbit_clock/isl.py ``los_clear``), counted at 4 instants over the first orbit (or the horizon
  if shorter) from the SGP4 positions (a k-d tree finds the pairs in range); the contact plan holds
  at least twice that many directed contacts, and every satellite's CGR searches over them;
* **satellite pairs**: N (N - 1) / 2, what the ISL search samples;
* **DP work**: plans (N satellites x horizon / ``scheduler.replan_period_s``) x DP steps
  (``plan_lookahead_s / dp_step_s``) x candidate GPs (twice the largest region's, as limits.py):
  the planners' cells.

:func:`check_work` refuses (one line, naming the figure, its limit and what drives it) a run over
:data:`LINKS_LIMIT` links in view or :data:`DP_CELLS_LIMIT` DP cells, unless ``force``; the CLI
prints the figures before it builds the world either way. The limits sit well above the largest
runs the project measures (bench/bench_scale.py: 480 satellites in 3 planes, 21.6 thousand links in
view), so they stop typos and impossible requests, not large studies; ``--force`` goes past them.

How we know it is right: tests/faults/test_impossible_inputs.py (the issue's 1000 satellites in one
plane refused in under a second before the world is built, and run with ``--force`` as far as the
world's first stage; the link count against a brute force over every pair with ``los_clear``).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import cKDTree

from bringup.scenario.config import Scenario, ScenarioError
from bringup.scenario.limits import _gps_per_region
from orbit_clock.isl import los_clear
from orbit_clock.propagation import build_constellation

__all__ = ["DP_CELLS_LIMIT", "LINKS_LIMIT", "check_work", "estimate_work", "links_in_view"]

LINKS_LIMIT = 50_000
DP_CELLS_LIMIT = 2e11
_SAMPLES = 4
_ORBIT_S = 6000.0  # longer than a LEO orbit (the paper's: 95 min)


def links_in_view(sc: Scenario, times_s: np.ndarray | None = None) -> float:
    """Mean number of satellite pairs with an ISL (in range, line of sight) at ``times_s``
    (default: :data:`_SAMPLES` instants over the first orbit or the horizon)."""
    if times_s is None:
        times_s = np.linspace(0.0, min(sc.scenario.horizon_s, _ORBIT_S), _SAMPLES)
    c = build_constellation(sc)
    r = c.states_ecef(times_s)[0]
    counts = []
    for k in range(len(times_s)):
        p = r[:, k, :]
        pairs = cKDTree(p).query_pairs(sc.isl.max_range_km, output_type="ndarray")
        n = int(los_clear(p[pairs[:, 0]], p[pairs[:, 1]], sc.isl.grazing_height_km).sum()) if len(pairs) else 0
        counts.append(n)
    return float(np.mean(counts))


def estimate_work(sc: Scenario) -> dict[str, float]:
    """{links_in_view, satellite_pairs, plans, dp_cells} (module docstring)."""
    n = sc.n_sats
    horizon = sc.scenario.horizon_s
    s = sc.scheduler
    plans = n * max(1.0, math.ceil(horizon / s.replan_period_s))
    per_region = _gps_per_region(sc)
    reach = min(sum(per_region), 2.0 * max(per_region))
    dp_steps = s.plan_lookahead_s / s.dp_step_s + 1
    return {"links_in_view": links_in_view(sc) if n > 1 else 0.0, "satellite_pairs": n * (n - 1) / 2,
            "plans": plans, "dp_cells": plans * dp_steps * reach}


def describe(w: dict[str, float]) -> str:
    """One phrase of the figures."""
    return (f"~{w['links_in_view']:,.0f} ISL links in view at once (>= {2 * w['links_in_view']:,.0f} directed "
            f"contacts), {w['satellite_pairs']:,.0f} satellite pairs, {w['plans']:,.0f} plans x DP = "
            f"{w['dp_cells']:.3g} DP cells")


def check_work(sc: Scenario, *, force: bool = False) -> dict[str, float]:
    """The estimate; ScenarioError (one line) when over a limit and not ``force``."""
    w = estimate_work(sc)
    if force:
        return w
    where = sc.source_path or sc.name
    planes = getattr(sc.constellation, "planes", None)
    fleet = f"{sc.n_sats} satellites" + (f" in {planes} plane(s)" if planes else "")
    if w["links_in_view"] > LINKS_LIMIT:
        raise ScenarioError(f"{where}: {fleet} keep ~{w['links_in_view']:,.0f} "
                            f"ISL links in view at once (isl.max_range_km {sc.isl.max_range_km:g}), over the "
                            f"{LINKS_LIMIT:,} limit (every satellite's CGR works over all of them; the largest "
                            "runs measured keep ~22,000): use more planes or fewer satellites, or --force")
    if w["dp_cells"] > DP_CELLS_LIMIT:
        raise ScenarioError(f"{where}: the planners would fill {w['dp_cells']:.3g} DP cells ({w['plans']:,.0f} plans "
                            f"x scheduler.plan_lookahead_s / scheduler.dp_step_s x candidate GPs), over the "
                            f"{DP_CELLS_LIMIT:.3g} limit; use a coarser dp_step_s or a shorter horizon, or --force")
    return w
