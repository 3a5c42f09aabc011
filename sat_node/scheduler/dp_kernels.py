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

Pruning that skips only candidates that cannot strictly beat the best found so far (so the plans,
values and back-pointers are the same as scanning every candidate, ties included: the first found
wins, in the order root, folded best, dk = 1, 2, ..., and within a step by decreasing value then
state index): a gain is at most the first-visit value ``vf``, so the window scan stops when the
largest value left in the reachable window steps (``top``) plus ``vf`` cannot beat it; with path
bitsets a candidate's gain is ``vf`` or 0, so once a step's values are no longer above the best only
candidates without the GP on their path can win, and the leading states of the step whose paths
all have it are skipped at once (``first_off``, :func:`_index_step`). Each finished step's values
and pointing vectors are kept in scan order (``Vs``, ``us``) so the scan reads memory in sequence,
and its order is sorted starting from the previous step's (:func:`_sort_step`: the same order as a
stable sort, far fewer moves).
bench/bench_dp_kernel.py times this against the kernel before these cuts on instances captured from
runs and checks that V and the back-pointers are bit for bit the same.

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

import math

import numpy as np
from numba import config, njit

__all__ = ["bit_gain", "dp_forward", "dp_states", "path_gain", "plan_values", "states_without", "table_gain"]


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


_ONE = np.uint64(1)

if config.DISABLE_JIT:  # plain Python (tests/unit/test_dp_numba_modes.py): no LLVM intrinsic

    def _ctz(x):
        """Index of the lowest set bit of a non-zero uint64."""
        x = int(x)
        return (x & -x).bit_length() - 1

else:
    from numba.cpython.unsafe.numbers import trailing_zeros

    @njit(inline="always")
    def _ctz(x):
        return np.int64(trailing_zeros(x))


@njit(cache=True)
def _index_step(kk, t_off, order, V, st_u, w_steps, Vs, us, seen_b, first_off, cum):
    """Once step kk is final: its values and pointing vectors in scan order (``Vs``, ``us``: position
    ``t_off[kk] + i`` holds state ``order[t_off[kk] + i]``) and, with path bitsets, in ring slot
    ``kk % w_steps`` of ``first_off``: for each GP column g, the first scan position whose best path
    does not have g (the number of states if none) - the running AND of the paths' bitsets, stopped
    as soon as it is empty (cum: ceil(G / 64) uint64 scratch)."""
    lo = t_off[kk]
    hi = t_off[kk + 1]
    for i in range(lo, hi):
        q = order[i]
        Vs[i] = V[q]
        us[i, 0] = st_u[q, 0]
        us[i, 1] = st_u[q, 1]
        us[i, 2] = st_u[q, 2]
    if seen_b.shape[0] == 0:
        return
    fo = first_off[kk % w_steps]
    fo[:] = 0
    if hi == lo:
        return
    words = seen_b.shape[1]
    left = 0
    q = order[lo]
    for w in range(words):
        cum[w] = seen_b[q, w]
        if cum[w] != 0:
            left += 1
    i = 1
    while left > 0 and lo + i < hi:
        q = order[lo + i]
        for w in range(words):
            c = cum[w]
            if c != 0:
                drop = c & ~seen_b[q, w]
                if drop != 0:
                    c ^= drop
                    cum[w] = c
                    if c == 0:
                        left -= 1
                    while drop != 0:
                        fo[(w << 6) + _ctz(drop)] = i
                        drop &= drop - _ONE
        i += 1
    if left > 0:
        for w in range(words):
            c = cum[w]
            while c != 0:
                fo[(w << 6) + _ctz(c)] = hi - lo
                c &= c - _ONE


@njit(cache=True)
def _sort_step(lo, hi, plo, phi, V, st_g, order, pos):
    """order[lo:hi] = the states lo..hi-1 by decreasing V, equal values by increasing index (what a
    stable sort of -V gives). Starts from the previous step's order (plo:phi) mapped by GP column and
    insertion-sorts it: a GP's value changes little from step to step (well under one inversion per
    state on the captured instances); when most of the step's GPs are new it sorts from scratch.
    pos: scratch of G (max GP column + 1) int64, all -1 on entry and on return."""
    n = hi - lo
    if n == 0:
        return
    for s in range(lo, hi):
        pos[st_g[s]] = s
    o = lo
    for i in range(plo, phi):
        g = st_g[order[i]]
        s = pos[g]
        if s >= 0:
            order[o] = s
            pos[g] = -1
            o += 1
    if 2 * (o - lo) < n:  # mostly new GPs: no good start
        for s in range(lo, hi):
            pos[st_g[s]] = -1
        idx = np.argsort(-V[lo:hi], kind="mergesort")
        for i in range(n):
            order[lo + i] = lo + idx[i]
        return
    for s in range(lo, hi):
        if pos[st_g[s]] >= 0:
            order[o] = s
            pos[st_g[s]] = -1
            o += 1
    for i in range(lo + 1, hi):
        x = order[i]
        v = V[x]
        j = i - 1
        while j >= lo:
            y = order[j]
            if V[y] > v or (V[y] == v and y < x):
                break
            order[j + 1] = y
            j -= 1
        order[j + 1] = x


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
    S = st_k.shape[0]
    Vs = np.empty(S)
    us = np.empty((S, 3))
    if bits:
        first_off = np.zeros((w_steps, seen_b.shape[1] * 64), dtype=np.int64)
    else:
        first_off = np.zeros((0, 0), dtype=np.int64)
    cum = np.empty(seen_b.shape[1], dtype=np.uint64)
    top = np.empty(w_steps + 1)
    dk0 = 1  # the shortest gap a slew can fit in (top[dk] = top[dk0] below it)
    while dk0 < w_steps and cos_thr[dk0] > 1.0:
        dk0 += 1
    ng = 0
    for s in range(S):
        ng = max(ng, st_g[s] + 1)
    pos = np.full(ng, -1, dtype=np.int64)
    plo = 0  # the latest non-empty step before k_lo (its order is final)
    phi = 0
    for kk in range(k_lo - 1, -1, -1):
        if t_off[kk] < t_off[kk + 1]:
            plo = t_off[kk]
            phi = t_off[kk + 1]
            break
    for kk in range(max(0, k_lo - w_steps + 1), k_lo):
        _index_step(kk, t_off, order, V, st_u, w_steps, Vs, us, seen_b, first_off, cum)
    for k in range(k_lo, k_hi):
        while pref[1] <= k - w_steps:
            kk = pref[1]
            if t_off[kk] < t_off[kk + 1]:
                s0 = order[t_off[kk]]
                if V[s0] > ninf and (pref[0] < 0 or V[s0] > V[pref[0]]):
                    pref[0] = s0
            pref[1] += 1
        # top[dk] >= every V in the window steps dk..w_steps-1 that a slew can reach
        top[w_steps] = ninf
        for dk in range(w_steps - 1, 0, -1):
            r = top[dk + 1]
            kk = k - dk
            if kk >= 0 and cos_thr[dk] <= 1.0 and t_off[kk] < t_off[kk + 1]:
                r = max(r, Vs[t_off[kk]])
            top[dk] = r
        for s in range(t_off[k], t_off[k + 1]):
            g = st_g[s]
            gw = g >> 6
            gb = np.uint64(g & 63)
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
            for dk in range(dk0, w_steps):
                kk = k - dk
                if kk < 0 or top[dk] + vf <= best:
                    break  # no candidate left can beat best (a gain is at most vf)
                thr = cos_thr[dk]
                if thr > 1.0:
                    continue
                lo = t_off[kk]
                n = t_off[kk + 1] - lo
                if bits:
                    i = 0
                    done = False
                    while i < n:  # candidates that win even with gain 0
                        vq = Vs[lo + i]
                        if vq + vf <= best:
                            done = True
                            break
                        if vq <= best:
                            break
                        dot = ux * us[lo + i, 0] + uy * us[lo + i, 1] + uz * us[lo + i, 2]
                        if dot >= thr:
                            q = order[lo + i]
                            if (seen_b[q, gw] >> gb) & _ONE:
                                best = vq  # gain 0
                                b = q
                            else:
                                best = vq + vf
                                b = q
                                done = True
                                break
                        i += 1
                    if not done:
                        # the rest can only win with gain vf: skip the leading ones with g on their path
                        i = max(i, first_off[kk % w_steps, g])
                        while i < n:
                            vq = Vs[lo + i]
                            if vq + vf <= best:
                                break
                            q = order[lo + i]
                            if (not (seen_b[q, gw] >> gb) & _ONE
                                    and ux * us[lo + i, 0] + uy * us[lo + i, 1] + uz * us[lo + i, 2] >= thr):
                                best = vq + vf
                                b = q
                                break
                            i += 1
                else:
                    for i in range(lo, lo + n):
                        vq = Vs[i]
                        if vq + vf <= best:
                            break
                        dot = ux * us[i, 0] + uy * us[i, 1] + uz * us[i, 2]
                        if dot < thr:
                            continue
                        q = order[i]
                        if table:
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
        _sort_step(lo, hi, plo, phi, V, st_g, order, pos)
        if hi > lo:
            plo = lo
            phi = hi
        _index_step(k, t_off, order, V, st_u, w_steps, Vs, us, seen_b, first_off, cum)


@njit(cache=True)
def dp_states(in_for, prior_recent, absval, prior_count, sat, gp):
    """The DP's states in one pass over the instance's (step, GP column) grid: those with a positive
    first-visit value ``absval / (prior_count + 1)`` in the FOR and not recently seen, in row-major
    order, with that value and the unit satellite-to-GP vector - the numbers of
    :func:`sat_node.scheduler.dp._states` (``SchedulingProblem.v_first`` and ``pointing``: the same
    IEEE operations in the same order, tests/unit/test_speed_paths.py compares the bits).
    Returns (st_k, st_g, st_u, st_vf, t_off, zero_length) - the last True if a satellite sat on a GP."""
    T, G = in_for.shape
    n = 0
    for k in range(T):
        for g in range(G):
            if in_for[k, g] and not prior_recent[k, g]:
                if absval[k, g] / (prior_count[k, g] + 1.0) > 0.0:
                    n += 1
    st_k = np.empty(n, np.int64)
    st_g = np.empty(n, np.int64)
    st_u = np.empty((n, 3))
    st_vf = np.empty(n)
    t_off = np.zeros(T + 1, np.int64)
    zero = False
    i = 0
    for k in range(T):
        t_off[k] = i
        sx = sat[k, 0]
        sy = sat[k, 1]
        sz = sat[k, 2]
        for g in range(G):
            if in_for[k, g] and not prior_recent[k, g]:
                v = absval[k, g] / (prior_count[k, g] + 1.0)
                if v > 0.0:
                    dx = gp[g, 0] - sx
                    dy = gp[g, 1] - sy
                    dz = gp[g, 2] - sz
                    nn = math.sqrt((dx * dx + dy * dy) + dz * dz)
                    zero = zero or nn == 0.0
                    st_k[i] = k
                    st_g[i] = g
                    st_vf[i] = v
                    st_u[i, 0] = dx / nn
                    st_u[i, 1] = dy / nn
                    st_u[i, 2] = dz / nn
                    i += 1
    t_off[T] = i
    return st_k, st_g, st_u, st_vf, t_off, zero


@njit(cache=True)
def plan_values(in_for, prior_recent, absval, prior_count, steps, cols, step_s, revisit_zero_s):
    """Eq. 1 value of each observation (step, GP column) of a plan in time order: the loop of
    :func:`sat_node.scheduler.problem.evaluate_plan` (the same operations on the same numbers): 0
    outside the FOR, recently seen, or within revisit_zero_s of an earlier look of the plan at the GP;
    else absval / (prior count + earlier looks of the plan at the GP + 1)."""
    n = steps.shape[0]
    vals = np.zeros(n)
    for i in range(n):
        k = steps[i]
        j = cols[i]
        own = 0
        recent = False
        for m in range(i):
            if cols[m] == j:
                own += 1
                if (k - steps[m]) * step_s < revisit_zero_s:
                    recent = True
        if in_for[k, j] and not prior_recent[k, j] and not recent:
            vals[i] = absval[k, j] / (prior_count[k, j] + own + 1.0)
    return vals


@njit(cache=True)
def states_without(gone, n_steps, st_k, st_g, st_u, st_vf, st_n1, root_ok, off_deg):
    """The DP states of a branch that makes the GP columns flagged in ``gone`` worth nothing: the
    parent's states (in their order) without those columns, every per-state number copied, and the
    new step offsets - what ``take`` of each array by the kept indices and ``bincount`` + ``cumsum``
    of the steps give (sat_node/scheduler/dp.py ``_prepared``; tests/unit/test_speed_paths.py)."""
    S = st_k.shape[0]
    n = 0
    for s in range(S):
        if not gone[st_g[s]]:
            n += 1
    k2 = np.empty(n, np.int64)
    g2 = np.empty(n, np.int64)
    u2 = np.empty((n, 3))
    vf2 = np.empty(n)
    n12 = np.empty(n)
    ok2 = np.empty(n, np.bool_)
    off2 = np.empty(n)
    t_off = np.zeros(n_steps + 1, np.int64)
    i = 0
    for s in range(S):
        if gone[st_g[s]]:
            continue
        k2[i] = st_k[s]
        g2[i] = st_g[s]
        u2[i, 0] = st_u[s, 0]
        u2[i, 1] = st_u[s, 1]
        u2[i, 2] = st_u[s, 2]
        vf2[i] = st_vf[s]
        n12[i] = st_n1[s]
        ok2[i] = root_ok[s]
        off2[i] = off_deg[s]
        t_off[st_k[s] + 1] += 1
        i += 1
    for k in range(n_steps):
        t_off[k + 1] += t_off[k]
    return k2, g2, u2, vf2, n12, ok2, off2, t_off
