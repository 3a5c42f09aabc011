"""Rank statistics of a value field over time: how fast the ranking of the GPs changes.

The transiency of a field (docs/design.md section 1; the study's precipitation field: 15 min) is the lag
at which the Spearman rank correlation of all GP values falls to 0.5. :func:`rank_correlation` is
that correlation at a lag of whole slots, averaged over the start slots of the horizon;
:func:`measured_transiency_min` finds the crossing (linear between slot lags, lag 0 counting 1).
Every run reports them for its truth field (``osse.rank_corr_15min``, ``osse.rank_corr_60min``,
``osse.transiency_min``).

How fast the values themselves change (the study's "case" is told by its errors: a planner that
knows a GP's value as of ``L`` ago errs by about the field's relative change over ``L``):
:func:`relative_change_by_lag` is the mean and the median over GPs and start slots of
``|v(s + k) - v(s)| / v(s + k)`` (the newer value in the denominator, as the report's assumed-value
error divides by the true value) for whole slot lags ``k``; :func:`relative_change_at` reads it at
any lag [s], linear between slot lags - exact for a lag measured from a time uniform over a slot of
a field held constant over each slot. Every run reports it at its median information age
(bringup/analysis/report.py, ``osse.rel_change_at_info_age``).

How we know it is right (tests/unit/test_osse_transient.py): Spearman's rho here equals
``scipy.stats.spearmanr`` on random data with ties; the crossing of a drawn correlation curve is
found where it was put. tests/unit/test_osse_resolution.py: the relative change equals a direct
loop over every (slot, GP) pair, and read between slot lags equals the average over uniformly
spread look times of a brute force on the piecewise-constant field.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["field_rank_figures", "measured_transiency_min", "rank_correlation", "ranks", "relative_change_at",
           "relative_change_by_lag", "spearman"]


def ranks(v: np.ndarray) -> np.ndarray:
    """Ranks 1..n of the rows' entries along the last axis, ties given their average rank."""
    v = np.asarray(v, dtype=np.float64)
    order = np.argsort(v, axis=-1, kind="stable")
    sv = np.take_along_axis(v, order, axis=-1)
    n = v.shape[-1]
    out = np.empty_like(v)
    for idx in np.ndindex(v.shape[:-1]):
        row = sv[idx]
        start = np.flatnonzero(np.concatenate([[True], row[1:] != row[:-1]]))
        end = np.concatenate([start[1:], [n]])
        avg = 0.5 * (start + end - 1) + 1.0
        r = np.repeat(avg, end - start)
        o = np.empty(n)
        o[order[idx]] = r
        out[idx] = o
    return out


def spearman(a: np.ndarray, b: np.ndarray) -> float:
    ra, rb = ranks(a), ranks(b)
    ra, rb = ra - ra.mean(), rb - rb.mean()
    den = math.sqrt(float((ra * ra).sum() * (rb * rb).sum()))
    return float((ra * rb).sum() / den) if den > 0 else 0.0


def rank_correlation(values: np.ndarray, lag_slots: int) -> float | None:
    """Mean over start slots of the Spearman rank correlation of every GP's value between slot ``t``
    and slot ``t + lag_slots`` (``values`` [n_slots, n_gp]); None when the horizon is too short or a
    slot is constant (no ranking)."""
    v = np.asarray(values)
    n = v.shape[0]
    if lag_slots < 0:
        raise ValueError(f"rank correlation: lag must be >= 0 slots, got {lag_slots}")
    if lag_slots == 0:
        return 1.0
    if n <= lag_slots or v.shape[1] < 3:
        return None
    r = ranks(v)
    r = r - r.mean(axis=1, keepdims=True)
    norm = np.sqrt((r * r).sum(axis=1))
    if np.any(norm == 0):
        return None
    c = (r[:-lag_slots] * r[lag_slots:]).sum(axis=1) / (norm[:-lag_slots] * norm[lag_slots:])
    return float(c.mean())


def measured_transiency_min(values: np.ndarray, slot_s: float) -> float | None:
    """The lag [min] at which :func:`rank_correlation` falls to 0.5, linear between slot lags (lag 0
    counts 1.0); None when it stays above 0.5 over the horizon."""
    prev = 1.0
    for lag in range(1, np.asarray(values).shape[0]):
        rc = rank_correlation(values, lag)
        if rc is None:
            return None
        if rc <= 0.5:
            frac = (prev - 0.5) / (prev - rc) if prev != rc else 1.0
            return (lag - 1 + frac) * slot_s / 60.0
        prev = rc
    return None




def field_rank_figures(values: np.ndarray, slot_s: float) -> dict:
    """The figures every run reports of its truth field: rank correlation at 15 and 60 min (None
    when those lags are not whole slots or exceed the horizon) and the measured transiency [min]."""
    out = {}
    for minutes in (15, 60):
        lag = minutes * 60.0 / slot_s
        out[f"rank_corr_{minutes}min"] = (rank_correlation(values, int(round(lag)))
                                          if abs(lag - round(lag)) < 1e-9 else None)
    out["transiency_min"] = measured_transiency_min(values, slot_s)
    return out


def relative_change_by_lag(values: np.ndarray) -> dict:
    """``{"mean": [...], "median": [...]}`` indexed by the slot lag ``k`` = 0 .. n_slots - 1: the mean
    and median over every start slot and GP of ``|v(s + k) - v(s)| / v(s + k)`` (values > 0)."""
    v = np.asarray(values, dtype=np.float64)
    if v.ndim != 2 or v.size == 0:
        raise ValueError(f"relative change: values must be [n_slots, n_gp], got shape {v.shape}")
    if np.any(v <= 0):
        raise ValueError("relative change: values must be > 0 (the OSSE's are 1..256)")
    mean, med = [0.0], [0.0]
    for k in range(1, v.shape[0]):
        r = np.abs(v[k:] - v[:-k]) / v[k:]
        mean.append(float(r.mean()))
        med.append(float(np.median(r)))
    return {"mean": mean, "median": med}


def relative_change_at(curve: list, slot_s: float, lag_s: float) -> float | None:
    """A :func:`relative_change_by_lag` curve read at ``lag_s`` [s], linear between slot lags; None
    for a negative lag or one beyond the curve's last slot lag."""
    if lag_s is None or not lag_s >= 0 or not curve:
        return None
    x = lag_s / float(slot_s)
    k = math.floor(x)
    if k >= len(curve) - 1:
        return float(curve[-1]) if abs(x - (len(curve) - 1)) < 1e-9 else None
    f = x - k
    return float((1.0 - f) * curve[k] + f * curve[k + 1])
