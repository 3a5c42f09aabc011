"""The aeossp geometry (bringup/benchmarks/aeossp/geometry.py): the Sun against Vallado's Example
5-1 and the 2026 equinox/solstice declinations, the bang-coast-bang slew law against its closed
forms, off-nadir and visibility against hand-built vectors, shadow on both sides of the Earth."""

from __future__ import annotations

from datetime import UTC, datetime

import numpy as np
import pytest

from bringup.benchmarks.aeossp.case import read_case
from bringup.benchmarks.aeossp.geometry import (
    Orbits,
    off_nadir_deg,
    slew_time_s,
    sun_distance_au,
    sun_unit_teme,
    sunlit,
    visible,
)
from tests.unit.aeossp_cases import standard


def test_sun_vallado_example_5_1():
    t = datetime(2006, 4, 2, tzinfo=UTC)
    r_au = sun_unit_teme(t, [0.0])[0] * sun_distance_au(t, [0.0])[0]
    # Vallado, Fundamentals of Astrodynamics and Applications, Example 5-1 (Algorithm 29)
    assert r_au == pytest.approx([0.9771945, 0.1924424, 0.0834308], abs=2e-6)


@pytest.mark.parametrize("when, dec", [(datetime(2026, 3, 20, 14, 46, tzinfo=UTC), 0.0),
                                       (datetime(2026, 6, 21, 8, 24, tzinfo=UTC), 23.436)])
def test_sun_declination_at_equinox_and_solstice(when, dec):
    u = sun_unit_teme(when, [0.0])[0]
    assert np.degrees(np.arcsin(u[2])) == pytest.approx(dec, abs=0.02)


def test_slew_law_closed_forms():
    w, a = 1.0, 0.25                         # triangular up to w^2/a = 4 deg
    assert slew_time_s(2.0, w, a) == pytest.approx(2 * np.sqrt(2.0 / 0.25))
    assert slew_time_s(10.0, w, a) == pytest.approx(1.0 / 0.25 + 10.0)
    assert slew_time_s(4.0 - 1e-9, w, a) == pytest.approx(slew_time_s(4.0 + 1e-9, w, a), abs=1e-6)
    assert slew_time_s(0.0, w, a) == 0.0
    th = np.linspace(0, 90, 181)
    assert np.all(np.diff(slew_time_s(th, w, a)) > 0)


def test_off_nadir_and_visibility_hand_built():
    sat = np.array([7000.0, 0.0, 0.0])
    assert off_nadir_deg(sat, np.array([6378.0, 0.0, 0.0])) == pytest.approx(0.0)
    # target 622 km down and 622 km sideways: 45 deg off nadir
    assert off_nadir_deg(sat, np.array([6378.0, 622.0, 0.0])) == pytest.approx(45.0)
    assert visible(sat, np.array([6378.0, 0.0, 0.0]))
    assert not visible(sat, np.array([0.0, 6378.0, 0.0]))     # 90 deg away: below the horizon


def test_shadow_cylinder():
    s = np.array([1.0, 0.0, 0.0])
    assert sunlit(np.array([7000.0, 0.0, 0.0]), s)
    assert not sunlit(np.array([-7000.0, 0.0, 0.0]), s)
    assert sunlit(np.array([-7000.0, 6400.0, 0.0]), s)        # behind, but outside the cylinder


def test_sgp4_radius_of_the_tiny_case(tmp_path):
    c = read_case(standard(tmp_path / "c")[0])
    r, e, _th = Orbits(c.satellites, c.mission.start).at("sat_a", np.arange(0, 3600, 60.0))
    # 15.2 rev/day: a = (mu / n^2)^(1/3) = 6868 km, near-circular
    assert np.linalg.norm(r, axis=1) == pytest.approx(6868.0, abs=25.0)
    assert np.linalg.norm(e, axis=1) == pytest.approx(np.linalg.norm(r, axis=1))
