"""SGP4 propagation, Walker generation, frames and ground points (orbit_clock core)."""

from __future__ import annotations

import subprocess
import sys
from importlib.resources import files

import numpy as np
import pytest
from sgp4.api import WGS72, Satrec, SatrecArray

from orbit_clock import build_constellation, ground_points, walker_elements
from orbit_clock.frames import geodetic_to_ecef_km


def _tcppver():
    """{satnum: [(tsince_min, r_km(3), v_km_s(3))]} from the Vallado verification output."""
    out, cur = {}, None
    for line in (files("sgp4") / "tcppver.out").read_text().splitlines():
        tok = line.split()
        if len(tok) == 2 and tok[1] == "xx":
            cur = out.setdefault(int(tok[0]), [])
        elif tok and cur is not None:
            v = [float(x) for x in tok[:7]]
            cur.append((v[0], np.array(v[1:4]), np.array(v[4:7])))
    return out


def test_sgp4_satrecarray_path_matches_vallado_vectors():
    """The path our Constellation uses (Satrec -> SatrecArray.sgp4 on (jd, fr)) reproduces
    tcppver.out (Vallado et al. AIAA 2006-6753) for every verification satellite it propagates."""
    ref = _tcppver()
    lines = [ln for ln in (files("sgp4") / "SGP4-VER.TLE").read_text().splitlines() if ln[:2] in ("1 ", "2 ")]
    n_cmp = 0
    for l1, l2 in zip(lines[::2], lines[1::2]):
        sat = Satrec.twoline2rv(l1, l2[:69], WGS72)
        rows = ref.get(sat.satnum, [])
        if not rows:
            continue
        tsince = np.array([r[0] for r in rows])
        jd = np.full(tsince.size, sat.jdsatepoch)
        fr = sat.jdsatepochF + tsince / 1440.0
        err, r, v = SatrecArray([sat]).sgp4(jd, fr)
        ok = err[0] == 0
        r_ref = np.array([x[1] for x in rows])
        v_ref = np.array([x[2] for x in rows])
        np.testing.assert_allclose(r[0][ok], r_ref[ok], atol=1e-3, rtol=0)  # 1 m (jd split rounding)
        np.testing.assert_allclose(v[0][ok], v_ref[ok], atol=1e-6, rtol=0)
        n_cmp += int(ok.sum())
    assert n_cmp > 400


def test_walker_paper_pattern(paper_scenario):
    els = build_constellation(paper_scenario).elements
    assert [e.name for e in els] == paper_scenario.sat_names
    assert sorted({e.raan_deg for e in els}) == [0.0, 60.0, 120.0]
    plane1 = [e.arglat_deg for e in els if e.plane == 1]
    assert plane1 == [45.0 * k for k in range(8)]
    # F = 1: plane p is 1*360/24 = 15 deg ahead of plane p-1
    assert [e.arglat_deg for e in els if e.slot == 1] == [0.0, 15.0, 30.0]
    assert all(e.sma_km == pytest.approx(6378.137 + 710.0) and e.inc_deg == 98.5 for e in els)
    delta = walker_elements(pattern="delta", total_sats=6, planes=3, phasing_f=2, altitude_km=500, inclination_deg=53,
                            raan0_deg=10.0, epoch=paper_scenario.epoch)
    assert [e.raan_deg for e in delta] == [10.0, 10.0, 130.0, 130.0, 250.0, 250.0]
    assert [e.arglat_deg for e in delta] == [0.0, 180.0, 120.0, 300.0, 240.0, 60.0]
    with pytest.raises(ValueError, match="pattern"):
        walker_elements(pattern="ring", total_sats=6, planes=3, phasing_f=0, altitude_km=500, inclination_deg=53,
                        raan0_deg=0, epoch=paper_scenario.epoch)


def test_constellation_orbits_are_the_walker_orbits(paper_scenario):
    c = build_constellation(paper_scenario)
    t = np.arange(0.0, 6000.0, 60.0)
    r, v = c.states_teme(t)
    assert r.shape == v.shape == (24, t.size, 3)
    radius = np.linalg.norm(r, axis=-1)
    # SGP4 mean radius is the Walker sma; J2 short-period terms move it by < 15 km
    assert np.abs(radius.mean(axis=1) - (6378.137 + 710.0)).max() < 5.0
    assert np.abs(radius - (6378.137 + 710.0)).max() < 15.0
    h = np.cross(r, v)
    inc = np.rad2deg(np.arccos(h[..., 2] / np.linalg.norm(h, axis=-1)))
    assert np.abs(inc - 98.5).max() < 0.1
    raan = np.rad2deg(np.arctan2(h[:, 0, 0], -h[:, 0, 1])) % 360.0
    np.testing.assert_allclose(raan[[0, 8, 16]], [0.0, 60.0, 120.0], atol=0.1)


def test_ecef_against_skyfield(paper_scenario):
    from skyfield.api import EarthSatellite, load
    from skyfield.framelib import itrs

    c = build_constellation(paper_scenario)
    ts = load.timescale()
    t_s = np.array([0.0, 1234.5, 10000.0, 21600.0])
    r = c.positions_ecef_km(t_s)
    r_teme = c.positions_teme_km(t_s)
    e0 = ts.from_datetime(paper_scenario.epoch)
    tt = ts.tt_jd(e0.tt + t_s / 86400.0)
    for i in (0, 13, 23):
        es = EarthSatellite.from_satrec(c.satrecs[i], ts)
        sky = es.at(tt).frame_xyz(itrs).km.T
        # skyfield applies UT1-UTC (~0.36 s in 2000) and polar motion from its tables: < 0.5 km
        assert np.linalg.norm(r[i] - sky, axis=-1).max() < 0.5
        assert np.abs(np.linalg.norm(r[i], axis=-1) - np.linalg.norm(r_teme[i], axis=-1)).max() < 1e-9
    one = c.positions_ecef_km_at([5, 5, 7], [0.0, 1234.5, 10000.0])
    np.testing.assert_allclose(one, np.stack([r[5, 0], r[5, 1], r[7, 2]]), atol=1e-9)
    # one satellite's track, by name or index
    np.testing.assert_allclose(c.track_ecef_km(c.names[13], t_s), r[13], atol=1e-9)
    np.testing.assert_array_equal(c.track_ecef_km(13, t_s), c.track_ecef_km(c.names[13], t_s))


def test_ground_points_paper(paper_scenario):
    """Nyquist sampling of the 8 km footprint, as the study: 4 km apart, 20 x 20 = 400 per region."""
    g = ground_points(paper_scenario)
    assert len(g) == 2000 and g.region_names[0] == "Dhaka"
    assert np.bincount(g.region_index).tolist() == [400] * 5
    np.testing.assert_array_equal(g.ids, np.arange(2000))
    # id order: region, then row (north -> south), then column (west -> east)
    d = g.in_region("Dhaka")
    assert np.all(np.diff(g.lat_deg[d].reshape(20, 20)[:, 0]) < 0)
    assert np.all(np.diff(g.lon_deg[d].reshape(20, 20)[0, :]) > 0)
    # neighbours are 4 km apart along the surface (chord on the ellipsoid: independent of the grid maths)
    for r in range(5):
        ids = g.in_region(r).reshape(20, 20)
        ew = np.linalg.norm(g.ecef_km[ids[:, 1:]] - g.ecef_km[ids[:, :-1]], axis=-1)
        ns = np.linalg.norm(g.ecef_km[ids[1:, :]] - g.ecef_km[ids[:-1, :]], axis=-1)
        np.testing.assert_allclose(ew, 4.0, rtol=1e-3)
        np.testing.assert_allclose(ns, 4.0, rtol=1e-3)
        centre = geodetic_to_ecef_km(g.region_center_lat_deg[r], g.region_center_lon_deg[r])
        assert np.linalg.norm(g.ecef_km[ids] - centre, axis=-1).max() == pytest.approx(38.0 * 2**0.5, rel=5e-3)
    # the footprint spacing of earlier releases: 10 x 10, 8 km apart
    g8 = ground_points(paper_scenario.with_overrides(gp_spacing_km=8.0))
    assert np.bincount(g8.region_index).tolist() == [100] * 5
    assert g.region_id("London") == 3
    with pytest.raises(ValueError, match="not one of"):
        g.region_id("Paris")


def test_core_modules_import_without_rclpy():
    code = ("import sys; sys.modules['rclpy'] = None\n"
            "import orbit_clock, orbit_clock.walker, orbit_clock.frames, orbit_clock.propagation, "
            "orbit_clock.ground_points, orbit_clock.access, orbit_clock.isl, orbit_clock.ground_passes, "
            "orbit_clock.priority\n")
    r = subprocess.run([sys.executable, "-c", code], check=False, capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
