"""bringup/analysis/stats.py against numpy and scipy, and by hand."""

import math

import numpy as np
import pytest
from scipy import stats as sps

from bringup.analysis.stats import summarize


@pytest.mark.parametrize("n", [2, 3, 5, 10])
def test_summary_equals_numpy_and_scipy(n):
    rng = np.random.default_rng(n)
    for _ in range(20):
        x = rng.normal(100.0, 15.0, n)
        s = summarize(list(x))
        assert s["n"] == n
        assert s["mean"] == pytest.approx(float(np.mean(x)), rel=1e-12)
        assert s["sd"] == pytest.approx(float(np.std(x, ddof=1)), rel=1e-12)
        lo, hi = sps.t.interval(0.95, n - 1, loc=np.mean(x), scale=sps.sem(x))
        assert s["ci95"] == pytest.approx([lo, hi], rel=1e-12)
        assert s["min"] == x.min() and s["max"] == x.max()


def test_small_and_missing_by_hand():
    assert summarize([]) == {"mean": None, "sd": None, "ci95": None, "n": 0, "min": None, "max": None}
    one = summarize([None, 4.0, float("nan")])
    assert one["mean"] == 4.0 and one["sd"] is None and one["ci95"] is None and one["n"] == 1
    two = summarize([1.0, 3.0, None, math.inf])
    # mean 2, sample sd sqrt(2), t(0.975, 1) = 12.7062..., half width 12.7062 * sqrt(2) / sqrt(2)
    assert two["mean"] == 2.0 and two["sd"] == pytest.approx(math.sqrt(2.0))
    assert two["ci95"] == pytest.approx([2.0 - 12.706204736, 2.0 + 12.706204736], rel=1e-9)
    assert summarize([True, 2.0])["n"] == 1
