"""Summaries of a figure over seeds: mean, sample standard deviation and a 95 % confidence interval.

Every figure the project reports over several seeds (``compare``, ``sweep``) goes through
:func:`summarize`, so all of them are labelled alike:

* ``mean`` - the arithmetic mean of the finite values;
* ``sd`` - the *sample* standard deviation (n - 1 in the denominator, Bessel's correction), ``None``
  for fewer than two values;
* ``ci95`` - ``[low, high]``, the two-sided 95 % confidence interval of the mean from Student's t with
  n - 1 degrees of freedom: ``mean -+ t(0.975, n - 1) sd / sqrt(n)`` (seeds are independent draws of
  the scenario's random parts; the interval assumes the figure is roughly normal over seeds, which
  is what a reader of a results table assumes too), ``None`` for fewer than two values;
* ``n`` - how many finite values there were, ``min`` and ``max``.

Values that are ``None``, NaN or infinite are left out (a seed in which a ratio has no denominator).

How we know it is right: tests/unit/test_stats.py - against numpy's ``std(ddof=1)`` and scipy's
``stats.t.interval`` on random samples, and hand-worked small cases (n = 1, n = 2, missing values).
"""

from __future__ import annotations

import math
from collections.abc import Iterable

from scipy.stats import t as student_t

__all__ = ["CI_LEVEL", "summarize"]

#: the confidence level of every interval the project reports
CI_LEVEL = 0.95


def summarize(values: Iterable) -> dict:
    """``{"mean", "sd", "ci95", "n", "min", "max"}`` of the finite values (module docstring)."""
    v = []
    for x in values:
        if x is None or isinstance(x, bool):
            continue
        f = float(x)
        if math.isfinite(f):
            v.append(f)
    n = len(v)
    if n == 0:
        return {"mean": None, "sd": None, "ci95": None, "n": 0, "min": None, "max": None}
    m = math.fsum(v) / n
    if n < 2:
        return {"mean": m, "sd": None, "ci95": None, "n": 1, "min": m, "max": m}
    sd = math.sqrt(math.fsum((x - m) ** 2 for x in v) / (n - 1))
    half = float(student_t.ppf(0.5 + CI_LEVEL / 2.0, n - 1)) * sd / math.sqrt(n)
    return {"mean": m, "sd": sd, "ci95": [m - half, m + half], "n": n, "min": min(v), "max": max(v)}
