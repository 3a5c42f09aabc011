"""orbit_clock.windows: the shared steps of every window search, each against an independent oracle."""

from __future__ import annotations

import numpy as np

from orbit_clock.windows import mean_range_km, time_grid, true_runs, windows_from_margin


def test_time_grid_ends_on_t1():
    np.testing.assert_array_equal(time_grid(0.0, 30.0, 10.0), [0.0, 10.0, 20.0, 30.0])
    np.testing.assert_array_equal(time_grid(0.0, 25.0, 10.0), [0.0, 10.0, 20.0, 25.0])
    np.testing.assert_array_equal(time_grid(5.0, 7.0, 10.0), [5.0, 7.0])
    np.testing.assert_array_equal(time_grid(5.0, 5.0, 10.0), [5.0])


def test_true_runs_against_a_python_loop():
    rng = np.random.default_rng(3)
    for _ in range(50):
        inside = rng.random((int(rng.integers(1, 6)), int(rng.integers(1, 40)))) < rng.uniform(0.1, 0.9)
        want = []
        for s, row in enumerate(inside):
            k = 0
            while k < len(row):
                if row[k]:
                    k0 = k
                    while k < len(row) and row[k]:
                        k += 1
                    want.append((s, k0, k))
                else:
                    k += 1
        si, ks, ke = true_runs(inside)
        assert list(zip(si.tolist(), ks.tolist(), ke.tolist())) == want


def test_windows_from_margin_finds_known_roots():
    """Margin sin(w t + phase) per series: its positive stretches start and end at known roots; the
    bisection must place them within tol_s; windows open at the grid's ends start/end there."""
    w = 2 * np.pi / 700.0
    phase = np.array([0.3, 1.9, -2.5])
    t = time_grid(0.0, 3000.0, 10.0)

    def margin_at(idx, tt):
        return np.sin(w * tt + phase[idx])

    margin = np.sin(w * t[None, :] + phase[:, None])
    si, st, en = windows_from_margin(t, margin, margin_at, tol_s=1e-4)
    for s, a, b in zip(si, st, en):
        for edge in (a, b):
            if edge in (t[0], t[-1]):
                continue
            assert abs(np.sin(w * edge + phase[s])) < w * 1e-4  # a root, to the tolerance
        assert np.all(np.sin(w * np.linspace(a, b, 50)[1:-1] + phase[s]) > 0)
    # every positive stretch of each series is one window: two per 700 s period over 3000 s
    assert sorted(set(si.tolist())) == [0, 1, 2] and 12 <= len(si) <= 15


def test_mean_range_against_a_circle():
    """A point on a circle of radius R around a fixed centre stays R away; a point moving along a
    line from distance 0 to D averages D/2 (samples evenly spaced, ends included)."""
    n = 21
    st, en = np.array([0.0, 100.0]), np.array([50.0, 900.0])
    centre = np.array([7000.0, 0.0, 0.0])

    def on_circle(t):
        a = t / 100.0
        return centre + 1234.5 * np.stack([np.zeros_like(a), np.cos(a), np.sin(a)], axis=1)

    got = mean_range_km(on_circle, lambda t: np.tile(centre, (t.size, 1)), st, en, n)
    np.testing.assert_allclose(got, 1234.5, rtol=1e-12)

    def along(t):
        k = np.repeat(np.arange(len(st)), n)
        f = (t - st[k]) / (en[k] - st[k])
        return centre + f[:, None] * np.array([0.0, 800.0, 0.0])

    got = mean_range_km(along, lambda t: np.tile(centre, (t.size, 1)), st, en, n)
    np.testing.assert_allclose(got, 400.0, rtol=1e-12)
    assert mean_range_km(along, along, np.empty(0), np.empty(0), n).shape == (0,)
