"""The geometry of an ``aeossp_standard`` case: SGP4 orbits, look angles, the slew law, sun and shadow.

Model (the benchmark's README, "Geometry, Attitude, And Power Semantics"), written from that text:

- Orbits: SGP4 of each satellite's TLE (``sgp4`` library, Vallado et al. AIAA 2006-6753) in TEME,
  rotated to Earth-fixed by GMST-82 (:mod:`orbit_clock.frames`; polar motion and the equation of the
  equinoxes neglected, < 0.5 km at the surface). Targets: WGS-84 geodetic -> ECEF.
- Visible: the satellite is above the target's geocentric horizon, ``(r_sat - r_tgt) . r_tgt/|r_tgt| > 0``.
- Off-nadir: the angle between the nadir direction ``-r_sat`` and the look vector ``r_tgt - r_sat``.
- Slew between two observations: the angle between the inertial look vectors at the end of the
  first and the start of the second (the first observation of a satellite slews from nadir at its
  start), taken in TEME. Time: bang-coast-bang with maximum rate ``w`` and acceleration ``a``:
  ``2 sqrt(theta/a)`` when ``theta <= w^2/a`` (triangular profile), else ``w/a + theta/w``; the
  settle time is added after it.
- Sun: the Astronomical Almanac's low-precision solar coordinates (Vallado, *Fundamentals of
  Astrodynamics and Applications*, 4th ed., Algorithm 29 "SUN", about 0.01 deg), mean equator of
  date, used as TEME. Shadow: a cylinder of the Earth's equatorial radius along the Sun line (the
  satellite is in eclipse when it is behind the Earth, ``r . s < 0``, and within 6378.137 km of the
  Sun line).

How we know it is right: tests/unit/test_aeossp_geometry.py (the Sun against Vallado's Example 5-1
and the equinox/solstice declinations; the slew law against its closed forms and its continuity at
the triangular/trapezoidal switch; off-nadir and visibility against hand-built geometry; SGP4 ECEF
positions at the TLE epoch against the satellite's orbital radius).
"""

from __future__ import annotations

from datetime import datetime

import numpy as np
from sgp4.api import SatrecArray, jday

from orbit_clock.frames import WGS84_A_KM, geodetic_to_ecef_km, gmst_rad

__all__ = ["Orbits", "angle_deg", "off_nadir_deg", "slew_time_s", "sun_unit_teme", "sunlit", "target_ecef_km",
           "visible"]


def _jd(start: datetime, offsets_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    jd0, fr0 = jday(start.year, start.month, start.day, start.hour, start.minute,
                    start.second + start.microsecond * 1e-6)
    fr = fr0 + np.asarray(offsets_s, dtype=float) / 86400.0
    whole = np.floor(fr)
    return jd0 + whole, fr - whole


class Orbits:
    """SGP4 of the case's satellites at offsets [s] from the horizon start: TEME and ECEF [km]."""

    def __init__(self, satellites, start: datetime):
        self.ids = [s.sat_id for s in satellites]
        self._one = {s.sat_id: SatrecArray([s.satrec()]) for s in satellites}
        self.start = start

    def at(self, sat: str, offsets_s):
        """(r_teme [n_t, 3], r_ecef [n_t, 3], gmst [n_t]) of one satellite at the offsets [s]."""
        jd, fr = _jd(self.start, np.atleast_1d(offsets_s))
        err, r, _v = self._one[sat].sgp4(jd, fr)
        if np.any(err):
            raise ValueError(f"SGP4 error {int(np.max(err))} propagating {sat}")
        r = r[0]
        theta = gmst_rad(jd, fr)
        c, s = np.cos(theta), np.sin(theta)
        ecef = np.stack([c * r[:, 0] + s * r[:, 1], -s * r[:, 0] + c * r[:, 1], r[:, 2]], axis=-1)
        return r, ecef, theta


def target_ecef_km(task) -> np.ndarray:
    return geodetic_to_ecef_km(task.lat_deg, task.lon_deg, task.alt_m / 1000.0)


def ecef_to_teme(v_ecef: np.ndarray, theta: np.ndarray) -> np.ndarray:
    c, s = np.cos(theta), np.sin(theta)
    return np.stack([c * v_ecef[..., 0] - s * v_ecef[..., 1], s * v_ecef[..., 0] + c * v_ecef[..., 1],
                     v_ecef[..., 2]], axis=-1)


def angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    na, nb = np.linalg.norm(a, axis=-1), np.linalg.norm(b, axis=-1)
    cos = np.einsum("...k,...k->...", a, b) / (na * nb)
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def off_nadir_deg(sat_ecef: np.ndarray, tgt_ecef: np.ndarray) -> np.ndarray:
    return angle_deg(-sat_ecef, tgt_ecef - sat_ecef)


def visible(sat_ecef: np.ndarray, tgt_ecef: np.ndarray) -> np.ndarray:
    n = tgt_ecef / np.linalg.norm(tgt_ecef, axis=-1, keepdims=True)
    return np.einsum("...k,...k->...", sat_ecef - tgt_ecef, n) > 0.0


def slew_time_s(theta_deg, rate_deg_s: float, acc_deg_s2: float):
    """Bang-coast-bang rest-to-rest time [s] for an angle [deg] (array or scalar)."""
    th = np.maximum(np.asarray(theta_deg, dtype=float), 0.0)
    tri = th <= rate_deg_s * rate_deg_s / acc_deg_s2
    t = np.where(tri, 2.0 * np.sqrt(th / acc_deg_s2), rate_deg_s / acc_deg_s2 + th / rate_deg_s)
    return float(t) if t.ndim == 0 else t


def sun_unit_teme(start: datetime, offsets_s) -> np.ndarray:
    """Unit vector to the Sun [n_t, 3] (Vallado Algorithm 29; mean equator and equinox of date)."""
    jd, fr = _jd(start, np.atleast_1d(offsets_s))
    t = ((jd - 2451545.0) + fr) / 36525.0
    lam_m = np.radians(np.mod(280.460 + 36000.771 * t, 360.0))
    m = np.radians(np.mod(357.5291092 + 35999.05034 * t, 360.0))
    lam = lam_m + np.radians(1.914666471 * np.sin(m) + 0.019994643 * np.sin(2.0 * m))
    eps = np.radians(23.439291 - 0.0130042 * t)
    return np.stack([np.cos(lam), np.cos(eps) * np.sin(lam), np.sin(eps) * np.sin(lam)], axis=-1)


def sunlit(r_teme_km: np.ndarray, sun_unit: np.ndarray) -> np.ndarray:
    """Cylindrical shadow: lit unless behind the Earth and within one Earth radius of the Sun line."""
    proj = np.einsum("...k,...k->...", r_teme_km, sun_unit)
    perp = np.linalg.norm(r_teme_km - proj[..., None] * sun_unit, axis=-1)
    return ~((proj < 0.0) & (perp < WGS84_A_KM))


def sun_distance_au(start: datetime, offsets_s) -> np.ndarray:
    """Earth-Sun distance [AU] of the same algorithm (for its test against Vallado's example)."""
    jd, fr = _jd(start, np.atleast_1d(offsets_s))
    t = ((jd - 2451545.0) + fr) / 36525.0
    m = np.radians(np.mod(357.5291092 + 35999.05034 * t, 360.0))
    return 1.000140612 - 0.016708617 * np.cos(m) - 0.000139589 * np.cos(2.0 * m)

