"""Slew model (sat_node.acs): polynomial, angle, inverse, validation."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sat_node.acs import SlewModel, SlewModelError, angle_between_deg, slew_angle_deg

PAPER = SlewModel((6.1974e-6, 1.3904e-3, 1.4165e-1, 4.6231), 0.4232)


def test_polynomial_hand_values():
    # hand-computed: t(0) = 4.6231 + 0.4232; t(10) = 0.0061974 + 0.13904 + 1.4165 + 4.6231 + 0.4232
    assert PAPER.time_s(0.0) == pytest.approx(5.0463, abs=1e-12)
    assert PAPER.time_s(10.0) == pytest.approx(6.6080374, abs=1e-9)
    assert PAPER.time_s(90.0) == pytest.approx(4.5179046 + 11.26224 + 12.7485 + 4.6231 + 0.4232, abs=1e-9)
    assert PAPER.time_s(-10.0) == PAPER.time_s(10.0)


def test_from_scenario(paper_scenario):
    m = SlewModel.from_scenario(paper_scenario)
    assert m == PAPER


def test_angle_against_atan2_formula():
    rng = np.random.default_rng(3)
    u = rng.normal(size=(500, 3))
    v = rng.normal(size=(500, 3))
    ref = np.degrees(np.arctan2(np.linalg.norm(np.cross(u, v), axis=1), np.sum(u * v, axis=1)))
    np.testing.assert_allclose(angle_between_deg(u, v), ref, atol=1e-6)


def test_slew_angle_uses_both_positions():
    gp = np.array([6378.0, 0.0, 0.0])
    sat_a = np.array([7088.0, 0.0, 0.0])
    sat_b = np.array([7088.0 * np.cos(0.01), 7088.0 * np.sin(0.01), 0.0])
    # same target, moving satellite -> nonzero angle
    a = slew_angle_deg(sat_a, gp, sat_b, gp)
    assert a > 1.0
    assert slew_angle_deg(sat_a, gp, sat_a, gp) == pytest.approx(0.0, abs=1e-6)


@settings(max_examples=200, deadline=None)
@given(st.floats(min_value=0.0, max_value=200.0))
def test_max_angle_is_inverse(dt):
    a = float(PAPER.max_angle_deg(dt))
    if dt < PAPER.min_time_s:
        assert a == -1.0
    elif a < 180.0:
        assert PAPER.time_s(a) == pytest.approx(dt, abs=1e-9)
        assert PAPER.time_s(a + 1e-6) > dt
    else:
        assert PAPER.time_s(180.0) <= dt


def test_max_angle_monotone():
    a = PAPER.max_angle_deg(np.linspace(0, 150, 3001))
    assert np.all(np.diff(a) >= 0)


@pytest.mark.parametrize("coeffs,margin", [((), 0.0), ((-1.0, 0.0), 0.0), ((1.0, float("nan")), 0.0),
                                           ((1.0, 1.0), -0.5), ((-1e-3, 0.0, 1.0), 0.0)])
def test_bad_coefficients_refused(coeffs, margin):
    with pytest.raises(SlewModelError, match="acs.slew_"):
        SlewModel(coeffs, margin)


def test_unit_vectors_and_angles_are_the_reductions_bit_for_bit():
    """unit_vectors and angle_between_deg add a 3-vector's components in order instead of calling
    numpy's reduction; oracle: the reduction itself (np.linalg.norm's and np.sum's arithmetic) on
    random vectors of every scale, in 1-D, 2-D and broadcast 3-D shapes - the same bits."""
    from sat_node.acs import dot3, unit_vectors

    rng = np.random.default_rng(3)
    for shape in [(3,), (5000, 3), (40, 60, 3)]:
        v = rng.normal(size=shape) * rng.uniform(1e-3, 1e4, size=shape[:-1] + (1,))
        w = rng.normal(size=shape[-1:] if len(shape) == 3 else shape) * 7000.0
        ref_u = v / np.sqrt(np.add.reduce(v * v, axis=-1, keepdims=True))
        assert unit_vectors(v).tobytes() == ref_u.tobytes()
        ref_w = w / np.sqrt(np.add.reduce(w * w, axis=-1, keepdims=True))
        ref_a = np.degrees(np.arccos(np.clip(np.sum(ref_u * ref_w, axis=-1), -1.0, 1.0)))
        assert angle_between_deg(v, w).tobytes() == ref_a.tobytes()
        assert dot3(v, w).tobytes() == np.sum(v * w, axis=-1).tobytes()
