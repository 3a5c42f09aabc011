"""The satellite's numba kernels, compiled or loaded from numba's cache before their first real use.

The DP scheduler's inner loop (:mod:`sat_node.scheduler.dp_kernels`), the field-of-regard test its
instances are built with (:mod:`orbit_clock.access_kernels`) and contact graph routing
(:mod:`sat_node.dtn.cgr`) are ``numba.njit(cache=True)`` functions: the first call in a process
compiles them (seconds of CPU: ~3 s for the DP on this project's 2-core machine) unless numba's
on-disk cache holds them (``__pycache__`` beside the sources, or ``NUMBA_CACHE_DIR``); then it loads
them (~0.1 s). A process that must answer within a deadline (a satellite stepped by the lockstep
clock of a ROS run, bringup/engine/ros/clock_node.py) calls :func:`warm_up` before it says it is
ready, and the launcher runs it once before it starts the satellites, so that 24 processes load the
kernels from the cache instead of all compiling them at once. ``python -m sat_node.kernels`` does the
same once for the checkout (scripts/setup.sh starts it in the background while the rest installs):
the cache it fills is the one every later run of this checkout loads from, and it prints the time.

:func:`warm_up` runs each kernel through its ordinary caller (``solve_dp`` - a joint branch's
too - ``for_mask`` and ``prior_state`` on a two-step, two-GP instance, the observed view's kernel
exponent and innovation grid on the types its view passes, a joint group's value on arrays; a CGR
route and a one-to-all query on a three-contact plan), so it compiles exactly the
argument types a run uses. How we know it is right: tests/unit/test_kernels_warm_up.py (after
``warm_up``, a paper run on the local engine adds no signature to any kernel; a second process with
the same cache finds every kernel there: cache hits, no misses).
"""

from __future__ import annotations

import time

import numpy as np

from orbit_clock import access_kernels
from orbit_clock.access import for_mask
from orbit_clock.contact_plan import Contact, ContactPlan
from sat_node import knowledge_kernels, value_kernels
from sat_node.acs import SlewModel
from sat_node.dtn import cgr
from sat_node.dtn.cgr import ContactGraph
from sat_node.scheduler import build_problem, dp_kernels, joint_kernels, solve_dp
from sat_node.scheduler.dp import make_plan
from sat_node.scheduler.joint import with_forbidden
from sat_node.scheduler.joint_kernels import group_value
from sat_node.value import KnownObservation, prior_state

__all__ = ["KERNELS", "dispatchers", "warm_up"]

# name -> the kernels it warms ((module, function names), ...), for the stats and the tests; the
# planner's group holds the DP and the field-of-regard test and prior-state runs its instances are built with
KERNELS = {
    "dp": ((dp_kernels, ("dp_forward", "dp_states", "path_gain", "table_gain", "bit_gain", "plan_values",
                         "states_without")), (access_kernels, ("for_codes",)),
           (value_kernels, ("prior_runs",)), (knowledge_kernels, ("kernel_exponent", "innovation_grid")),
           (joint_kernels, ("joint_total",))),
    "cgr": ((cgr, ("_dijkstra", "_first_open", "_node_dominated", "_node_label")),),
}


def dispatchers(which=tuple(KERNELS)) -> dict[str, object]:
    """``{"module.function": numba dispatcher}`` of the kernels named in ``which``."""
    out = {}
    for name in which:
        for mod, fns in KERNELS[name]:
            for fn in fns:
                out[f"{mod.__name__}.{fn}"] = getattr(mod, fn)
    return out


def _dp() -> None:
    r = 6378.137 + 700.0
    sat = np.array([[r, 0.0, 0.0], [r, 0.0, 50.0]])
    gp = np.array([[6378.137, 0.0, 0.0], [6378.137, 0.0, 30.0]])
    p = build_problem(t0_s=0.0, step_s=10.0, sat_pos_km=sat, gp_ecef_km=gp, in_for=np.ones((2, 2), bool),
                      absval=np.array([1.0, 2.0]), slew=SlewModel((0.0, 0.0, 0.1, 1.0), 0.0), revisit_zero_s=900.0)
    solve_dp(p, check=True)  # path bitsets (the window is within the revisit window)
    solve_dp(p, check=True, bit_words=0)  # path tables (same signature)
    solve_dp(p, check=True, table_cells=0, bit_words=0)  # the branch that walks back-pointers
    solve_dp(with_forbidden(p, [1]), check=True)  # a joint branch: states copied from p's (states_without)
    for_mask(sat, gp, 55.0)  # the compiled field-of-regard test (both GPs within its bound)
    prior_state([KnownObservation(5.0, 1, "sat_12")], np.array([0, 1]), np.array([0.0, 10.0]), "sat_11", 900.0)
    # the observed view's kernel sums (sat_node/knowledge.py ObservedView._ref: contiguous float64 arrays)
    knowledge_kernels.kernel_exponent(gp, np.ascontiguousarray(gp[:1]), np.array([5.0]), 10.0, 100.0, 1298.4)
    knowledge_kernels.innovation_grid(np.ones(2), np.zeros(2), np.zeros(2), np.zeros((1, 2)),
                                      np.zeros(2, np.int64), 5.5)
    one = make_plan(p, [0], [0])
    group_value([p, p], [one, one], array_looks=0)  # a joint group's value on arrays (its compiled sum)


def _cgr() -> None:
    g = ContactGraph(ContactPlan([Contact(0.0, 100.0, "sat_11", "sat_12", 1000.0, 0.01),
                                  Contact(50.0, 150.0, "sat_12", "sat_13", 1000.0, 0.01),
                                  Contact(0.0, 10.0, "sat_11", "sat_13", 1000.0, 0.01)]))
    g.route("sat_11", "sat_13", 20.0, 2000.0, excluded=np.zeros(len(g.contacts), dtype=np.bool_),
            excluded_nodes=("sat_12",), first_backlog_bits=g._no_backlog.copy())
    g.route("sat_11", "sat_13", 20.0, 2000.0)
    g.earliest_arrivals("sat_11", 0.0, 2000.0)


_WARM = {"dp": _dp, "cgr": _cgr}


def warm_up(which=tuple(KERNELS)) -> dict[str, float]:
    """Compile (empty cache) or load (warm cache) the kernels named in ``which`` ("dp", "cgr") in
    this process; returns the wall seconds each took."""
    took = {}
    for name in which:
        if name not in _WARM:
            raise ValueError(f"warm_up: unknown kernel group {name!r} (known: {', '.join(_WARM)})")
        t0 = time.perf_counter()
        _WARM[name]()
        took[name] = time.perf_counter() - t0
    return took


if __name__ == "__main__":
    t0 = time.perf_counter()
    took = warm_up()
    print("numba kernels ready in {:.1f} s ({}): compiled into numba's cache, or loaded from it".format(
        time.perf_counter() - t0, ", ".join(f"{k} {v:.1f} s" for k, v in took.items())), flush=True)
