"""SGP4 propagation of a whole constellation at once (sgp4 ``SatrecArray``).

Implements SGP4 as in Vallado, Crawford, Hujsak, Kelso, "Revisiting Spacetrack Report #3",
AIAA 2006-6753, through the ``sgp4`` package (the authors' C++ core). Each satellite is built with
``sgp4init`` (WGS-84 constants, improved mode, no drag) from its Walker elements at the scenario
epoch; the Kozai mean motion given to SGP4 is solved (fixed point, 1e-9 relative) so that SGP4's
Brouwer mean semi-major axis equals ``sma_km`` exactly. A catalogue satellite (a TLE or OMM element
set, orbit_clock/elements.py) is built from its own elements at their own epoch with the WGS-72
constants they were fitted with; SGP4 propagates it from there to the scenario's times (one
``SatrecArray`` holds both kinds: every record carries its own constants and epoch). Positions come out in TEME and, rotated by
GMST-82 (orbit_clock.frames), in the Earth-fixed frame.

Times: ``t_s`` float seconds since the scenario epoch (the wire uses integer t_ns; convert with
``t_ns * 1e-9``). Output arrays are (n_sat, n_t, 3) in km and km/s.

How we know it is right: tests/unit/test_orbit_propagation.py runs the same SGP4 path
(``Satrec`` -> ``SatrecArray``) on the Vallado verification TLEs shipped in the sgp4 wheel
(SGP4-VER.TLE) and matches their published tcppver.out vectors to 1 m and 1 mm/s, and checks a
Walker satellite's radius/inclination and ECEF positions against skyfield.
"""

from __future__ import annotations

import datetime as _dt
import math

import numpy as np
from sgp4.api import WGS84, Satrec, SatrecArray, jday

from orbit_clock.elements import ElementSet
from orbit_clock.frames import gmst_rad, teme_to_ecef
from orbit_clock.walker import WalkerElements, walker_elements

__all__ = ["MU_WGS84_KM3_S2", "Constellation", "PropagationError", "build_constellation"]

MU_WGS84_KM3_S2 = 398600.5  # sgp4's wgs84 mu [km^3/s^2]
_SGP4_EPOCH0_JD = 2433281.5  # 1949 Dec 31 00:00 UT, origin of sgp4init's epoch argument


class PropagationError(ValueError):
    """SGP4 reported an error for a satellite (decayed, eccentricity out of range...)."""


def _jd_fr(epoch: _dt.datetime) -> tuple[float, float]:
    e = epoch.astimezone(_dt.UTC)
    return jday(e.year, e.month, e.day, e.hour, e.minute, e.second + e.microsecond * 1e-6)


def _satrec_from(el: WalkerElements | ElementSet, satnum: int) -> Satrec:
    if isinstance(el, ElementSet):
        return el.satrec()
    jd, fr = _jd_fr(el.epoch)
    epoch_days = (jd - _SGP4_EPOCH0_JD) + fr
    n_rad_min = math.sqrt(MU_WGS84_KM3_S2 / el.sma_km**3) * 60.0
    for _ in range(20):
        sat = Satrec()
        sat.sgp4init(WGS84, "i", satnum, epoch_days, 0.0, 0.0, 0.0, 0.0, 0.0, math.radians(el.inc_deg),
                     math.radians(el.arglat_deg), n_rad_min, math.radians(el.raan_deg))
        a_km = sat.a * sat.radiusearthkm
        if abs(a_km / el.sma_km - 1.0) < 1e-12:
            break
        n_rad_min *= (a_km / el.sma_km) ** 1.5
    return sat


class Constellation:
    """Satellites propagated together with SGP4.

    names: satellite names (scenario.sat_names order); elements: WalkerElements or ElementSet per
    satellite; epoch: scenario epoch (UTC datetime). Methods take ``t_s`` [s since epoch], 1-D.
    Pickles as its elements and epoch (the SGP4 records are rebuilt on load).
    """

    def __init__(self, elements: list[WalkerElements | ElementSet], epoch: _dt.datetime):
        self.elements = list(elements)
        self.names = [e.name for e in self.elements]
        self._index = {n: i for i, n in reversed(list(enumerate(self.names)))}  # the first of a name, as list.index
        self.epoch = epoch
        self.satrecs = [_satrec_from(e, i + 1) for i, e in enumerate(self.elements)]
        self._array = SatrecArray(self.satrecs)
        self._jd0, self._fr0 = _jd_fr(epoch)

    def __len__(self) -> int:
        return len(self.names)

    def __reduce__(self):
        return (Constellation, (self.elements, self.epoch))

    def index(self, name: str) -> int:
        try:
            return self._index[name]
        except KeyError:
            raise ValueError(f"satellite {name!r}: not in the constellation ({self.names[0]}..{self.names[-1]})") from None

    # ---- time ----------------------------------------------------------------------------
    def jd_fr(self, t_s) -> tuple[np.ndarray, np.ndarray]:
        """Julian date (whole, fraction) arrays of times t_s [s since epoch]."""
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        return np.full(t.shape, self._jd0), self._fr0 + t / 86400.0

    def gmst_rad(self, t_s) -> np.ndarray:
        jd, fr = self.jd_fr(t_s)
        return gmst_rad(jd, fr)

    # ---- whole constellation on a common grid ----------------------------------------------
    def states_teme(self, t_s) -> tuple[np.ndarray, np.ndarray]:
        """(r_teme_km, v_teme_km_s), each (n_sat, n_t, 3)."""
        jd, fr = self.jd_fr(t_s)
        err, r, v = self._array.sgp4(jd, fr)
        if np.any(err):
            i, k = np.argwhere(err)[0]
            raise PropagationError(f"SGP4 error {int(err[i, k])} for {self.names[i]} at t_s={float(np.atleast_1d(t_s)[k])}")
        return r, v

    def positions_teme_km(self, t_s) -> np.ndarray:
        return self.states_teme(t_s)[0]

    def states_ecef(self, t_s) -> tuple[np.ndarray, np.ndarray]:
        """(r_ecef_km, v_ecef_km_s), each (n_sat, n_t, 3), Earth-fixed (PEF, no polar motion)."""
        r, v = self.states_teme(t_s)
        return teme_to_ecef(r, self.gmst_rad(t_s), v)

    def positions_ecef_km(self, t_s) -> np.ndarray:
        r = self.positions_teme_km(t_s)
        return teme_to_ecef(r, self.gmst_rad(t_s))

    # ---- scattered (satellite, time) pairs ---------------------------------------------------
    def positions_ecef_km_at(self, sat_idx, t_s) -> np.ndarray:
        """ECEF positions (n, 3) km of satellite sat_idx[k] at t_s[k] (same-length 1-D arrays)."""
        sat_idx = np.asarray(sat_idx, dtype=np.int64)
        t = np.asarray(t_s, dtype=float)
        out = np.empty((t.size, 3))
        theta = self.gmst_rad(t)
        jd, fr = self.jd_fr(t)
        if sat_idx.size and sat_idx.size == t.size and (sat_idx == sat_idx[0]).all():
            # one satellite (a track, a slew-angle position): the same calls without np.unique and
            # the masked copies (called once per executed observation)
            i = int(sat_idx[0])
            err, r, _ = self.satrecs[i].sgp4_array(jd, fr)
            if np.any(err):
                raise PropagationError(f"SGP4 error {int(err[err != 0][0])} for {self.names[i]}")
            return teme_to_ecef(r, theta)
        # one group of positions per satellite, in their given order (a stable sort: O(n log n),
        # where one mask per satellite would be O(n * satellites)); the rotation to Earth-fixed is
        # element by element, so it is made once for all of them (the same numbers as group by group:
        # tests/unit/test_speed_paths.py)
        order = np.argsort(sat_idx, kind="stable")
        cuts = np.flatnonzero(np.diff(sat_idx[order])) + 1
        for m in np.split(order, cuts) if order.size else ():
            i = int(sat_idx[m[0]])
            err, r, _ = self.satrecs[i].sgp4_array(jd[m], fr[m])
            if np.any(err):
                raise PropagationError(f"SGP4 error {int(err[err != 0][0])} for {self.names[i]}")
            out[m] = r
        return teme_to_ecef(out, theta)

    def track_ecef_km(self, sat: str | int, t_s) -> np.ndarray:
        """ECEF positions (n, 3) km of one satellite (name or index) at times t_s [s] (1-D)."""
        i = self.index(sat) if isinstance(sat, str) else int(sat)
        t = np.asarray(t_s, dtype=float)
        return self.positions_ecef_km_at(np.full(t.size, i), t)


def build_constellation(scenario) -> Constellation:
    """The scenario's constellation at its epoch (names in scenario.sat_names order): its
    ``orbit_elements`` (bringup/scenario/fleet.py: Walker and catalogue satellites), or for a plain
    Walker description its ``constellation`` keys."""
    els = getattr(scenario, "orbit_elements", None)
    if els is not None:
        return Constellation(els, scenario.epoch)
    c = scenario.constellation
    els = walker_elements(pattern=c.pattern, total_sats=c.total_sats, planes=c.planes, phasing_f=c.phasing_f,
                          altitude_km=c.altitude_km, inclination_deg=c.inclination_deg, raan0_deg=c.raan0_deg,
                          epoch=scenario.epoch)
    assert [e.name for e in els] == scenario.sat_names
    return Constellation(els, scenario.epoch)
