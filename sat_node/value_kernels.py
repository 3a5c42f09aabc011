"""Numba kernel of the prior state's runs (:func:`sat_node.value.prior_state`).

A known observation covers a run of consecutive (sorted) instance times for its GP column: from
``start`` on it counts as seen before (Eq. 1's times-seen count, to the instance's end), and over
[``rec_lo``, ``rec_hi``) it is recent (the GP worth nothing). :func:`prior_runs` adds the runs up
in one pass - a difference array per column, summed down the times (the count's in its own output
array) - into the (T, G) count and recent arrays. Integer sums: the same arrays as numpy's
``bincount`` of the run ends followed by a ``cumsum`` down axis 0, without their (T + 1, G)
temporaries (numpy's cumsum down axis 0 was most of the prior state's cost).

How we know it is right: tests/unit/test_value.py test_prior_state_equals_pairwise_definition (random
histories, both arrays equal to the pairwise definition) and test_prior_runs_equals_difference_arrays
(the kernel against numpy's bincount and cumsum on random runs, empty runs and runs to the end).
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["prior_runs"]


@njit(cache=True)
def prior_runs(cols, start, rec_lo, rec_hi, T, G):
    """(count int64 (T, G), recent bool (T, G)): count[t, g] = runs of column g with start <= t;
    recent[t, g] = some run of column g with rec_lo <= t < rec_hi (0 <= start, rec_lo, rec_hi <= T)."""
    count = np.zeros((T, G), np.int64)  # the count's differences first, summed down in place
    d_rec = np.zeros((T + 1, G), np.int32)
    for i in range(cols.shape[0]):
        g = cols[i]
        if start[i] < T:
            count[start[i], g] += 1
        d_rec[rec_lo[i], g] += 1
        d_rec[rec_hi[i], g] -= 1
    recent = np.empty((T, G), np.bool_)
    run = np.zeros(G, np.int32)
    for g in range(G):
        run[g] = d_rec[0, g]
        recent[0, g] = run[g] > 0
    for t in range(1, T):
        for g in range(G):
            count[t, g] += count[t - 1, g]
            run[g] += d_rec[t, g]
            recent[t, g] = run[g] > 0
    return count, recent
