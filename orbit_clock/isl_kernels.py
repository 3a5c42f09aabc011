"""Compiled kernel of the pruned ISL window search (orbit_clock/isl.py ``_runs_in_segments``).

The pruned search samples each candidate span of a satellite pair (the k-d tree's spans,
``_candidate_segments``) on the coarse grid and keeps the runs of samples whose margin is positive:
margin = min(line-of-sight clearance, maximum range - range) [km], the expressions of
``orbit_clock.isl.los_clearance_km`` and ``_margin`` written out for one pair at one sample, with
the same operations in the same order (products summed left to right, as numpy's einsum and norm
do over three components), so a sample is inside here exactly when it is inside there. A 1000-
satellite constellation over 6 h has ~2.4e8 such samples; numpy held five arrays of that length
at once (gigabytes), this loop holds none.

How we know it is right: tests/unit/test_speed_paths.py
``test_pruned_isl_windows_equal_every_pair_at_every_sample`` (the pruned search, this kernel
included, gives the windows of the plain numpy search over every pair at every sample, bit for bit)
and ``test_isl_runs_kernel_equals_numpy_margin`` (the kernel's runs equal those of numpy's margin
on random spans of a 96-satellite constellation, with per-pair ranges).
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["runs_in_segments"]


@njit(cache=True)
def _inside(r, i, j, k, z_scale, radius, lim):
    ax = r[i, k, 0]
    ay = r[i, k, 1]
    az0 = r[i, k, 2]
    bx = r[j, k, 0]
    by = r[j, k, 1]
    bz0 = r[j, k, 2]
    # line-of-sight clearance in the ellipsoid-to-sphere scaled frame (los_clearance_km)
    sax = ax * 1.0
    say = ay * 1.0
    saz = az0 * z_scale
    dx = bx * 1.0 - sax
    dy = by * 1.0 - say
    dz = bz0 * z_scale - saz
    dd = dx * dx + dy * dy + dz * dz
    ad = sax * dx + say * dy + saz * dz
    u = -ad / (dd if dd > 0 else 1.0)
    u = min(max(u, 0.0), 1.0)  # np.clip
    cx = sax + u * dx
    cy = say + u * dy
    cz = saz + u * dz
    clear = np.sqrt(cx * cx + cy * cy + cz * cz) - radius
    # range in the Earth-fixed frame (_margin)
    ex = ax - bx
    ey = ay - by
    ez = az0 - bz0
    rng = lim - np.sqrt(ex * ex + ey * ey + ez * ez)
    m = min(rng, clear)
    if np.isnan(clear) or np.isnan(rng):
        return False
    return m > 0.0


@njit(cache=True)
def runs_in_segments(r, I, J, pair, first, last, z_scale, radius, lim_pair):
    """Runs of positive margin within each span: (span pair, first inside sample, sample after).

    r: (n_sat, n_t, 3) Earth-fixed positions [km]; I, J: the pairs' satellites; span s covers pair
    ``pair[s]`` at samples first[s]..last[s]; radius = a + grazing height [km]; lim_pair: the
    maximum range of each pair [km] (indexed by pair). Runs in span order, then time."""
    cap = 1024
    si = np.empty(cap, np.int64)
    ks = np.empty(cap, np.int64)
    ke = np.empty(cap, np.int64)
    n = 0
    for s in range(pair.size):
        p = pair[s]
        i = I[p]
        j = J[p]
        lim = lim_pair[p]
        start = -1
        for k in range(first[s], last[s] + 2):  # (k = last + 1 closes a run still open at the span's end)
            if k <= last[s] and _inside(r, i, j, k, z_scale, radius, lim):
                if start < 0:
                    start = k
            elif start >= 0:
                if n == cap:
                    cap *= 2
                    si = np.concatenate((si, np.empty(cap - si.size, np.int64)))
                    ks = np.concatenate((ks, np.empty(cap - ks.size, np.int64)))
                    ke = np.concatenate((ke, np.empty(cap - ke.size, np.int64)))
                si[n] = p
                ks[n] = start
                ke[n] = k
                n += 1
                start = -1
    return si[:n], ks[:n], ke[:n]
