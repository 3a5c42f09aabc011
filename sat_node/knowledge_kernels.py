"""Numba kernel of the observed-knowledge sums (:class:`sat_node.knowledge.ObservedView`).

The observed model spreads each known look's innovation over its region's GPs with a Gaussian
kernel in distance that fades with the look's age (sat_node/knowledge.py, module docstring):
``k(g, o) = exp(-0.5 |x_g - x_o|^2 / spread^2 - (t_now - t_o) / memory)``. Its exponent was a
chain of numpy temporaries over the (GPs, looks) grid - the (G, N, 3) differences, their squared
norms by ``einsum``, the scalings - each a pass over memory; :func:`kernel_exponent` makes the
same numbers in one pass. The exponential, the matrix-vector product with the innovations and
the row sums stay numpy's (their rounding is numpy's SIMD and BLAS code, which a compiled loop
would not reproduce bit for bit).

The same IEEE operations in the same order as the numpy expression it replaces:
``-0.5 * einsum("ijk,ijk->ij", dx, dx) / spread_km ** 2 - (t_now - t_o) / memory_s`` with
``dx = x_g - x_o``; numpy's ``einsum`` adds a 3-vector's squared components as
``(x*x + z*z) + y*y`` (its SIMD reduction folds the vector's halves; measured, and checked by the
test against ``einsum`` itself). How we know it is right: tests/unit/test_knowledge_kernels.py
compares the kernel's bits with the numpy expression's on random and real (paper GP) geometry,
and the views built with it with the numpy path (test_knowledge.py's scalar formula and
region-reuse tests keep holding).

Looks are made at GPs, so a region's looks sit at far fewer places than there are looks (a region's
GPs, seen again and again): :func:`place_exponent` makes the distance term once per (GP, place) and
:func:`gathered_exponent` takes it for each look and subtracts the look's age - the same two
operations on the same operands as :func:`kernel_exponent`, so the same bits (the test compares
them with :func:`kernel_exponent` and the numpy expression).
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["gathered_exponent", "innovation_grid", "kernel_exponent", "place_exponent"]


@njit(cache=True)
def kernel_exponent(gp_xyz, obs_xyz, obs_t, t_now, spread2, memory_s):
    """(G, N) exponent of the Gaussian kernel between GPs ``gp_xyz`` (G, 3) [km] and looks
    ``obs_xyz`` (N, 3) [km] made at ``obs_t`` (N,) [s], at ``t_now`` [s]: ``-0.5 |dx|^2 / spread2
    - (t_now - t_o) / memory_s`` (module docstring: numpy's operations and order)."""
    N = obs_xyz.shape[0]
    age = np.empty(N)
    for j in range(N):
        age[j] = (t_now - obs_t[j]) / memory_s
    out = place_exponent(gp_xyz, obs_xyz, spread2)  # the distance term, then the age: the same bits
    for i in range(out.shape[0]):
        for j in range(N):
            out[i, j] = out[i, j] - age[j]
    return out


@njit(cache=True)
def place_exponent(gp_xyz, place_xyz, spread2):
    """(G, U) distance term ``-0.5 |dx|^2 / spread2`` of :func:`kernel_exponent` between GPs
    ``gp_xyz`` (G, 3) and the places ``place_xyz`` (U, 3) looks were made at [km]."""
    G = gp_xyz.shape[0]
    U = place_xyz.shape[0]
    out = np.empty((G, U))
    for i in range(G):
        gx = gp_xyz[i, 0]
        gy = gp_xyz[i, 1]
        gz = gp_xyz[i, 2]
        for j in range(U):
            dx = gx - place_xyz[j, 0]
            dy = gy - place_xyz[j, 1]
            dz = gz - place_xyz[j, 2]
            sq = (dx * dx + dz * dz) + dy * dy
            out[i, j] = -0.5 * sq / spread2
    return out


@njit(cache=True)
def gathered_exponent(place_term, place_of, obs_t, t_now, memory_s, out):
    """(G, N) :func:`kernel_exponent` from :func:`place_exponent`'s (G, U) ``place_term``: look j
    made at place ``place_of[j]`` at ``obs_t[j]`` [s]: ``place_term[:, place_of[j]] - (t_now - t_j) /
    memory_s``; written into ``out`` (G, N) (a buffer the caller keeps: a fresh array of this size
    costs its page faults again at every call), which it returns."""
    G = place_term.shape[0]
    N = place_of.shape[0]
    age = np.empty(N)
    for j in range(N):
        age[j] = (t_now - obs_t[j]) / memory_s
    for i in range(G):
        row = place_term[i]
        for j in range(N):
            out[i, j] = row[place_of[j]] - age[j]
    return out


@njit(cache=True)
def innovation_grid(a, n0, w0, rows, col_row, ln_max):
    """(T, G) innovation D of a row of GPs by a column of times (sat_node/knowledge.py
    ``ObservedView.innovation``): with ``a`` (T,) the fading of the looks' sums at each time,
    ``n0``, ``w0`` (G,) those sums per GP, ``rows`` (R, T) the region insights' terms per time (row 0
    all zero: no insight) and ``col_row`` (G,) each GP's row, ``clip(a n0 / max(1, a w0) +
    (1 - min(1, a w0)) row, -ln_max, ln_max)`` - numpy's operations on the broadcast arrays, element
    by element in the same order."""
    T = a.shape[0]
    G = n0.shape[0]
    out = np.empty((T, G))
    for t in range(T):
        at = a[t]
        for g in range(G):
            wt = at * w0[g]
            d = at * n0[g] / max(1.0, wt)
            v = d + (1.0 - min(1.0, wt)) * rows[col_row[g], t]
            if v < -ln_max:
                v = -ln_max
            elif v > ln_max:
                v = ln_max
            out[t, g] = v
    return out
