"""GP access windows: skyfield find_events oracle, brute-force grid, invariants (orbit_clock.access)."""

from __future__ import annotations

import numpy as np
import pytest

from orbit_clock import access_windows, access_windows_bruteforce, build_constellation, ground_points
from orbit_clock.access import off_nadir_deg, off_nadir_profile, visibility_matrix

LIMIT = 55.0


@pytest.fixture(scope="module")
def setup(paper_scenario):
    c = build_constellation(paper_scenario)
    return paper_scenario, c, ground_points(paper_scenario)


def test_off_nadir_hand_cases():
    sat = np.array([7000.0, 0, 0])
    assert off_nadir_deg(sat, np.array([6378.0, 0, 0])) == pytest.approx(0.0, abs=1e-9)
    # GP seen 45 deg off nadir: offset perpendicular equal to the distance along nadir
    assert off_nadir_deg(sat, np.array([6000.0, 1000.0, 0])) == pytest.approx(45.0, abs=1e-9)
    many = off_nadir_deg(np.tile(sat, (4, 1)), np.array([[6000.0, 1000.0, 0]] * 4))
    assert many.shape == (4,)


def _mask_equivalent_events(es, site, t0, t1, ts):
    """Rise/set times [s after t0] where skyfield's geodetic elevation crosses the mask that is
    equivalent to 55 deg off-nadir for the actual geometry (Newton on the mask with find_events)."""
    from skyfield.api import wgs84
    from skyfield.framelib import itrs

    gp = site.itrs_xyz.km
    nominal = np.rad2deg(np.arccos(np.sin(np.deg2rad(LIMIT)) * (6378.137 + 710.0) / 6378.137))  # 24.448
    tt, ev = es.find_events(site, t0, t1, altitude_degrees=nominal - 1.5)
    out = []
    for t_ev, kind in zip(tt, ev):
        if kind == 1:
            continue
        t_k, mask = t_ev, nominal
        for _ in range(4):
            lo, hi = ts.tt_jd(t_k.tt - 40 / 86400), ts.tt_jd(t_k.tt + 40 / 86400)
            t2, e2 = es.find_events(site, lo, hi, altitude_degrees=mask)
            hits = [t for t, k in zip(t2, e2) if k == kind]
            if not hits:
                break
            t_k = hits[0]
            sat = es.at(t_k).frame_xyz(itrs).km
            eta = float(off_nadir_deg(sat, gp))
            el = (es - wgs84.latlon(site.latitude.degrees, site.longitude.degrees)).at(t_k).altaz()[0].degrees
            r_s, r_g = np.linalg.norm(sat), np.linalg.norm(gp)
            dedeta = -(r_s * np.cos(np.deg2rad(eta))) / (r_g * np.sin(np.deg2rad(el)))
            mask = el + dedeta * (LIMIT - eta)
        else:
            out.append((int(kind), (t_k.tt - t0.tt) * 86400.0, mask))
            continue
        out.append((int(kind), None, mask))
    return out


def test_access_against_skyfield_find_events(setup):
    from skyfield.api import EarthSatellite, load, wgs84

    sc, c, g = setup
    ts = load.timescale()
    t0 = ts.from_datetime(sc.epoch)
    horizon = 21600.0
    t1 = ts.tt_jd(t0.tt + horizon / 86400)
    sats = [0, 9, 17]
    gids = [0, 44, 120, 255, 399, 455]  # GPs in all five regions
    w = access_windows(c, g, 0.0, horizon, LIMIT, sats=sats)
    n_cmp = 0
    for s in sats:
        es = EarthSatellite.from_satrec(c.satrecs[s], ts)
        for gid in gids:
            site = wgs84.latlon(g.lat_deg[gid], g.lon_deg[gid])
            ours = w.select((w.sat == s) & (w.gp == gid))
            edges = _mask_equivalent_events(es, site, t0, t1, ts)
            sky = [(k, t) for k, t, _ in edges if t is not None]
            rises = [t for k, t in sky if k == 0]
            sets = [t for k, t in sky if k == 2]
            # every skyfield edge has one of ours within 2 s, and vice versa
            for t in rises:
                assert np.min(np.abs(ours.start_s - t)) <= 2.0, (s, gid, t, ours.start_s)
                n_cmp += 1
            for t in sets:
                assert np.min(np.abs(ours.end_s - t)) <= 2.0, (s, gid, t, ours.end_s)
                n_cmp += 1
            for a, b in zip(ours.start_s, ours.end_s):
                if a > 0.0:
                    assert rises and np.min(np.abs(np.array(rises) - a)) <= 2.0
                if b < horizon:
                    assert sets and np.min(np.abs(np.array(sets) - b)) <= 2.0
    assert n_cmp >= 16  # the choice of satellites/GPs above gives real passes to compare


def test_coarse_refine_matches_bruteforce_grid(setup):
    _sc, c, g = setup
    sats = [0, 5, 12, 20]
    fast = access_windows(c, g, 0.0, 3600.0, LIMIT, sats=sats)
    ref = access_windows_bruteforce(c, g, 0.0, 3600.0, LIMIT, sats=sats)
    assert len(ref) > 30
    assert len(fast) == len(ref)
    np.testing.assert_array_equal(fast.sat, ref.sat)
    np.testing.assert_array_equal(fast.gp, ref.gp)
    np.testing.assert_allclose(fast.start_s, ref.start_s, atol=1e-6)
    np.testing.assert_allclose(fast.end_s, ref.end_s, atol=1e-6)


def test_invariants_paper_scale(setup):
    sc, c, g = setup
    horizon = float(sc.scenario.horizon_s)
    w = access_windows(c, g, 0.0, horizon, LIMIT)
    assert len(g) == 500 and len(w) > 1000
    assert np.all(w.start_s >= 0.0) and np.all(w.end_s <= horizon) and np.all(w.end_s > w.start_s)
    assert np.all(w.min_off_nadir_deg <= LIMIT)
    key = w.sat * 10_000 + w.gp
    same = key[1:] == key[:-1]
    assert np.all(w.start_s[1:][same] > w.end_s[:-1][same])  # ordered, non-overlapping per (sat, gp)
    # every region is reached by some satellite in 6 h
    assert set(np.unique(w.region)) == set(range(len(g.region_names)))
    # off-nadir profile is inside the limit within the window and outside just beyond its edges
    rng = np.random.default_rng(3)
    for k in rng.choice(len(w), 25, replace=False):
        _t, eta = off_nadir_profile(c, g, w, int(k))
        assert np.all(eta <= LIMIT + 1e-3)
        assert eta.min() == pytest.approx(w.min_off_nadir_deg[k], abs=0.05)
        if w.start_s[k] > 1.0:
            _, e = visibility_matrix(c, int(w.sat[k]), [w.start_s[k] - 0.5], g, LIMIT, gp_ids=[w.gp[k]])
            assert e[0, 0] > LIMIT


def test_visibility_matrix_agrees_with_windows(setup):
    _sc, c, g = setup
    t = np.arange(0.0, 3600.0, 1.0)
    vis, eta = visibility_matrix(c, "sat_12", t, g, LIMIT)
    assert vis.shape == eta.shape == (t.size, len(g))
    w = access_windows(c, g, 0.0, 3600.0, LIMIT, sats=[1])
    expect = np.zeros_like(vis)
    for a, b, gp in zip(w.start_s, w.end_s, w.gp):
        expect[(t >= a) & (t <= b), gp] = True
    assert vis.any()
    assert np.array_equal(vis, expect)
