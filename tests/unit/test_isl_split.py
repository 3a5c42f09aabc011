"""The ISL contact plan built with its SGP4 work split over processes equals the one-process plan
bit for bit (orbit_clock/isl.py ``workers``, orbit_clock/windows.py refine_runs_split).

Oracle: the one-process path (refine_runs, the mean-range blocks one after the other), itself
checked against brute-force line of sight (tests/unit/test_scale_plans.py, test_orbit_isl.py)."""

from __future__ import annotations

import numpy as np
import pytest

from orbit_clock import build_constellation, isl
from orbit_clock.windows import refine_runs, refine_runs_split, time_grid


@pytest.mark.parametrize("workers", [2, 3])
def test_split_plan_equals_one_process(paper_scenario, monkeypatch, workers):
    sc = paper_scenario.with_overrides(sats=96, planes=6, hours=1.0)
    c = build_constellation(sc)
    one = isl.isl_contact_plan(sc, c)
    # small enough for this plan to be split (bisection and mean-range blocks)
    monkeypatch.setattr(isl, "_SPLIT_MIN_RUNS", 0)
    monkeypatch.setattr(isl, "_MEAN_BLOCK", 97)
    split = isl.isl_contact_plan(sc, c, workers=workers)
    assert len(one) > 1000
    a = [(x.start_s, x.end_s, x.src, x.dst, x.rate_bps, x.range_light_s) for x in one.contacts]
    b = [(x.start_s, x.end_s, x.src, x.dst, x.rate_bps, x.range_light_s) for x in split.contacts]
    assert a == b


def test_split_windows_equal_unrounded(paper_scenario, monkeypatch):
    """The windows before rounding to the ms (isl_windows), bit for bit."""
    sc = paper_scenario.with_overrides(sats=60, planes=6, hours=1.0)
    c = build_constellation(sc)
    h = sc.scenario.horizon_s
    one = isl.isl_windows(c, 0.0, h)
    monkeypatch.setattr(isl, "_SPLIT_MIN_RUNS", 0)
    split = isl.isl_windows(c, 0.0, h, workers=2)
    assert len(one[0]) > 100
    assert all(np.array_equal(x, y) for x, y in zip(one, split, strict=True))


def test_split_bisection_takes_a_part_on_to_the_others_steps():
    """A part whose brackets are all narrow (the grid's short last step) stops early alone; split,
    it goes on to the steps of the part with the wide brackets, as one bisection of all does."""
    t = time_grid(0.0, 100.3, 10.0)  # last step 0.3 s
    roots = {0: 35.123456789, 1: 100.1234567}  # series 0: a run ending mid-grid; series 1: in the last step

    def margin_at(idx, tt):
        r = np.array([roots[int(i)] for i in idx])
        return r - tt  # > 0 before the root

    si = np.array([0, 1])
    ks = np.array([0, 0])
    ke = np.array([4, t.size - 1])  # series 0 inside up to sample 3 (30 s), series 1 up to 100.0
    want = refine_runs(t, si, ks, ke, margin_at, 1e-3)
    got = refine_runs_split(t, si, ks, ke, margin_at, 1e-3, workers=2)
    assert all(np.array_equal(g, w) for g, w in zip(got, want, strict=True))
    assert abs(want[1][0] - roots[0]) < 1e-3 and abs(want[1][1] - roots[1]) < 1e-3
    # part 1 alone would have stopped earlier: a different number (the take-on is what makes them equal)
    alone = refine_runs(t, si[1:], ks[1:], ke[1:], margin_at, 1e-3)
    assert alone[1][0] != want[1][1]
