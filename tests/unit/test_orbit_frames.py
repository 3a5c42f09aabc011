"""WGS-84 geodesy of orbit_clock.frames: the forward transform against skyfield, the inverse against
the closed-form forward transform (to 3e-8 m) and against skyfield's own inverse (to 1 cm)."""

from __future__ import annotations

import numpy as np
import pytest

from orbit_clock.frames import WGS84_A_KM, WGS84_B_KM, ecef_to_geodetic, geodetic_to_ecef_km


def _errors_m(lat, lon, alt_km, la, lo, al):
    """Position error [m] of an inverse result: along the meridian, along the parallel, in height."""
    r_m = (WGS84_A_KM + alt_km) * 1000.0
    dlon = (lo - lon + 180.0) % 360.0 - 180.0
    return (np.abs(np.radians(la - lat)) * r_m, np.abs(np.radians(dlon)) * r_m * np.cos(np.radians(lat)),
            np.abs(al - alt_km) * 1000.0)


@pytest.mark.parametrize("alt_range_km", [(-10.0, 10.0), (300.0, 2000.0), (2000.0, 40000.0)])
@pytest.mark.parametrize("lat_range_deg", [(-90.0, 90.0), (80.0, 89.99), (89.99, 90.0)])
def test_inverse_against_the_closed_form_forward_transform(alt_range_km, lat_range_deg):
    """Oracle: geodetic -> ECEF is a closed form; its inverse must give the point back to 3e-8 m,
    near the poles too (the height formula divides by nothing that vanishes there)."""
    rng = np.random.default_rng(7)
    n = 5000
    lat = rng.uniform(*lat_range_deg, n) * rng.choice([-1.0, 1.0], n)
    lon = rng.uniform(-180.0, 180.0, n)
    alt = rng.uniform(*alt_range_km, n)
    la, lo, al = ecef_to_geodetic(geodetic_to_ecef_km(lat, lon, alt))
    e_lat, e_lon, e_h = _errors_m(lat, lon, alt, la, lo, al)
    assert max(e_lat.max(), e_lon.max(), e_h.max()) < 3e-8


def test_inverse_by_hand_on_the_axes():
    """The semi-axes: a point above the equator and one above the pole."""
    assert ecef_to_geodetic([WGS84_A_KM + 710.0, 0.0, 0.0]) == pytest.approx((0.0, 0.0, 710.0), abs=1e-9)
    la, _, al = ecef_to_geodetic([0.0, 0.0, WGS84_B_KM + 710.0])
    assert la == pytest.approx(90.0, abs=1e-12) and al == pytest.approx(710.0, abs=1e-9)
    la, _, al = ecef_to_geodetic([0.0, 0.0, -WGS84_B_KM])
    assert la == pytest.approx(-90.0, abs=1e-12) and al == pytest.approx(0.0, abs=1e-9)
    # broadcasting over leading axes
    la, lo, al = ecef_to_geodetic(np.zeros((4, 2, 3)) + [WGS84_A_KM, 0.0, 0.0])
    assert la.shape == lo.shape == al.shape == (4, 2)


def test_forward_and_inverse_against_skyfield():
    """Independent implementation: skyfield's wgs84 (forward to 1 mm; its inverse, three fixed-point
    iterations from the geocentric latitude, to 1 cm at LEO heights)."""
    from skyfield.api import load, wgs84
    from skyfield.framelib import itrs
    from skyfield.positionlib import build_position

    rng = np.random.default_rng(1)
    lat, lon, alt = rng.uniform(-89, 89, 50), rng.uniform(-180, 180, 50), rng.uniform(-0.5, 800, 50)
    xyz = geodetic_to_ecef_km(lat, lon, alt)
    t = load.timescale(builtin=True).utc(2000, 1, 1, 12)
    rot = itrs.rotation_at(t)  # ICRS -> ITRS
    for k in range(len(lat)):
        sky = wgs84.latlon(lat[k], lon[k], elevation_m=alt[k] * 1000).itrs_xyz.km
        np.testing.assert_allclose(xyz[k], sky, atol=1e-6)
        au = xyz[k] / 149597870.700
        pos = build_position(rot.T @ au, center=399, t=t)
        g = wgs84.geographic_position_of(pos)
        la, lo, al = ecef_to_geodetic(xyz[k])
        e = _errors_m(g.latitude.degrees, g.longitude.degrees, g.elevation.km, la, lo, al)
        assert max(float(x) for x in e) < 0.01
