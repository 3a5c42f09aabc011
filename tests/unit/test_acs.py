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


def test_scalar_slew_time_is_polyval_bit_for_bit():
    """A float angle goes through Python floats, an array through np.polyval: the same bits, for the
    study's coefficients and random ones, at 0, 180, negative angles and random ones."""
    rng = np.random.default_rng(3)
    models = [PAPER] + [
        SlewModel(tuple(rng.uniform(0.01, 1.0, int(rng.integers(2, 6)))), float(rng.uniform(0.0, 1.0)))
        for _ in range(20)]
    angles = np.concatenate([[0.0, 180.0, -37.25, 1e-300], rng.uniform(-180.0, 180.0, 200)])
    for m in models:
        vec = m.time_s(angles)
        for a, want in zip(angles, vec):
            for x in (float(a), np.float64(a)):
                got = m.time_s(x)
                assert type(got) is np.float64 and got.tobytes() == np.float64(want).tobytes()
