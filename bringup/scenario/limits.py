"""How much memory a scenario will take, estimated before anything is allocated; too much is refused.

A scenario's sizes multiply: ground points = sum over regions of (size_km / gp_spacing_km)^2; OSSE
slots = horizon_s / slot_s; orbit samples = horizon_s / 10 s per satellite; a planner instance has
plan_lookahead_s / dp_step_s steps by its candidate GPs. A typo (gp_spacing_km = 1e-3, horizon_s =
1e12, dp_step_s = 1e-6) turns them into tens of GiB to TiB, and numpy then either fails deep inside
a computation or the machine swaps until the kernel kills the run. :func:`estimate_bytes` adds up
the largest arrays each stage holds, in the process that holds them all (the local engine:
the world, one belief per satellite, one planner instance at a time), from the scenario alone, and
:func:`check_run_size` refuses a scenario whose estimate exceeds :func:`memory_budget_bytes` with one
line giving the estimate, its largest parts and the key that drives them.

The terms (bytes; each names the module whose arrays it counts):

* ground points (orbit_clock/ground_points.py): ~200 per GP (coordinates, indices, ECEF and the
  region filters' copies);
* OSSE field (ground_station/osse.py): int16 values per GP and slot, plus the float64 working
  arrays of the largest region while it is drawn (x3);
* beliefs (sat_node/value.py Belief): one float64 noise value per GP and slot, per satellite and for
  the ground segment;
* orbit samples (orbit_clock/propagation.py, isl.py, ground_passes.py): positions every 10 s per
  satellite, x4 for the temporaries of the searches;
* ISL search (orbit_clock/isl.py): 8 bytes per satellite pair per 10 s sample - measured (peak
  resident memory of ``isl_contact_plan`` alone, 2 cores, 2026-11-25): 240 satellites 6 h 581 MiB
  (estimate 473), 1000 satellites 1 h 1318 MiB (1372), 3 h 3840 MiB (4116); it grows with the
  contacts found (1.2 million for 1000 satellites over 3 h), so 1000 satellites over 24 h (~32 GiB)
  do not fit a 24 GiB machine;
* access search (orbit_clock/access.py): float64 angles per satellite, region and 20 s sample (x3);
* planner instance (sat_node/scheduler/problem.py, dp.py): ~48 per DP step and candidate GP
  (values, masks, prior counts, DP tables); the candidates are the GPs of the regions in reach over
  the lookahead, counted as twice the largest region (at most all GPs);
* the program itself: 0.25 GiB (Python, numpy, numba's kernels, rclpy; measured ~0.2 GiB peak
  for a 6-satellite, 1 h local run).

The budget is 80 % of the machine's physical memory (``os.sysconf``), or ``AGILE_DTN_MEMORY_GIB``
when set (a container's limit, a shared machine).

Time too: ROS time (``builtin_interfaces/Time``, what /clock and the bag's clock carry) holds its
seconds in an int32, and the bag's log times are unsigned ns since 1970, so a run's instants -
the epoch and the epoch plus the horizon - must lie in 1970-01-01T00:00:00Z ..
2038-01-19T03:14:07Z; :func:`check_time_range` (called by :func:`check_run_size` after the memory estimate) refuses
others in one line naming ``scenario.epoch_utc`` and the horizon, before anything is built (an
epoch in 2040 used to simulate the whole run, then fail in the recorder).

How we know it is right: tests/faults/test_impossible_inputs.py (a 2040 epoch, a 1969 epoch, an
epoch whose horizon crosses 2038, refused in one line before the world is built), tests/unit/test_limits.py measures the peak resident memory of building a
world and a planner instance for several scenarios (``resource.getrusage``, in a fresh process) and
checks the estimate lies within [0.5x, 4x] of it, and the estimate's terms against a direct count of
the arrays; tests/faults/test_hostile_inputs.py refuses the issue's inputs (gp_spacing_km = 1e-3,
horizon_s = 1e12, dp_step_s = 1e-6) in under a second, naming the estimate.
"""

from __future__ import annotations

import math
import os

from bringup.scenario.config import Scenario, ScenarioError

__all__ = ["ROS_TIME_MAX_S", "check_run_size", "check_time_range", "estimate_bytes", "gib",
           "memory_budget_bytes"]

_ORBIT_STEP_S = 10.0  # the ISL and ground-pass searches' grid (orbit_clock/isl.py, ground_passes.py)
_ACCESS_STEP_S = 20.0  # the access search's coarse grid (orbit_clock/access.py)
_BUDGET_FRACTION = 0.8
ENV_BUDGET = "AGILE_DTN_MEMORY_GIB"
ROS_TIME_MAX_S = 2**31 - 1  # builtin_interfaces/Time.sec is an int32: 2038-01-19T03:14:07Z


def check_time_range(sc: Scenario) -> None:
    """ScenarioError (one line) unless the epoch and the epoch plus the horizon lie in what ROS time
    and the bag hold (module docstring)."""
    where = sc.source_path or sc.name
    epoch_s = sc.epoch_ns / 1e9
    horizon = sc.scenario.horizon_s
    if epoch_s < 0:
        raise ScenarioError(f"{where}: key 'scenario.epoch_utc': {sc.epoch_iso} is before 1970-01-01T00:00:00Z; "
                            "the bag's times are unsigned nanoseconds since 1970")
    if epoch_s + horizon > ROS_TIME_MAX_S:
        what = ("is" if epoch_s > ROS_TIME_MAX_S else
                f"plus the horizon ({horizon:g} s, scenario.horizon_s / --hours) ends")
        raise ScenarioError(f"{where}: key 'scenario.epoch_utc': {sc.epoch_iso} {what} after "
                            "2038-01-19T03:14:07Z, the last instant ROS time holds (builtin_interfaces/Time.sec "
                            "is an int32); choose an earlier epoch")


def gib(n: float) -> str:
    """Bytes as a short human figure: '47.7 GiB', '512 MiB', '1.2e+06 TiB'."""
    for unit, k in (("TiB", 2 ** 40), ("GiB", 2 ** 30), ("MiB", 2 ** 20)):
        if n >= k:
            x = n / k
            return f"{x:.3g} {unit}" if x < 1e6 else f"{x:.2e} {unit}"
    return f"{n / 2 ** 10:.3g} KiB"


def _gps_per_region(sc: Scenario) -> list[float]:
    """max(1, round(size_km / spacing))^2 per square region (orbit_clock/ground_points.py region_grid),
    area / spacing^2 per drawn shape, as floats: a spacing near 0 gives inf, not an OverflowError."""
    spacing = sc.gp_spacing_km
    out = []
    for r in sc.regions.list:
        shape = r.shape_deg
        if shape is not None:  # a drawn shape: its equal-area area over the GP cell's (region_shapes.py)
            from orbit_clock.region_shapes import shape_area_km2

            out.append(max(1.0, shape_area_km2(shape) / spacing / spacing))
            continue
        n = r.size_km / spacing
        side = max(1.0, float(round(n))) if math.isfinite(n) else math.inf
        out.append(side * side)  # (float ** 2 raises OverflowError past 1e308; * gives inf)
    return out


def estimate_bytes(sc: Scenario) -> dict[str, tuple[float, str]]:
    """The estimate's terms: {what: (bytes, what drives it)} (module docstring)."""
    per_region = _gps_per_region(sc)
    n_gp = sum(per_region)
    horizon = sc.scenario.horizon_s
    n_slots = max(1, math.ceil(horizon / sc.value.slot_s - 1e-9))  # (ground_station/osse.py)
    n_sats = sc.n_sats
    n_orbit = horizon / _ORBIT_STEP_S + 1
    n_access = horizon / _ACCESS_STEP_S + 1
    dp_steps = sc.scheduler.plan_lookahead_s / sc.scheduler.dp_step_s + 1
    pairs = n_sats * (n_sats - 1) / 2
    gp_txt = f"{n_gp:.3g} ground points (regions.gp_spacing_km {sc.gp_spacing_km:g})"
    reach = min(n_gp, 2.0 * max(per_region))
    return {
        "the program": (0.25 * 2 ** 30, "Python, numpy, numba, rclpy"),
        "ground points": (200.0 * n_gp, gp_txt),
        "OSSE field": (2.0 * n_gp * n_slots + 24.0 * max(per_region) * n_slots,
                       f"{gp_txt} x {n_slots:.3g} slots (scenario.horizon_s / value.slot_s)"),
        "beliefs": (8.0 * n_gp * n_slots * (n_sats + 1),
                    f"{n_sats + 1} x {gp_txt} x {n_slots:.3g} slots"),
        "orbit samples": (96.0 * n_sats * n_orbit,
                          f"{n_sats} satellites x {n_orbit:.3g} samples (scenario.horizon_s {horizon:g} s)"),
        "ISL search": (8.0 * pairs * n_orbit, f"{pairs:.3g} satellite pairs x {n_orbit:.3g} samples"),
        "access search": (24.0 * n_sats * len(per_region) * n_access,
                          f"{n_sats} satellites x {len(per_region)} regions x {n_access:.3g} samples"),
        "planner instance": (48.0 * dp_steps * reach,
                             f"{dp_steps:.3g} DP steps (scheduler.plan_lookahead_s / scheduler.dp_step_s "
                             f"{sc.scheduler.dp_step_s:g}) x {reach:.3g} candidate GPs "
                             f"(regions.gp_spacing_km {sc.gp_spacing_km:g})"),
    }


def memory_budget_bytes() -> float:
    """80 % of physical memory, or ``AGILE_DTN_MEMORY_GIB`` GiB."""
    env = os.environ.get(ENV_BUDGET)
    if env:
        try:
            v = float(env)
        except ValueError:
            v = float("nan")
        if not (math.isfinite(v) and v > 0):
            raise ScenarioError(f"${ENV_BUDGET} = {env!r}: must be a positive number of GiB")
        return v * 2 ** 30
    try:
        phys = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError):
        return float("inf")
    return _BUDGET_FRACTION * phys


def check_run_size(sc: Scenario, budget: float | None = None) -> float:
    """The estimate (bytes); ScenarioError naming it and its largest parts when over ``budget``
    (default :func:`memory_budget_bytes`); then the time range (:func:`check_time_range`)."""
    terms = estimate_bytes(sc)
    total = sum(b for b, _ in terms.values())
    limit = memory_budget_bytes() if budget is None else budget
    if not total <= limit:
        top = sorted(terms.items(), key=lambda kv: -kv[1][0])[:2]
        parts = "; ".join(f"{k} {gib(b)}: {why}" for k, (b, why) in top
                          if b >= 0.01 * total or b == math.inf)
        src = os.environ.get(ENV_BUDGET) and f"${ENV_BUDGET}" or f"{_BUDGET_FRACTION:.0%} of this machine's memory"
        raise ScenarioError(f"{sc.source_path or sc.name}: the run would need about {gib(total)} of memory, "
                            f"over the {gib(limit)} budget ({src}): {parts}")
    check_time_range(sc)
    return total
