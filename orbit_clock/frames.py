"""Reference frames and geodesy: TEME -> Earth-fixed, WGS-84 geodetic <-> ECEF, look angles.

Implements:
- Greenwich mean sidereal time, IAU-82 (Vallado et al., "Revisiting Spacetrack Report #3",
  AIAA 2006-6753, ``gstime``), with UT1 taken equal to UTC (error < 0.9 s of Earth rotation,
  < 0.42 km at the equator).
- TEME -> pseudo Earth-fixed (PEF) by the GMST rotation about z. Polar motion is neglected (its
  effect is < 20 m), so "ECEF" here is PEF, which is also what skyfield's ``TEME`` ->
  ``itrs`` gives with no polar-motion table loaded.
- WGS-84 (NIMA TR8350.2) geodetic latitude/longitude/height <-> ECEF: the closed form one way,
  Bowring's method with two refinements the other; topocentric elevation with respect to the
  ellipsoid normal. These constants are the project's one copy of the WGS-84 ellipsoid.

How we know it is right: tests/unit/test_orbit_frames.py (geodesy: the inverse against the closed
forward transform to 3e-8 m from -10 km to 40000 km, poles included; both directions against
skyfield), tests/unit/test_orbit_propagation.py (ECEF positions against skyfield's TEME -> ITRS) and
tests/unit/test_orbit_isl.py (station elevations and pass times against skyfield).

All angles in names carry their unit (``_deg``/``_rad``), lengths are km, times s.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "C_KM_S",
    "OMEGA_EARTH_RAD_S",
    "WGS84_A_KM",
    "WGS84_B_KM",
    "WGS84_E2",
    "WGS84_F",
    "ecef_to_geodetic",
    "elevation_deg",
    "geodetic_to_ecef_km",
    "gmst_rad",
    "teme_to_ecef",
    "up_unit",
]

WGS84_A_KM = 6378.137
WGS84_F = 1.0 / 298.257223563
WGS84_B_KM = WGS84_A_KM * (1.0 - WGS84_F)
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)
_EP2 = WGS84_E2 / (1.0 - WGS84_E2)  # second eccentricity squared
OMEGA_EARTH_RAD_S = 7.292115146706979e-5  # rotation rate used with GMST-82 [rad/s]
C_KM_S = 299792.458


def gmst_rad(jd_ut1: np.ndarray, fr_ut1: np.ndarray | float = 0.0) -> np.ndarray:
    """Greenwich mean sidereal time [rad] (IAU-82) of a Julian date given as whole + fraction."""
    jd = np.asarray(jd_ut1, dtype=float)
    fr = np.asarray(fr_ut1, dtype=float)
    tut1 = ((jd - 2451545.0) + fr) / 36525.0
    # seconds of time; the 876600 h * 3600 s term is split off and done via the day fraction for
    # precision (one sidereal turn per solar day plus the drift).
    temp = (-6.2e-6 * tut1 + 0.093104) * tut1 * tut1 + 8640184.812866 * tut1 + 67310.54841
    days = (jd - 2451545.0) + fr
    theta = np.deg2rad(temp / 240.0) + 2.0 * np.pi * np.mod(days, 1.0)  # 876600h*3600s/240 = 360 deg/day
    return np.mod(theta, 2.0 * np.pi)


def teme_to_ecef(r_teme_km: np.ndarray, theta_rad: np.ndarray, v_teme_km_s: np.ndarray | None = None):
    """Rotate TEME vectors [..., n_t, 3] to Earth-fixed with GMST ``theta_rad`` [n_t].

    Returns r_ecef_km, or (r_ecef_km, v_ecef_km_s) when a velocity is given (v includes -w x r).
    """
    c, s = np.cos(theta_rad), np.sin(theta_rad)
    r = np.asarray(r_teme_km, dtype=float)
    x = c * r[..., 0] + s * r[..., 1]
    y = -s * r[..., 0] + c * r[..., 1]
    r_ecef = np.stack([x, y, r[..., 2]], axis=-1)
    if v_teme_km_s is None:
        return r_ecef
    v = np.asarray(v_teme_km_s, dtype=float)
    vx = c * v[..., 0] + s * v[..., 1] + OMEGA_EARTH_RAD_S * y
    vy = -s * v[..., 0] + c * v[..., 1] - OMEGA_EARTH_RAD_S * x
    return r_ecef, np.stack([vx, vy, v[..., 2]], axis=-1)


def geodetic_to_ecef_km(lat_deg, lon_deg, alt_km=0.0) -> np.ndarray:
    """WGS-84 geodetic latitude/longitude [deg] and height [km] -> ECEF [..., 3] km."""
    lat = np.deg2rad(np.asarray(lat_deg, dtype=float))
    lon = np.deg2rad(np.asarray(lon_deg, dtype=float))
    h = np.asarray(alt_km, dtype=float)
    n = WGS84_A_KM / np.sqrt(1.0 - WGS84_E2 * np.sin(lat) ** 2)
    x = (n + h) * np.cos(lat) * np.cos(lon)
    y = (n + h) * np.cos(lat) * np.sin(lon)
    z = (n * (1.0 - WGS84_E2) + h) * np.sin(lat)
    return np.stack(np.broadcast_arrays(x, y, z), axis=-1)


def ecef_to_geodetic(r_ecef_km: np.ndarray):
    """ECEF [..., 3] km -> (lat_deg, lon_deg, alt_km) on WGS-84.

    Bowring's parametric-latitude start (Bowring 1976, Survey Review 23(181)) and two fixed-point
    refinements of the latitude with the height formula ``p cos(lat) + z sin(lat) - a^2 / N``, which
    is exact for a given latitude and stable at the poles (no division by cos(lat)). From 10 km below
    the ellipsoid to beyond GEO the result is within 3e-8 m of the closed-form forward transform
    (tests/unit/test_orbit_frames.py).
    """
    r = np.asarray(r_ecef_km, dtype=float)
    x, y, z = r[..., 0], r[..., 1], r[..., 2]
    p = np.hypot(x, y)
    lon = np.arctan2(y, x)
    theta = np.arctan2(z * WGS84_A_KM, p * WGS84_B_KM)
    lat = np.arctan2(z + _EP2 * WGS84_B_KM * np.sin(theta) ** 3, p - WGS84_E2 * WGS84_A_KM * np.cos(theta) ** 3)
    for _ in range(2):  # fixed-point refinement with the pole-stable height formula
        n = WGS84_A_KM / np.sqrt(1.0 - WGS84_E2 * np.sin(lat) ** 2)
        alt = p * np.cos(lat) + z * np.sin(lat) - WGS84_A_KM ** 2 / n
        lat = np.arctan2(z, p * (1.0 - WGS84_E2 * n / (n + alt)))
    n = WGS84_A_KM / np.sqrt(1.0 - WGS84_E2 * np.sin(lat) ** 2)
    sl, cl = np.sin(lat), np.cos(lat)
    alt = p * cl + z * sl - WGS84_A_KM ** 2 / n  # exact for given lat, stable at the poles
    return np.degrees(lat), np.degrees(lon), alt


def up_unit(lat_deg, lon_deg) -> np.ndarray:
    """Ellipsoid normal (local up) unit vectors [..., 3] at geodetic lat/lon [deg]."""
    lat = np.deg2rad(np.asarray(lat_deg, dtype=float))
    lon = np.deg2rad(np.asarray(lon_deg, dtype=float))
    return np.stack(np.broadcast_arrays(np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)), axis=-1)


def elevation_deg(sat_ecef_km: np.ndarray, site_ecef_km: np.ndarray, site_up: np.ndarray) -> np.ndarray:
    """Elevation [deg] of satellites above sites' ellipsoid horizon (broadcasting over leading axes)."""
    d = np.asarray(sat_ecef_km) - np.asarray(site_ecef_km)
    rng = np.linalg.norm(d, axis=-1)
    sin_el = np.einsum("...k,...k->...", d, np.broadcast_to(site_up, d.shape)) / rng
    return np.rad2deg(np.arcsin(np.clip(sin_el, -1.0, 1.0)))
