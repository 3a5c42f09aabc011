"""Walker constellations (Walker, "Satellite constellations", JBIS 37, 1984): i:T/P/F patterns.

- Walker Delta: P planes with RAAN spread over 360 deg (spacing 360/P).
- Walker Star: P planes with RAAN spread over 180 deg (spacing 180/P), as the study's 24/3/1
  near-polar constellation (planes at RAAN 0/60/120 deg; Nag et al. 2019, section 5).
In both, the S = T/P satellites of a plane are 360/S apart in argument of latitude and plane p is
phased F*360/T deg ahead of plane p-1. Satellites are named by plane and slot (from 1):
``sat_PS`` up to 9 planes x 9 slots, ``sat_PPPP_SSSS`` beyond (msgs_json/names.py), in the
scenario's ``sat_names`` order (plane-major).

How we know it is right: tests/unit/test_orbit_propagation.py checks the paper's 24/3/1 values by
hand (RAAN 0/60/120, 45 deg in-plane spacing, 15 deg inter-plane phase, semi-major axis 6378.137 +
altitude km), a 6/3/2 delta pattern worked by hand, and that SGP4 flies the orbits it was given.
"""

from __future__ import annotations

import datetime as _dt
from dataclasses import dataclass

from msgs_json.names import constellation_limits_error, sat_name
from orbit_clock.frames import WGS84_A_KM

__all__ = ["WalkerElements", "walker_elements"]


@dataclass(frozen=True)
class WalkerElements:
    """Circular-orbit elements of one satellite at the scenario epoch.

    sma_km: semi-major axis [km] (taken as SGP4's mean semi-major axis); inc_deg, raan_deg,
    arglat_deg [deg] (argument of latitude = true anomaly + argument of perigee, e = 0).
    """

    name: str
    plane: int
    slot: int
    sma_km: float
    inc_deg: float
    raan_deg: float
    arglat_deg: float
    epoch: _dt.datetime

    @property
    def epoch_utc(self) -> str:
        return self.epoch.strftime("%Y-%m-%dT%H:%M:%S.%f")[:-3] + "Z"


def walker_elements(*, pattern: str, total_sats: int, planes: int, phasing_f: int, altitude_km: float,
                    inclination_deg: float, raan0_deg: float, epoch: _dt.datetime) -> list[WalkerElements]:
    """Element sets of a Walker i:T/P/F pattern ('star' or 'delta'), plane-major (the names' order)."""
    if pattern not in ("star", "delta"):
        raise ValueError(f"walker pattern {pattern!r}: must be 'star' or 'delta'")
    why = constellation_limits_error(total_sats, planes)
    if why is not None:
        raise ValueError(f"walker {total_sats}/{planes}: {why}")
    per_plane = total_sats // planes
    spread_deg = 180.0 if pattern == "star" else 360.0
    sma_km = WGS84_A_KM + altitude_km
    out = []
    for p in range(planes):
        raan = (raan0_deg + p * spread_deg / planes) % 360.0
        for s in range(per_plane):
            arglat = (s * 360.0 / per_plane + p * phasing_f * 360.0 / total_sats) % 360.0
            out.append(WalkerElements(sat_name(p + 1, s + 1, planes, per_plane), p + 1, s + 1, sma_km,
                                      inclination_deg, raan, arglat, epoch))
    return out
