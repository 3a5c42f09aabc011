"""The in-pass look cadence: how long a satellite takes from one look to its next over a region.

Each satellite's executed looks in time order; an interval shorter than ``IN_PASS_GAP_S`` (60 s) is
one inside a pass, a longer one a gap between passes (the study's own scheduler output, its traffic
files tests/fixtures/paper_inputs, has 7792 of its 7795 case1 intervals under 60 s at exactly 9 s,
the others 18, 29 and 37 s, and none between 37 and 106 s: the gap parts passes cleanly). The report gives their histogram in whole
seconds (an interval of 9.0 s counts in "9"), the mode, its share and the median
(``looks.in_pass_interval_s``), so a run's cadence can be set beside the study's.

How we know it is right (tests/unit/test_ground_network.py): the figures of hand-made look times; the paper
scenario's planner gives the study's 9-s cadence as measured from the study's traffic files by an
independent reading of the CSV.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Mapping

import numpy as np

__all__ = ["IN_PASS_GAP_S", "cadence_figures", "in_pass_intervals"]

IN_PASS_GAP_S = 60.0


def in_pass_intervals(times_by_sat: Mapping[str, Iterable[float]], gap_s: float = IN_PASS_GAP_S) -> np.ndarray:
    """Intervals [s] between successive looks of one satellite shorter than ``gap_s``."""
    out = []
    for ts in times_by_sat.values():
        t = np.sort(np.asarray(list(ts), dtype=np.float64))
        d = np.diff(t)
        out.append(d[d < gap_s])
    return np.concatenate(out) if out else np.zeros(0)


def cadence_figures(times_by_sat: Mapping[str, Iterable[float]], gap_s: float = IN_PASS_GAP_S) -> dict:
    """``{"count", "hist" {whole seconds: n}, "mode_s", "mode_share", "median_s", "gap_s"}`` of the
    in-pass intervals (None figures when there are none)."""
    d = in_pass_intervals(times_by_sat, gap_s)
    whole = np.floor(np.round(d, 3)).astype(np.int64)
    hist = Counter(int(x) for x in whole)
    out: dict = {"count": int(d.size), "gap_s": float(gap_s),
                 "hist": {str(k): hist[k] for k in sorted(hist)}}
    if d.size:
        mode, n = max(hist.items(), key=lambda kv: (kv[1], -kv[0]))
        out.update(mode_s=int(mode), mode_share=n / d.size, median_s=float(np.median(d)))
    else:
        out.update(mode_s=None, mode_share=None, median_s=None)
    return out
