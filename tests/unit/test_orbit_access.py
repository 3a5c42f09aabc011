"""GP access (orbit_clock.access): the off-nadir angle and the field-of-regard bound against closed
forms, the FOR mask's row pre-filter against the test of every pair, access windows against
skyfield find_events, a brute-force grid and invariants."""

from __future__ import annotations

import numpy as np
import pytest

from orbit_clock import access_windows, access_windows_bruteforce, build_constellation, ground_points
from orbit_clock.access import (
    RegionPrefilter,
    _eta_grid,
    _for_chunks,
    _for_mask_all,
    _for_rows,
    for_central_angle_rad,
    for_mask,
    off_nadir_deg,
    off_nadir_profile,
    visibility_matrix,
)

LIMIT = 55.0


@pytest.fixture(scope="module")
def setup(paper_scenario):
    # the footprint spacing (500 GPs, 100 per region): the GP ids picked below are in all five regions
    sc = paper_scenario.with_overrides(gp_spacing_km=8.0)
    c = build_constellation(sc)
    return sc, c, ground_points(sc)


def test_off_nadir_hand_cases():
    sat = np.array([7000.0, 0, 0])
    assert off_nadir_deg(sat, np.array([6378.0, 0, 0])) == pytest.approx(0.0, abs=1e-9)
    # GP seen 45 deg off nadir: offset perpendicular equal to the distance along nadir
    assert off_nadir_deg(sat, np.array([6000.0, 1000.0, 0])) == pytest.approx(45.0, abs=1e-9)
    many = off_nadir_deg(np.tile(sat, (4, 1)), np.array([[6000.0, 1000.0, 0]] * 4))
    assert many.shape == (4,)


def _sphere_geometry(rng, n):
    """Random satellite/GP pairs on a sphere with their closed-form off-nadir angle [deg].

    Satellite at radius r on +z rotated to a random direction, GP at radius rho and central angle lam
    from the sub-satellite point: eta = atan2(rho sin(lam), r - rho cos(lam)) (plane triangle)."""
    r = rng.uniform(6500.0, 45000.0, n)
    rho = rng.uniform(6350.0, 6390.0, n)
    lam = rng.uniform(0.0, np.arccos(rho / r))  # up to the horizon
    az = rng.uniform(0.0, 2 * np.pi, n)
    sat = np.stack([np.zeros(n), np.zeros(n), r], axis=1)
    gp = rho[:, None] * np.stack([np.sin(lam) * np.cos(az), np.sin(lam) * np.sin(az), np.cos(lam)], axis=1)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))  # one random rotation for all
    eta = np.rad2deg(np.arctan2(rho * np.sin(lam), r - rho * np.cos(lam)))
    return sat @ q.T, gp @ q.T, r, rho, lam, eta


def test_off_nadir_against_the_plane_triangle_and_atan2():
    """Oracles: the closed form of the plane triangle (centre, satellite, GP) and the well-conditioned
    atan2(|s x d|, -s.d) formula, to 1e-9 deg from nadir to the horizon, orbits 120 km to GEO."""
    rng = np.random.default_rng(11)
    sat, gp, *_, eta = _sphere_geometry(rng, 5000)
    got = off_nadir_deg(sat, gp)
    d = gp - sat
    ref = np.rad2deg(np.arctan2(np.linalg.norm(np.cross(-sat, d), axis=1), np.einsum("ik,ik->i", -sat, d)))
    assert np.abs(got - eta).max() < 1e-9
    assert np.abs(got - ref).max() < 1e-9
    # the access search's matrix form of the same angle and near-side test
    e, near = _eta_grid(sat[:50], gp[:70])
    np.testing.assert_allclose(e, off_nadir_deg(sat[:50, None, :], gp[None, :70, :]), atol=1e-9)
    np.testing.assert_array_equal(near, np.einsum("tgk,gk->tg", sat[:50, None, :] - gp[None, :70, :], gp[:70]) > 0)


def test_for_central_angle_is_the_largest_visible_central_angle():
    """Oracle: for each (r, rho, eta_max), the largest central angle of a GP within eta_max of nadir
    and above its horizon, found by brute force on a 1e-5 rad grid of central angles (plane triangle).
    Also the closed form at the paper's geometry: 55 deg at 710 km -> 24.448 deg elevation."""
    for r, rho, eta_max in [(7088.137, 6378.137, 55.0), (7088.137, 6356.752, 55.0), (6800.0, 6378.0, 70.0),
                            (7088.0, 6356.0, 66.0), (42164.0, 6378.0, 8.0), (42164.0, 6378.0, 8.8),
                            (6700.0, 6378.0, 0.0), (7000.0, 6378.0, 90.0), (7000.0, 6378.0, 150.0)]:
        lam = np.arange(0.0, np.pi, 1e-5)
        eta = np.rad2deg(np.arctan2(rho * np.sin(lam), r - rho * np.cos(lam)))
        above = r * np.cos(lam) > rho  # the satellite above the GP's horizon
        ok = above & (eta <= eta_max + 1e-12)
        brute = lam[ok].max()
        got = for_central_angle_rad(r, rho, eta_max)
        assert brute - 1e-12 <= got <= brute + 1e-5, (r, rho, eta_max, got, brute)
    # elevation at the FOR edge: 90 deg - eta - lam
    lam = for_central_angle_rad(6378.137 + 710.0, 6378.137, 55.0)
    assert 90.0 - 55.0 - np.rad2deg(lam) == pytest.approx(24.448, abs=1e-3)
    assert for_central_angle_rad(6000.0, 6378.0, 55.0) == pytest.approx(np.pi)  # no bound below the ground


def test_for_mask_row_prefilter_equals_full_test():
    """The FOR mask computed on the pre-filtered rows equals the test of every (time, GP) pair, and
    the off-nadir angles of a row subset are bit-identical to those of the whole array; orbits from
    300 to 36000 km, FOR angles up to beyond the horizon, regions from 50 km to a hemisphere."""
    from dp_instances import circular_walker_ecef_km, square_region_gp_ecef_km

    rng = np.random.default_rng(5)
    kept = total = 0
    for alt, for_deg, size_km, spacing in [(500.0, 55.0, 800.0, 40.0), (300.0, 30.0, 50.0, 5.0),
                                           (1200.0, 80.0, 3000.0, 150.0), (36000.0, 8.0, 6000.0, 400.0),
                                           (700.0, 120.0, 9000.0, 600.0), (500.0, 0.0, 500.0, 50.0)]:
        times = np.arange(0.0, 12000.0, float(rng.choice([7.0, 10.0, 37.0])))
        sats = circular_walker_ecef_km(times, total_sats=4, planes=2, phasing_f=1, altitude_km=alt,
                                       inclination_deg=float(rng.uniform(40, 98)))
        gp = square_region_gp_ecef_km(float(rng.uniform(-60, 60)), float(rng.uniform(-180, 180)), size_km, spacing)
        for s in sats:
            full = _for_mask_all(s, gp, for_deg)
            assert np.array_equal(for_mask(s, gp, for_deg), full)
            rows = _for_rows(s, gp, for_deg)
            kept += len(rows)
            total += len(s)
            sub = rng.choice(len(s), size=min(len(s), 7), replace=False)
            a = off_nadir_deg(s[:, None, :], gp[None, :, :])[sub]
            b = off_nadir_deg(s[sub][:, None, :], gp[None, :, :])
            assert a.tobytes() == b.tobytes()
    assert kept < total  # the filter drops rows


@pytest.mark.parametrize("for_deg", [55.0, 70.0, 0.0])
def test_for_mask_edge_pairs_use_the_reference(for_deg):
    """GPs placed on the FOR's edge (off-nadir = the limit, to rounding) and on the horizon of a
    satellite: the compiled test leaves them undecided (orbit_clock/access_kernels.py) and the mask,
    which decides them with the reference arithmetic, equals the test of every pair. At 70 deg the FOR
    reaches past the horizon, so the horizon GPs are the edge; at 0 deg only nadir is in it."""
    from orbit_clock import access_kernels

    rng = np.random.default_rng(11)
    rho = 6371.0
    sats, gps = [], []
    for _ in range(40):
        r = rho + float(rng.uniform(400.0, 1500.0))
        u = rng.normal(size=3)
        u /= np.linalg.norm(u)
        sats.append(r * u)
        eta = np.radians(for_deg)
        x = r * np.sin(eta) / rho
        lam_for = np.arcsin(x) - eta if x < 1.0 and eta < np.pi / 2 else np.inf
        lam_hor = np.arccos(rho / r)
        for lam in (min(lam_for, lam_hor), lam_hor, 0.0):
            w = np.cross(u, rng.normal(size=3))
            w /= np.linalg.norm(w)
            gps.append(rho * (np.cos(lam) * u + np.sin(lam) * w))
    sat = np.array(sats)
    gp = np.array(gps)
    starts, ends, ok = _for_chunks(sat, gp, for_deg)
    rows = np.flatnonzero(ok.any(axis=1))
    codes = np.zeros((len(sat), len(gp)), np.uint8)
    undecided = access_kernels.for_codes(sat, gp, rows, starts, ends, np.ascontiguousarray(ok[rows]),
                                         float(np.cos(np.radians(for_deg))), codes)
    assert undecided >= 40  # every satellite has an edge GP the kernel does not decide
    full = _for_mask_all(sat, gp, for_deg)
    assert np.array_equal(for_mask(sat, gp, for_deg), full)
    # a satellite on a GP, and fields of regard outside 0..180 deg: the reference's answer, no error
    on = np.array([[7000.0, 0.0, 0.0], [6371.0, 10.0, 0.0]])
    g3 = np.array([[6371.0, 0.0, 0.0], [6371.0, 10.0, 0.0], [0.0, 6371.0, 0.0]])
    with np.errstate(invalid="ignore", divide="ignore"):  # the reference's 0 / 0 on the GP
        for deg in (for_deg, -5.0, np.inf):
            assert np.array_equal(for_mask(on, g3, deg), _for_mask_all(on, g3, deg))
    if for_deg > 0:  # (at 0 deg the reference's arccos near 1 puts nadir itself ~1e-6 deg off)
        assert full[np.arange(40), 3 * np.arange(40) + 2].all()  # the nadir GPs


@pytest.mark.parametrize("for_deg", [55.0, 70.0])
def test_region_prefilter_keeps_every_gp_in_the_for(setup, for_deg):
    """Oracle: the exact FOR mask over every GP on a 1 s grid, 10-min windows over 2 h for six
    satellites; at 70 deg the FOR reaches past the horizon of a 710 km orbit (the bound is then the
    horizon's central angle, not 90 deg - eta)."""
    sc, c, g = setup
    horizon = 7200.0
    pf = RegionPrefilter(c, g, horizon, for_deg)
    kept = dropped = 0
    for sat in c.names[::4]:
        for t0 in np.arange(0.0, horizon, 600.0):
            t = t0 + np.arange(600.0)
            pos = c.positions_ecef_km_at(np.full(t.size, c.index(sat)), t)
            visible = np.flatnonzero(for_mask(pos, g.ecef_km, for_deg).any(axis=0))
            ids = pf.candidate_gp_ids(sat, t0, t0 + 600.0)
            assert set(visible.tolist()) <= set(ids.tolist()), (sat, t0)
            kept += len(ids) > 0
            dropped += len(ids) < len(g)
    assert kept > 0 and dropped > 0  # it keeps some windows and filters others


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
