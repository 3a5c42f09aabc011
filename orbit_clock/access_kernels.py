"""Numba kernel of the field-of-regard test (:func:`orbit_clock.access.for_mask`).

The FOR test of one (time, GP) pair (orbit_clock/access.py module docstring): the off-nadir angle
eta = angle(-r_sat, r_gp - r_sat) within the FOR, and the GP on the near side of the Earth,
(r_sat - r_gp) . r_gp > 0. :func:`for_codes` runs it in one pass, without temporaries, over the pairs
a pre-filter keeps (a time row and a chunk of consecutive GPs whose spherical cap the FOR may reach),
in cosine space: ``cos(eta) > cos(limit)`` instead of ``degrees(arccos(cos(eta))) <= limit``.
Its arithmetic is not the reference's (:func:`orbit_clock.access._for_mask_all`, numpy on whole
arrays), so a pair it finds within ``COS_BAND`` of the limit's cosine, or within ``DOT_BAND`` (relative)
of the horizon, is marked undecided (2) and the caller decides it with the reference arithmetic: the
mask is the reference's bit for bit. The cosine band is ~1e7 times the rounding of either
arithmetic (a few 1e-16), the horizon band over a thousand times (its error is at most
~7e-16 |r_gp| (|r_sat| + |r_gp|)), so a pair decided here is decided the same way there. A pair with
the satellite on the GP (zero distance) is left undecided too; a field of regard outside 0..180 deg
never reaches the kernel.

How we know it is right: tests/unit/test_orbit_access.py (test_for_mask_row_prefilter_equals_full_test:
random orbits and regions, the mask equal to the reference on every pair;
test_for_mask_edge_pairs_use_the_reference: GPs placed on the FOR's edge and on the horizon, which
this kernel leaves undecided, still give the reference's mask).
"""

from __future__ import annotations

import math

from numba import njit

__all__ = ["COS_BAND", "DOT_BAND", "for_codes"]

#: cosines within this of the limit's are undecided (an angle band of >= 1e-9 rad)
COS_BAND = 1e-9
#: near-side products within this fraction of |r_gp| (|r_sat| + |r_gp|) of zero are undecided
DOT_BAND = 1e-12


@njit(cache=True)
def for_codes(sat, gp, rows, starts, ends, ok, cos_lim, out):
    """For each ``rows[i]`` (a time index into ``sat`` (T, 3)) and each GP chunk ``c`` with
    ``ok[i, c]`` (GPs ``starts[c]:ends[c]`` of ``gp`` (G, 3)): ``out[rows[i], g]`` = 1 in the FOR,
    2 undecided, left as it is (0) outside. Returns the number of undecided pairs."""
    undecided = 0
    for i in range(rows.shape[0]):
        t = rows[i]
        sx = sat[t, 0]
        sy = sat[t, 1]
        sz = sat[t, 2]
        rs = math.sqrt(sx * sx + sy * sy + sz * sz)
        for c in range(starts.shape[0]):
            if not ok[i, c]:
                continue
            for g in range(starts[c], ends[c]):
                gx = gp[g, 0]
                gy = gp[g, 1]
                gz = gp[g, 2]
                dx = gx - sx
                dy = gy - sy
                dz = gz - sz
                dd = math.sqrt(dx * dx + dy * dy + dz * dz)
                rg = math.sqrt(gx * gx + gy * gy + gz * gz)
                near = -(dx * gx + dy * gy + dz * gz)  # (r_sat - r_gp) . r_gp
                band = DOT_BAND * rg * (rs + rg)
                den = rs * dd
                if den == 0.0:  # the satellite on the GP (or at the centre): the reference decides
                    out[t, g] = 2
                    undecided += 1
                    continue
                cos_eta = -(sx * dx + sy * dy + sz * dz) / den
                if near > band and cos_eta > cos_lim + COS_BAND:
                    out[t, g] = 1
                elif not (near < -band or cos_eta < cos_lim - COS_BAND):  # near an edge, or NaN
                    out[t, g] = 2
                    undecided += 1
    return undecided
