"""Every executed observation of a whole run obeys the field of regard and the slew model.

Local-engine runs of the paper scenario (24 satellites, 1 h, through ``constellation run``), in
distributed mode (each satellite plans onboard) and centralized mode (the ground plans and uplinks at
passes), are read back from their bags (``/sat_XX/observations``, and the plans' times from
``/sat_XX/schedule`` or ``/ground/uplink``). Each executed observation is checked against
geometry computed here, independently of the project's orbit, frame, access and ACS code:

* orbits - the scenario's Walker i:T/P/F pattern restated here (Walker 1984: star planes 180/P deg
  of RAAN apart, 360/S deg in-plane spacing, phasing F*360/T deg), each satellite built directly
  with the ``sgp4`` library's ``Satrec.sgp4init`` (WGS-84 constants, no drag) at the scenario
  epoch, circular, with the Kozai mean motion found so that SGP4's mean semi-major axis is the WGS-84
  equatorial radius plus the altitude (the scenario's definition of ``altitude_km``); TEME -> Earth
  fixed by the ``sgp4`` package's own ``gstime`` (GMST-82, UT1 = UTC);
* ground points - their geodetic latitude/longitude (the grid's definition, checked to lie in its
  region by great-circle distance) converted to ECEF by the WGS-84 closed form written out below;
* angles - ``atan2(|u x v|, u . v)`` (the project's code uses ``arccos``).

Oracles (the study, Nag et al., ICAPS SPARK 2019, section 5):

* field of regard - at its time, the GP of every observation is at most 55 deg off the satellite's
  geocentric nadir and on the near side of the Earth (above the GP's horizon plane);
* slew - consecutive observations of one satellite are at least the slew time of the angle between
  the two satellite-to-GP lines of sight apart (the satellite at its positions at the two times),
  with the paper's fit ``t = 6.1974e-6 a^3 + 1.3904e-3 a^2 + 1.4165e-1 a + 4.6231`` s plus its
  0.4232 s 2-sigma margin (restated here, and the scenario must carry the same numbers). The slew may
  start right after the previous look or, for the first look of a newer plan, when the satellite
  got that plan (its own ``planned_ns``, or the uplink's time; it holds its last target until
  then); the first look of a satellite slews from geocentric nadir from when it got its plan.

Tolerances: 1e-4 deg and 1e-4 s. This geometry agrees with the project's to 1 cm in satellite
position (GMST from the whole Julian date here, from its two parts there) and exactly for the GPs,
i.e. to ~1e-6 deg in angle and ~1e-7 s in slew time; a planner that dropped the 0.42 s slew margin
leaves slews up to 0.42 s short and one with a 5 deg wider field of regard looks 55.1-60 deg off nadir. The checker itself is shown to fail on observations
moved out of the field of regard and on a pair moved closer than the slew time
(``test_the_checks_catch_violations``).
"""

from __future__ import annotations

import itertools
import math
import subprocess
import sys
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from sgp4.api import WGS84, Satrec, jday
from sgp4.propagation import gstime

from bringup.recording.bag import BagReader
from bringup.scenario.config import load_scenario
from msgs_json import codec
from orbit_clock import ground_points

pytestmark = [pytest.mark.system]

HOURS = 1.0

# The study's parameters (Nag et al. 2019, section 5), restated: field of regard and slew fit.
FOR_OFF_NADIR_DEG = 55.0
SLEW_COEFFS_S = (6.1974e-6, 1.3904e-3, 1.4165e-1, 4.6231)  # [s/deg^3, s/deg^2, s/deg, s]
SLEW_MARGIN_S = 0.4232
ANGLE_TOL_DEG = 1e-4
TIME_TOL_S = 1e-4

# WGS-84 (NIMA TR8350.2) and SGP4's WGS-84 gravitational parameter
A_KM = 6378.137
F = 1.0 / 298.257223563
E2 = F * (2.0 - F)
MU_KM3_S2 = 398600.5
SGP4_EPOCH0_JD = 2433281.5  # sgp4init's epoch is counted in days from 1949 Dec 31 00:00 UT


def slew_time_s(angle_deg: float) -> float:
    """The paper's slew fit [s] for an angle [deg], margin included."""
    c3, c2, c1, c0 = SLEW_COEFFS_S
    a = abs(angle_deg)
    return c3 * a**3 + c2 * a**2 + c1 * a + c0 + SLEW_MARGIN_S


def wgs84_ecef_km(lat_deg: float, lon_deg: float, h_km: float = 0.0) -> np.ndarray:
    """Geodetic -> ECEF [km]: N = a / sqrt(1 - e^2 sin^2 lat), x = (N+h) cos lat cos lon,
    y = (N+h) cos lat sin lon, z = (N (1 - e^2) + h) sin lat."""
    la, lo = math.radians(lat_deg), math.radians(lon_deg)
    n = A_KM / math.sqrt(1.0 - E2 * math.sin(la) ** 2)
    return np.array([(n + h_km) * math.cos(la) * math.cos(lo), (n + h_km) * math.cos(la) * math.sin(lo),
                     (n * (1.0 - E2) + h_km) * math.sin(la)])


def angle_deg(u: np.ndarray, v: np.ndarray) -> float:
    return math.degrees(math.atan2(float(np.linalg.norm(np.cross(u, v))), float(np.dot(u, v))))


class Orbits:
    """The scenario's Walker satellites, built with sgp4 alone; ``ecef_km(name, t_s)``."""

    def __init__(self, sc):
        c = sc.constellation
        assert c.pattern == "star", "this oracle restates the Walker star pattern only"
        per_plane = c.total_sats // c.planes
        ep = sc.epoch
        self.jd0, self.fr0 = jday(ep.year, ep.month, ep.day, ep.hour, ep.minute, ep.second + ep.microsecond * 1e-6)
        sma_km = A_KM + c.altitude_km
        self.sats: dict[str, Satrec] = {}
        for p in range(c.planes):
            for s in range(per_plane):
                raan_deg = (c.raan0_deg + p * 180.0 / c.planes) % 360.0
                arglat_deg = (s * 360.0 / per_plane + p * c.phasing_f * 360.0 / c.total_sats) % 360.0
                n_rad_min = math.sqrt(MU_KM3_S2 / sma_km**3) * 60.0
                for _ in range(50):  # Kozai mean motion whose SGP4 mean semi-major axis is sma_km
                    sat = Satrec()
                    sat.sgp4init(WGS84, "i", len(self.sats) + 1, self.jd0 - SGP4_EPOCH0_JD + self.fr0, 0.0, 0.0,
                                 0.0, 0.0, 0.0, math.radians(c.inclination_deg), math.radians(arglat_deg),
                                 n_rad_min, math.radians(raan_deg))
                    ratio = sat.a * sat.radiusearthkm / sma_km
                    if abs(ratio - 1.0) < 1e-13:
                        break
                    n_rad_min *= ratio**1.5
                assert abs(ratio - 1.0) < 1e-12
                self.sats[f"sat_{p + 1}{s + 1}"] = sat  # sat_PS names (<= 9 planes x 9 slots)
        assert sorted(self.sats) == sorted(sc.sat_names)

    def ecef_km(self, name: str, t_s: float) -> np.ndarray:
        fr = self.fr0 + t_s / 86400.0
        err, r, _ = self.sats[name].sgp4(self.jd0, fr)
        assert err == 0, f"sgp4 error {err} for {name} at {t_s} s"
        th = gstime(self.jd0 + fr)
        c, s = math.cos(th), math.sin(th)
        return np.array([c * r[0] + s * r[1], -s * r[0] + c * r[1], r[2]])


@dataclass(frozen=True)
class Look:
    sat: str
    gp: int
    t_ns: int
    version: int


def check_looks(looks: list[Look], planned_ns: dict[tuple[str, int], int], orbits: Orbits, gp_ecef: dict[int, np.ndarray],
                *, for_deg: float = FOR_OFF_NADIR_DEG, slew=slew_time_s) -> tuple[list[str], list[str], dict]:
    """(field-of-regard violations, slew violations, figures) of executed looks (module docstring).

    ``planned_ns``: (satellite, plan version) -> when the satellite got that plan."""
    for_bad, slew_bad = [], []
    worst_off, min_slack = 0.0, math.inf
    by_sat: dict[str, list[Look]] = defaultdict(list)
    pos: dict[Look, np.ndarray] = {}
    for o in looks:
        r = orbits.ecef_km(o.sat, o.t_ns * 1e-9)
        g = gp_ecef[o.gp]
        pos[o] = r
        off = angle_deg(-r, g - r)
        worst_off = max(worst_off, off)
        if off > for_deg + ANGLE_TOL_DEG or np.dot(r - g, g) <= 0.0:
            for_bad.append(f"{o.sat} GP {o.gp} at {o.t_ns * 1e-9:.3f} s: {off:.6f} deg off nadir")
        by_sat[o.sat].append(o)
    for sat, lst in by_sat.items():
        lst.sort(key=lambda o: (o.t_ns, o.gp))
        first = lst[0]
        t_plan = planned_ns[(sat, first.version)]
        r0 = orbits.ecef_km(sat, t_plan * 1e-9)
        need = slew(angle_deg(-r0, gp_ecef[first.gp] - pos[first]))
        have = (first.t_ns - t_plan) * 1e-9
        min_slack = min(min_slack, have - need)
        if have + TIME_TOL_S < need:
            slew_bad.append(f"{sat} first look GP {first.gp} at {first.t_ns * 1e-9:.3f} s: {have:.3f} s from nadir "
                            f"at its plan < slew {need:.3f} s")
        for a, b in itertools.pairwise(lst):
            u_b = gp_ecef[b.gp] - pos[b]
            starts = [(a.t_ns, pos[a])]  # slew right after the previous look
            t_plan = planned_ns[(sat, b.version)]
            if b.version != a.version and a.t_ns < t_plan <= b.t_ns:  # or when the plan holding b was made
                starts.append((t_plan, orbits.ecef_km(sat, t_plan * 1e-9)))
            slack = max((b.t_ns - t0) * 1e-9 - slew(angle_deg(gp_ecef[a.gp] - r0, u_b)) for t0, r0 in starts)
            min_slack = min(min_slack, slack)
            if slack + TIME_TOL_S < 0.0:
                slew_bad.append(f"{sat} GP {a.gp} at {a.t_ns * 1e-9:.3f} s -> GP {b.gp} at {b.t_ns * 1e-9:.3f} s: "
                                f"{-slack:.3f} s short of the slew time")
    return for_bad, slew_bad, {"worst_off_nadir_deg": worst_off, "min_slew_slack_s": min_slack}


@pytest.fixture(scope="module", params=["distributed", "centralized"])
def run(request, tmp_path_factory):
    """The run's looks and plan times, its scenario's orbits and GP positions (independent)."""
    out = tmp_path_factory.mktemp("physics") / request.param
    cmd = [sys.executable, "-m", "bringup.cli", "run", "--scenario", "paper", "--engine", "local", "--hours",
           str(HOURS), "--mode", request.param, "--out", str(out), "--no-plots", "--no-progress"]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=600, check=False)
    assert r.returncode == 0, r.stderr[-3000:]
    sc = load_scenario("paper").with_overrides(hours=HOURS)
    assert sc.instrument.for_off_nadir_deg == FOR_OFF_NADIR_DEG
    assert tuple(sc.acs.slew_coeffs_s) == SLEW_COEFFS_S and sc.acs.slew_margin_s == SLEW_MARGIN_S
    looks, planned = [], {}
    with BagReader(Path(out) / "bag") as bag:
        topics = [t.topic for t in bag.topics() if t.topic.endswith(("/observations", "/schedule", "/ground/uplink"))]
        for env in bag.envelopes(topics):
            m = codec.decode(env.topic, env.data)
            if env.topic.endswith("/observations"):
                looks.append(Look(m.sat, m.gp, m.t_ns, m.schedule_version))
            elif env.topic == "/ground/uplink":  # the satellite has the ground's plan from the uplink on
                planned[(m.sat, m.schedule.version)] = max(m.t_ns, m.schedule.planned_ns)
            elif request.param == "distributed":
                planned[(m.sat, m.version)] = m.planned_ns
    gps = ground_points(sc)
    gp_ecef = {}
    for g in {o.gp for o in looks}:
        lat, lon = float(gps.lat_deg[g]), float(gps.lon_deg[g])
        reg = sc.regions.list[int(gps.region_index[g])]
        # the GP lies in its region: within the square's half diagonal of the centre (haversine, 6371 km)
        dlat, dlon = math.radians(lat - reg.lat_deg), math.radians(lon - reg.lon_deg)
        h = math.sin(dlat / 2) ** 2 + math.cos(math.radians(lat)) * math.cos(math.radians(reg.lat_deg)) * math.sin(dlon / 2) ** 2
        assert 2 * 6371.0 * math.asin(math.sqrt(h)) <= reg.size_km / math.sqrt(2) * 1.01, f"GP {g} outside {reg.name}"
        gp_ecef[g] = wgs84_ecef_km(lat, lon)
    return {"looks": looks, "planned": planned, "orbits": Orbits(sc), "gp_ecef": gp_ecef, "sc": sc}


def test_run_has_observations_of_every_plane(run):
    looks = run["looks"]
    assert len(looks) >= 200, f"only {len(looks)} observations: the checks below would be weak"
    assert {o.sat[:5] for o in looks} == {"sat_1", "sat_2", "sat_3"}
    assert all(0 <= o.t_ns <= run["sc"].horizon_ns for o in looks)


def test_every_observation_is_in_the_field_of_regard(run):
    for_bad, _, fig = check_looks(run["looks"], run["planned"], run["orbits"], run["gp_ecef"])
    assert not for_bad, f"{len(for_bad)} of {len(run['looks'])} observations outside the FOR: {for_bad[:5]}"
    assert fig["worst_off_nadir_deg"] <= FOR_OFF_NADIR_DEG + ANGLE_TOL_DEG


def test_consecutive_observations_leave_the_slew_time(run):
    _, slew_bad, fig = check_looks(run["looks"], run["planned"], run["orbits"], run["gp_ecef"])
    assert not slew_bad, f"{len(slew_bad)} slews too short: {slew_bad[:5]}"
    assert fig["min_slew_slack_s"] >= -TIME_TOL_S


def test_the_checks_catch_violations(run):
    """The checker flags a look moved 10 min away from its pass (out of the FOR) and a look moved to
    1 s after the previous one of its satellite (the shortest slew is 5.05 s)."""
    looks = sorted(run["looks"], key=lambda o: (o.sat, o.t_ns))
    orbits, gp_ecef, planned = run["orbits"], run["gp_ecef"], run["planned"]
    i = next(k for k in range(1, len(looks) - 1) if looks[k].sat == looks[k - 1].sat == looks[k + 1].sat
             and looks[k].version == looks[k - 1].version)
    moved = Look(looks[i].sat, looks[i].gp, looks[i].t_ns - 600 * 10**9, looks[i].version)
    for_bad, _, _ = check_looks([moved], planned, orbits, gp_ecef)
    assert len(for_bad) == 1
    a = looks[i - 1]
    squeezed = looks[:i] + [Look(a.sat, looks[i].gp, a.t_ns + 10**9, a.version)] + looks[i + 1:]
    _, slew_bad, _ = check_looks(squeezed, planned, orbits, gp_ecef)
    assert any(f"-> GP {looks[i].gp} at {(a.t_ns + 10**9) * 1e-9:.3f} s" in s for s in slew_bad), slew_bad
