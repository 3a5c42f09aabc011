"""Visibility windows from sampled time series: the grid, the runs, the edges, the mean range.

Every window search of the orbit core (GP access, ISL contacts, ground-station passes) samples a
margin on a time grid and turns the runs of positive samples into windows; this module holds those
steps once:

* :func:`time_grid` - [t0, t1] every ``step_s``, the last sample exactly at t1;
* :func:`true_runs` - the runs of True along the time axis of a (series, time) boolean array;
* :func:`windows_from_margin` - windows where a margin is > 0, each edge refined by bisection on the
  margin evaluated at scattered times (ISL line of sight and range, station elevation); the access
  search places its edges by linear interpolation instead (orbit_clock.access);
  :func:`refine_runs` is its bisection alone, for searches that find the runs themselves (the
  pruned ISL search samples only the pairs and times that can be in range);
* :func:`mean_range_km` - the mean distance over each window (evenly spaced samples, ends
  included), which a contact plan turns into a constant light time (CGR takes range constant over a
  contact).

How we know it is right: the searches built on it are checked against independent oracles
(tests/unit/test_orbit_access.py: skyfield ``find_events`` and a brute-force 1 s grid;
tests/unit/test_orbit_isl.py: 1 s brute-force ISL windows, skyfield station passes), and
tests/unit/test_orbit_windows.py checks the runs against a Python loop, the bisection against a
margin whose roots are known, and the mean range against a closed form.
"""

from __future__ import annotations

from collections.abc import Callable
from itertools import pairwise

import numpy as np

__all__ = ["mean_range_km", "refine_runs", "refine_runs_split", "time_grid", "true_runs", "windows_from_margin"]


def time_grid(t0_s: float, t1_s: float, step_s: float) -> np.ndarray:
    """Times [s] from t0_s every step_s, with t1_s as the last sample (also when t1_s - t0_s < step_s)."""
    t = np.arange(t0_s, t1_s, step_s, dtype=float)
    return np.append(t, t1_s) if t.size == 0 or t[-1] < t1_s else t


def true_runs(inside: np.ndarray):
    """Runs of True along the last axis of ``inside`` (n_series, n_t): (series, first, after) int
    arrays - each run covers samples first .. after - 1 of its series; ordered by series, then time."""
    n_s = inside.shape[0]
    pad = np.zeros((n_s, 1), dtype=np.int8)
    d = np.diff(np.concatenate([pad, inside.astype(np.int8), pad], axis=1), axis=1)
    si, ks = np.nonzero(d == 1)
    _, ke = np.nonzero(d == -1)
    return si, ks, ke


def windows_from_margin(t_s: np.ndarray, margin: np.ndarray,
                        margin_at: Callable[[np.ndarray, np.ndarray], np.ndarray], tol_s: float = 1e-3):
    """Windows where margin > 0, from a sampled grid refined by bisection.

    t_s: (n_t,) grid [s]; margin: (n_series, n_t) samples; margin_at(series_idx, t_s) evaluates the
    margin at scattered points (same-length 1-D arrays). Returns (series_idx, start_s, end_s);
    a window open at the first/last sample starts/ends there.
    """
    si, ks, ke = true_runs(margin > 0)
    start, end = refine_runs(t_s, si, ks, ke, margin_at, tol_s)
    return si, start, end


def refine_runs(t_s: np.ndarray, si: np.ndarray, ks: np.ndarray, ke: np.ndarray,
                margin_at: Callable[[np.ndarray, np.ndarray], np.ndarray], tol_s: float = 1e-3):
    """(start_s, end_s) of runs of positive margin found on the grid ``t_s``: run k of series si[k]
    covers samples ks[k] .. ke[k] - 1 (:func:`true_runs`); each edge inside the grid is refined by
    bisection on ``margin_at`` to ``tol_s``, an edge at the grid's first/last sample stays there.
    The bisection of every edge runs together (the same steps whatever else is refined with it)."""
    n_t = t_s.size
    start = t_s[ks].astype(float)
    end = t_s[ke - 1].astype(float)
    m = ks > 0
    lo, hi, _ = _bisect(si[m], t_s[ks[m] - 1], t_s[ks[m]], False, margin_at, tol_s)
    start[m] = 0.5 * (lo + hi)
    m = ke < n_t
    lo, hi, _ = _bisect(si[m], t_s[ke[m] - 1], t_s[ke[m]], True, margin_at, tol_s)
    end[m] = 0.5 * (lo + hi)
    return start, end


def _bisect(idx, lo, hi, lo_inside: bool, margin_at, tol_s: float, min_steps: int = 0):
    """Bisect every bracket [lo, hi] together until the widest is at most ``tol_s`` and at least
    ``min_steps`` steps were made: (lo, hi, steps). A bracket's steps depend on it alone (``margin_at``
    is evaluated point by point), so brackets bisected apart and each group then taken on to the
    largest step count of all end as the brackets bisected together."""
    steps = 0
    while idx.size and (np.max(hi - lo) > tol_s or steps < min_steps):
        mid = 0.5 * (lo + hi)
        ins = margin_at(idx, mid) > 0
        move_lo = ins if lo_inside else ~ins
        lo = np.where(move_lo, mid, lo)
        hi = np.where(move_lo, hi, mid)
        steps += 1
    return lo, hi, steps


def refine_runs_split(t_s: np.ndarray, si: np.ndarray, ks: np.ndarray, ke: np.ndarray,
                      margin_at: Callable[[np.ndarray, np.ndarray], np.ndarray], tol_s: float = 1e-3,
                      workers: int = 2):
    """:func:`refine_runs` with the runs cut into ``workers`` consecutive parts bisected side by side
    in forked processes (orbit_clock/fork_split.py): the same numbers bit for bit. A part whose
    widest bracket reached ``tol_s`` in fewer steps than another part's is taken on to the larger
    count here, as one bisection of all the runs would have done (:func:`_bisect`)."""
    from orbit_clock.fork_split import run_parts

    n_t = t_s.size
    cuts = np.linspace(0, si.size, max(1, workers) + 1).round().astype(np.int64)
    parts = [slice(int(a), int(b)) for a, b in pairwise(cuts)]

    def edges(sl: slice):
        s_i, s_ks, s_ke = si[sl], ks[sl], ke[sl]
        m0, m1 = s_ks > 0, s_ke < n_t
        return (_bisect(s_i[m0], t_s[s_ks[m0] - 1], t_s[s_ks[m0]], False, margin_at, tol_s),
                _bisect(s_i[m1], t_s[s_ke[m1] - 1], t_s[s_ke[m1]], True, margin_at, tol_s))

    res = run_parts(edges, parts, workers=workers)
    start = t_s[ks].astype(float)
    end = t_s[ke - 1].astype(float)
    for which, out, lo_inside in ((0, start, False), (1, end, True)):
        most = max(r[which][2] for r in res)
        for sl, r in zip(parts, res):
            lo, hi, steps = r[which]
            m = (ks[sl] > 0) if which == 0 else (ke[sl] < n_t)
            if steps < most:  # the other parts' brackets were still wider: the same steps go on here
                lo, hi, _ = _bisect(si[sl][m], lo, hi, lo_inside, margin_at, tol_s, most - steps)
            out[sl][m] = 0.5 * (lo + hi)
    return start, end


def mean_range_km(pos_a_km_at: Callable[[np.ndarray], np.ndarray],
                  pos_b_km_at: Callable[[np.ndarray], np.ndarray],
                  start_s: np.ndarray, end_s: np.ndarray, n_samples: int = 21) -> np.ndarray:
    """Mean distance [km] between two moving points over each window [start_s[k], end_s[k]].

    ``pos_a_km_at(t)`` / ``pos_b_km_at(t)`` give the positions (n * n_samples, 3) [km] at the times
    ``t`` of the windows' samples, window by window (``n_samples`` evenly spaced, ends included).
    """
    if len(start_s) == 0:
        return np.empty(0)
    u = np.linspace(0.0, 1.0, n_samples)
    t = (start_s[:, None] + (end_s - start_s)[:, None] * u[None, :]).ravel()
    return np.linalg.norm(pos_a_km_at(t) - pos_b_km_at(t), axis=-1).reshape(-1, n_samples).mean(axis=1)
