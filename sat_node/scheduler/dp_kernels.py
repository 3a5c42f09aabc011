"""Numba inner loop of the DP scheduler (the one seam between Python and compiled code).

Flat arrays only; :mod:`sat_node.scheduler.dp` builds them and checks the result. See dp.py for the
algorithm and for how we know it is right (brute force, MILP, numba on/off).

States are (step k, GP column g) pairs with positive first-visit value, stored sorted by step:
``t_off[k]:t_off[k+1]`` are the states of step k. For each state the kernel finds the best
predecessor: the root (initial attitude, if the slew fits), the best state at least ``w_steps``
steps earlier (always reachable: ``w_steps`` covers the largest possible slew), or a state within the
slew window whose pointing vector is within ``acos(cos_thr[dk])`` of this one. Within a step,
states are visited in decreasing accumulated value (``order``), so the scan stops as soon as no
remaining candidate can beat the best found (branch and bound on the sorted lists).

Path tables: the gain of a GP after a path depends only on how many times the path observed it and
when it last did (a repeat within the revisit window is worth 0 exactly when the latest one is), so
when ``seen_n`` has one row per state the kernel keeps, for each state, those two numbers for every
GP column of its best path (copied from the predecessor's row, then its own GP added) and the gain
is a table look-up (:func:`table_gain`). The same numbers as walking the back-pointers
(:func:`path_gain`), which is what the kernel does when the caller gives no table (too many states
times GPs for memory). When every step of the window lies within the revisit window of every other
(a window no longer than ``revisit_zero_s``, as onboard), a GP already on the path is worth 0
whatever the count, so one bit per GP and state is enough: ``seen_b`` (``ceil(G / 64)`` uint64 words
per state, :func:`bit_gain`), 64 times smaller than the two int32 tables - the dense grids' case.

Checked by tests/unit/test_dp.py (against brute force on small instances),
tests/unit/test_dp_numba_modes.py (compiled and plain Python give the same plans) and
tests/unit/test_speed_paths.py (path tables equal path walks).
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["bit_gain", "dp_forward", "path_gain", "table_gain"]


@njit(cache=True)
def path_gain(q, g, k, vf, n1, st_k, st_g, bp, revisit_steps):
    """Value of observing GP g at step k after the path ending in state q (Eq. 1 along the path).

    vf = first-visit value, n1 = known prior count + 1; path repeats within revisit_steps -> 0,
    older repeats divide absval by one more each.
    """
    cnt = 0
    p = q
    while p >= 0:
        if st_g[p] == g:
            if (k - st_k[p]) < revisit_steps:
                return 0.0
            cnt += 1
        p = bp[p]
    if cnt == 0:
        return vf
    return vf * n1 / (n1 + cnt)


@njit(cache=True)
def table_gain(q, g, k, vf, n1, seen_n, seen_k, revisit_steps):
    """:func:`path_gain` from the path table: seen_n[q, g] = observations of GP column g on the path
    ending in q, seen_k[q, g] = the step of the latest one."""
    cnt = seen_n[q, g]
    if cnt == 0:
        return vf
    if (k - seen_k[q, g]) < revisit_steps:
        return 0.0
    return vf * n1 / (n1 + cnt)


@njit(cache=True)
def bit_gain(q, g, vf, seen_b):
    """:func:`path_gain` when every earlier step is within the revisit window: 0 if GP column g is on
    the path ending in q (bit g of seen_b[q]), else the first-visit value."""
    if (seen_b[q, g >> 6] >> np.uint64(g & 63)) & np.uint64(1):
        return 0.0
    return vf


@njit(cache=True)
def dp_forward(k_lo, k_hi, t_off, st_k, st_g, st_u, st_vf, st_n1, root_ok, cos_thr, w_steps,
               revisit_steps, V, bp, order, pref, seen_n, seen_k, seen_b):
    """Process steps k_lo..k_hi-1 in place (V, bp, order, pref, seen_n, seen_k, seen_b); earlier steps
    must be done.

    pref[0] = best state among steps folded so far (-1 none), pref[1] = next step to fold.
    V = -inf and bp = -2 for unreachable states; bp = -1 for paths starting at the root.
    seen_b: (S, ceil(G / 64)) uint64 path bitsets, zeros on entry, when the window lies within the
    revisit window (module docstring); else (0, 0) and seen_n, seen_k: (S, G) int32 path tables,
    zeros on entry, or (0, 0) arrays to walk the back-pointers instead.
    """
    bits = seen_b.shape[0] > 0
    table = (not bits) and seen_n.shape[0] > 0
    ninf = -np.inf
    for k in range(k_lo, k_hi):
        while pref[1] <= k - w_steps:
            kk = pref[1]
            if t_off[kk] < t_off[kk + 1]:
                s0 = order[t_off[kk]]
                if V[s0] > ninf and (pref[0] < 0 or V[s0] > V[pref[0]]):
                    pref[0] = s0
            pref[1] += 1
        for s in range(t_off[k], t_off[k + 1]):
            g = st_g[s]
            vf = st_vf[s]
            n1 = st_n1[s]
            ux = st_u[s, 0]
            uy = st_u[s, 1]
            uz = st_u[s, 2]
            best = ninf
            b = -2
            if root_ok[s]:
                best = vf
                b = -1
            p = pref[0]
            if p >= 0:
                if bits:
                    gain = bit_gain(p, g, vf, seen_b)
                elif table:
                    gain = table_gain(p, g, k, vf, n1, seen_n, seen_k, revisit_steps)
                else:
                    gain = path_gain(p, g, k, vf, n1, st_k, st_g, bp, revisit_steps)
                if V[p] + gain > best:
                    best = V[p] + gain
                    b = p
            for dk in range(1, w_steps):
                kk = k - dk
                if kk < 0:
                    break
                thr = cos_thr[dk]
                if thr > 1.0:
                    continue
                for i in range(t_off[kk], t_off[kk + 1]):
                    q = order[i]
                    vq = V[q]
                    if vq + vf <= best:
                        break
                    dot = ux * st_u[q, 0] + uy * st_u[q, 1] + uz * st_u[q, 2]
                    if dot < thr:
                        continue
                    if bits:
                        gain = bit_gain(q, g, vf, seen_b)
                    elif table:
                        gain = table_gain(q, g, k, vf, n1, seen_n, seen_k, revisit_steps)
                    else:
                        gain = path_gain(q, g, k, vf, n1, st_k, st_g, bp, revisit_steps)
                    if vq + gain > best:
                        best = vq + gain
                        b = q
                    if gain >= vf:
                        break
            V[s] = best
            bp[s] = b
            if bits and b > -2:
                if b >= 0:
                    for w in range(seen_b.shape[1]):
                        seen_b[s, w] = seen_b[b, w]
                seen_b[s, g >> 6] |= np.uint64(1) << np.uint64(g & 63)
            elif table and b > -2:
                if b >= 0:
                    seen_n[s, :] = seen_n[b, :]
                    seen_k[s, :] = seen_k[b, :]
                seen_n[s, g] += 1
                seen_k[s, g] = k
        lo = t_off[k]
        hi = t_off[k + 1]
        if hi > lo:
            idx = np.argsort(-V[lo:hi], kind="mergesort")
            for i in range(hi - lo):
                order[lo + i] = lo + idx[i]
