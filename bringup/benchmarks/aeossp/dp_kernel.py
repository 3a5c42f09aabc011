"""The per-satellite longest-path DP of the ``aeossp_standard`` planner, compiled with numba.

Over a satellite's candidate observations sorted by start, ``V[i] = gain_i + max(0 if the first slew
from nadir fits, max_j V[j])`` over predecessors ``j`` of another task that end early enough for the
bang-coast-bang slew (maximum rate ``w``, acceleration ``a``: ``2 sqrt(theta/a)`` up to
``theta = w^2/a``, else ``w/a + theta/w``) plus settle plus margin from ``j``'s end look ``u1[j]``
to ``i``'s start look ``u0[i]``. A predecessor ending more than ``t_far`` (the time of the longest
slew) before ``i`` starts is always feasible and comes from a running maximum over predecessors
taken in order of their end, so each candidate scans only the few predecessors ending within
``t_far`` of its start.

How we know it is right: tests/unit/test_aeossp_planner.py compares the planner's DP (this kernel)
with a brute force over all subsets of a small satellite's candidates, and every plan it feeds
passes our own check (:mod:`.check`).
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["longest_path"]


@numba.njit(cache=True)
def _slew_need(cos_theta, rate, acc, settle, margin):
    c = min(1.0, max(-1.0, cos_theta))
    th = math.degrees(math.acos(c))
    if th <= rate * rate / acc:
        t = 2.0 * math.sqrt(th / acc)
    else:
        t = rate / acc + th / rate
    return t + settle + margin


@numba.njit(cache=True)
def longest_path(start, end, task, u0, u1, gain, first_ok, by_end, rate, acc, settle, margin, t_far, slew):
    """(V, P): best path value ending at each candidate and its predecessor (-1: none).

    Candidates must be sorted by start; ``by_end`` is the permutation sorting them by end. A
    candidate with ``gain <= 0`` is never used. ``slew=False`` keeps only the no-overlap rule."""
    n = start.shape[0]
    V = np.full(n, -np.inf)
    P = np.full(n, -1, dtype=np.int64)
    best_v, best_j, ptr = 0.0, -1, 0
    for i in range(n):
        if gain[i] <= 0.0:
            continue
        lim = start[i] - t_far
        while ptr < n and end[by_end[ptr]] <= lim:
            j = by_end[ptr]
            if V[j] > best_v:
                best_v, best_j = V[j], j
            ptr += 1
        if first_ok[i]:
            v, p = 0.0, -1
        else:
            v, p = -np.inf, -1
        if best_j >= 0 and best_v > v:
            v, p = best_v, best_j
        k = ptr
        while k < n and end[by_end[k]] <= start[i]:
            j = by_end[k]
            k += 1
            if task[j] == task[i] or V[j] == -np.inf or V[j] <= v:
                continue
            if slew:
                cs = u1[j, 0] * u0[i, 0] + u1[j, 1] * u0[i, 1] + u1[j, 2] * u0[i, 2]
                if start[i] - end[j] < _slew_need(cs, rate, acc, settle, margin):
                    continue
            v, p = V[j], j
        if v > -np.inf:
            V[i], P[i] = v + gain[i], p
    return V, P
