"""The assumed-value error of a run's looks, reported three ways and split by the age of the information.

A look's assumed value is what its planner expected it to be worth (``Observation.assumed_value``);
its true value is Eq. 1 of the study over the run's executed looks (bringup/analysis/report.py
``true_values``). Over the looks with a true value ``r > 0`` and assumed value ``a``:

* ``mean`` - the mean of ``|a - r| / r`` (the report's ``value.assumed_error_mean``, unchanged);
* ``median`` - its median;
* ``sum_based`` - ``sum |a - r| / sum r``: the error per unit of true value, which the few looks
  with a small ``r`` (whose ratios dominate the mean) do not dominate;
* ``se`` - the standard error of the mean, ``sd(|a - r| / r) / sqrt(n)`` (sample sd), and ``n``.

Each again for two sets of looks (``same_slot``, ``other_slot``): a look whose information time
(``Observation.info_ns``, the newest information about its region its planner had) lies in the
look's own OSSE slot (``slot_s``, the field's time resolution), and one whose information is from an
earlier slot. The split separates the planner's inference noise from the field's change since the
information: the study reports ~4 % onboard, which is its 2-8 % belief noise, E|sigma z| =
0.798 x 5 % = 3.99 % (Nag et al., ICAPS SPARK 2019, section 5). Looks without an information time
are in neither set (``without_info_time`` counts them).

How we know it is right: tests/unit/test_assumed_error.py - hand-worked looks (mean, median,
sum-based, standard error, the slot split on both sides of a slot boundary); the check of the metric
itself, tests/system/test_gp_twin.py: under the ``region-truth`` knowledge model the same-slot onboard
error of first looks (no Eq. 1 count to get wrong) equals the belief noise of the satellites that
made them within three standard errors. A same-slot look at a GP seen before may also carry the
error of an Eq. 1 count its planner got wrong (it had not heard of the earlier look): the figure
here keeps those looks, as it keeps every look.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["assumed_error_figures", "error_summary"]

_NS = 1_000_000_000


def error_summary(assumed: np.ndarray, true: np.ndarray) -> dict:
    """``{"n", "mean", "median", "sum_based", "se"}`` of ``|a - r| / r`` over the pairs with ``r > 0``."""
    a = np.asarray(assumed, np.float64)
    r = np.asarray(true, np.float64)
    keep = r > 0
    a, r = a[keep], r[keep]
    n = int(r.size)
    if n == 0:
        return {"n": 0, "mean": None, "median": None, "sum_based": None, "se": None}
    e = np.abs(a - r) / r
    return {"n": n, "mean": float(np.mean(e)), "median": float(np.median(e)),
            "sum_based": float(np.abs(a - r).sum() / r.sum()),
            "se": float(np.std(e, ddof=1) / math.sqrt(n)) if n > 1 else None}


def assumed_error_figures(rows: list[tuple], slot_s: float, horizon_s: float) -> dict:
    """``value.assumed_error`` of report.json from ``rows`` = [(observation, true Eq. 1 value, dup)]
    (report.py ``true_values``); ``slot_s`` the OSSE slot, ``horizon_s`` the run's horizon (a time at
    or after the last slot's start belongs to the last slot, as ground_station/osse.py ``slot_of``)."""
    slot_ns = round(float(slot_s) * _NS)
    if slot_ns <= 0:
        raise ValueError(f"assumed_error_figures: slot_s must be > 0, got {slot_s}")
    last = max(0, math.ceil(float(horizon_s) / float(slot_s)) - 1)
    a = np.array([o.assumed_value for o, _v, _d in rows], np.float64)
    r = np.array([v for _o, v, _d in rows], np.float64)
    has = np.array([o.info_ns is not None for o, _v, _d in rows], bool)
    same = np.array([o.info_ns is not None and min(o.info_ns // slot_ns, last) == min(o.t_ns // slot_ns, last)
                     for o, _v, _d in rows], bool)
    out = error_summary(a, r)
    out["same_slot"] = error_summary(a[same], r[same])
    out["other_slot"] = error_summary(a[has & ~same], r[has & ~same])
    out["without_info_time"] = int((~has & (r > 0)).sum())
    out["slot_s"] = float(slot_s)
    return out
