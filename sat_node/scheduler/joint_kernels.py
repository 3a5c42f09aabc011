"""The joint group's Eq. 1 value (:func:`sat_node.scheduler.joint.joint_value`) on arrays.

The value was a Python loop over every look of every plan (:func:`value_loop`), run for each
joint plan. For groups with many looks they are gathered into arrays (numpy), sorted as the loop
sorted them (time, then member, step, column), and summed by a compiled loop (:func:`joint_total`):
the same operations on the same numbers in the same order - a look's time ``t0_s + step_s * k``,
``absval / (prior count + group looks before + 1.0)`` added in that order - so the same float.

How we know it is right: tests/unit/test_joint_kernels.py compares both paths with the loop on
random groups (2-4 members, shared, repeated and tied looks, known prior looks) and on DP plans
of two-satellite instances, bit for bit.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["ARRAY_LOOKS", "group_value", "joint_total", "value_loop"]


@njit(cache=True)
def joint_total(t, gc, n_gp, in_for, prior_recent, absval, prior_count, revisit_zero_s):
    """Eq. 1 over looks already in the group's order: look x at time ``t[x]`` of compact GP
    ``gc[x]`` (0..n_gp-1) is worth 0 outside the FOR, when recently seen (``prior_recent``) or
    within ``revisit_zero_s[x]`` of the group's previous look at it, else ``absval[x] /
    (prior_count[x] + group looks at it before + 1.0)``; returns the sum in that order."""
    last = np.zeros(n_gp)
    seen = np.zeros(n_gp, np.bool_)
    n = np.zeros(n_gp, np.int64)
    total = 0.0
    for x in range(t.shape[0]):
        c = gc[x]
        recent = prior_recent[x] or (seen[c] and t[x] - last[c] < revisit_zero_s[x])
        if in_for[x] and not recent:
            total += absval[x] / (prior_count[x] + n[c] + 1.0)
        last[c] = t[x]
        seen[c] = True
        n[c] += 1
    return total


def _looks(problems, plans):
    """Every look of the plans as arrays (member, step, column, time, global GP), member by member."""
    sizes = [len(pl.steps) for pl in plans]
    member = np.repeat(np.arange(len(plans), dtype=np.int64), sizes)
    steps = np.concatenate([np.asarray(pl.steps, np.int64) for pl in plans])
    cols = np.concatenate([np.asarray(pl.cols, np.int64) for pl in plans])
    t = np.concatenate([p.t0_s + p.step_s * np.asarray(pl.steps, np.int64) for p, pl in zip(problems, plans)])
    return member, steps, cols, t, sizes


#: from this many looks in a group on, :func:`group_value` sums on arrays (below, numpy's fixed cost
#: per call is more than the loop's: 21 looks of 4 members 170 against 61 us, 70 looks of 2 members
#: 75 against 262 us)
ARRAY_LOOKS = 32


def value_loop(problems, plans) -> float:
    """:func:`group_value` as a loop over the looks (small groups; the value as first written)."""
    looks = []
    for i, (p, pl) in enumerate(zip(problems, plans)):
        for k, j in zip(pl.steps, pl.cols):
            looks.append((p.t0_s + p.step_s * int(k), i, int(k), int(j)))
    looks.sort()
    last: dict[int, float] = {}
    n: dict[int, int] = {}
    total = 0.0
    for t, i, k, j in looks:
        p = problems[i]
        g = int(p.gp_ids[j])
        recent = p.prior_recent[k, j] or (g in last and t - last[g] < p.revisit_zero_s)
        if p.in_for[k, j] and not recent:
            total += p.absval[k, j] / (p.prior_count[k, j] + n.get(g, 0) + 1.0)
        last[g] = t
        n[g] = n.get(g, 0) + 1
    return total


def group_value(problems, plans, *, array_looks: int = ARRAY_LOOKS) -> float:
    """:func:`sat_node.scheduler.joint.joint_value` (module docstring): on arrays from
    ``array_looks`` looks on, else :func:`value_loop` (the same float either way)."""
    n = sum(len(pl.steps) for pl in plans)
    if n == 0 or n < array_looks:
        return value_loop(problems, plans)
    member, steps, cols, t, sizes = _looks(problems, plans)
    order = np.lexsort((cols, steps, member, t))  # Python's sort of (t, member, step, column)
    bounds = np.cumsum([0] + sizes)
    parts = []
    for i, p in enumerate(problems):
        k, j = steps[bounds[i]:bounds[i + 1]], cols[bounds[i]:bounds[i + 1]]
        parts.append((p.gp_ids[j], p.in_for[k, j], p.prior_recent[k, j], p.absval[k, j], p.prior_count[k, j],
                      np.full(len(k), p.revisit_zero_s)))
    g, in_for, recent, absval, count, rz = (np.concatenate([x[i] for x in parts])[order] for i in range(6))
    uniq, gc = np.unique(g, return_inverse=True)
    return float(joint_total(t[order], gc.astype(np.int64), len(uniq), in_for.astype(np.bool_),
                             recent.astype(np.bool_), absval.astype(np.float64), count.astype(np.int64),
                             rz.astype(np.float64)))
