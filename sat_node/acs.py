"""Attitude control (ACS) slew model: how long a slew between two pointing directions takes.

Model (Nag et al., "Autonomous Scheduling of Agile Spacecraft Constellations with Delay Tolerant
Networking for Reactive Imaging", ICAPS SPARK 2019, section 5; docs/design.md section 1): the slew time
[s] for an angle ``a`` [deg] between the satellite-to-GP vectors before and after is the cubic fit
``t = 6.1974e-6 a^3 + 1.3904e-3 a^2 + 1.4165e-1 a + 4.6231`` plus a 2-sigma margin of 0.4232 s. The
coefficients come from the scenario (``[acs] slew_coeffs_s``, highest power first) and the angle is
computed from the real positions at both times (satellite and GP at the start and at the end of the
slew, ECEF km): the pointing direction changes both because the target changes and because the
satellite has moved.

How we know it is right (tests/unit/test_acs.py): the polynomial against the paper's values at
hand-computed angles (0, 10, 90 deg); the angle against an independent formula
(``atan2(|u x v|, u.v)`` against our ``arccos`` with clipping); ``max_angle_deg`` is the inverse of
``time_s`` (``time_s(max_angle_deg(t)) == t`` to 1e-9 s, and monotone); a coefficient set that is
not increasing on [0, 180] deg is refused with a ValueError naming the key. In whole runs
(tests/system/test_observation_physics.py): consecutive executed observations of each satellite are
at least the paper's slew time apart, for the angle recomputed with sgp4 and WGS-84 written out in
the test.

Not modelled: attitude dynamics (the fit already includes them), settling jitter, wheel momentum.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "SlewModel",
    "SlewModelError",
    "angle_between_deg",
    "dot3",
    "nadir_unit",
    "pointing_unit",
    "slew_angle_deg",
    "unit_vectors",
]


class SlewModelError(ValueError):
    """Slew-model coefficients that cannot be used (message names the key)."""


def unit_vectors(v: np.ndarray) -> np.ndarray:
    """Normalize vectors along the last axis; zero vectors raise ValueError."""
    v = np.asarray(v, dtype=np.float64)
    # np.linalg.norm(v, axis=-1, keepdims=True) computes exactly this for real input:
    # sqrt(add.reduce(v * v, axis=-1)), which adds a 3-vector's squares in order; written out per
    # component (dot3) it is the same sum (tests/unit/test_acs.py checks the bits) without a strided
    # reduction over millions of short rows (this runs for every DP state, plan check and slew)
    n = np.sqrt(dot3(v, v))[..., None] if v.ndim and v.shape[-1] == 3 else np.sqrt(
        np.add.reduce(v * v, axis=-1, keepdims=True))
    if (n == 0.0).any():
        raise ValueError("unit_vectors: zero-length vector (satellite on its target?)")
    return v / n


def pointing_unit(sat_pos_km: np.ndarray, target_km: np.ndarray) -> np.ndarray:
    """Unit satellite-to-target vector(s) [-], broadcasting over leading axes."""
    return unit_vectors(np.asarray(target_km, np.float64) - np.asarray(sat_pos_km, np.float64))


def nadir_unit(sat_pos_km: np.ndarray) -> np.ndarray:
    """Unit vector(s) from the satellite to the Earth's centre (geocentric nadir)."""
    return unit_vectors(-np.asarray(sat_pos_km, np.float64))


def angle_between_deg(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Angle [deg] between (not necessarily unit) vectors along the last axis."""
    u = unit_vectors(u)
    v = unit_vectors(v)
    dot = dot3(u, v) if u.shape[-1] == 3 and v.shape[-1] == 3 else np.sum(u * v, axis=-1)
    return np.degrees(np.arccos(np.clip(dot, -1.0, 1.0)))


def dot3(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``np.sum(u * v, axis=-1)`` of 3-vectors: the products added in order, as numpy's reduction
    does - the same bits, but for the sign of an all-zero sum (-0.0 here, +0.0 there: equal
    numbers, and every caller takes a square root or an arccos of it)."""
    return (u[..., 0] * v[..., 0] + u[..., 1] * v[..., 1]) + u[..., 2] * v[..., 2]


def slew_angle_deg(sat_a_km, target_a_km, sat_b_km, target_b_km) -> np.ndarray:
    """Slew angle [deg] between pointing at target_a from sat_a and at target_b from sat_b (ECEF km)."""
    return angle_between_deg(pointing_unit(sat_a_km, target_a_km), pointing_unit(sat_b_km, target_b_km))


@dataclass(frozen=True)
class SlewModel:
    """Slew time polynomial (highest power first, [s] per deg^k) plus a margin [s]."""

    coeffs_s: tuple[float, ...]
    margin_s: float = 0.0

    def __post_init__(self) -> None:
        c = tuple(float(x) for x in self.coeffs_s)
        object.__setattr__(self, "coeffs_s", c)
        if not c or not all(np.isfinite(c)):
            raise SlewModelError(f"acs.slew_coeffs_s: need finite coefficients, got {list(self.coeffs_s)}")
        if not np.isfinite(self.margin_s) or self.margin_s < 0:
            raise SlewModelError(f"acs.slew_margin_s: must be >= 0, got {self.margin_s}")
        a = np.linspace(0.0, 180.0, 1801)
        t = np.polyval(c, a)
        if t[0] + self.margin_s <= 0 or np.any(np.diff(t) <= 0):
            raise SlewModelError(
                f"acs.slew_coeffs_s: slew time must be positive and increasing on 0..180 deg, got {list(c)}")

    @classmethod
    def from_scenario(cls, sc) -> SlewModel:
        return cls(tuple(sc.acs.slew_coeffs_s), float(sc.acs.slew_margin_s))

    @property
    def min_time_s(self) -> float:
        """Shortest possible slew (zero angle) [s], margin included."""
        return float(self.time_s(0.0))

    def time_s(self, angle_deg) -> np.ndarray:
        """Slew time [s] (margin included) for angle(s) [deg]; vectorized. A single float is
        evaluated with Python floats in np.polyval's order (Horner from 0.0: the same operations,
        the same bits; tests/unit/test_acs.py), without numpy's per-call overhead (the DP's slew
        window is found by stepping through scalar angles)."""
        if type(angle_deg) is float or type(angle_deg) is np.float64:
            a = abs(float(angle_deg))
            y = 0.0
            for c in self.coeffs_s:
                y = y * a + c
            return np.float64(y + self.margin_s)
        a = np.abs(np.asarray(angle_deg, dtype=np.float64))
        return np.polyval(self.coeffs_s, a) + self.margin_s

    def max_angle_deg(self, dt_s) -> np.ndarray:
        """Largest angle [deg] (<= 180) slewable within dt_s [s]; -1 where even 0 deg does not fit.

        Exact inverse of :meth:`time_s` by bisection (60 halvings of [0, 180]: < 1e-15 deg).
        """
        dt = np.asarray(dt_s, dtype=np.float64)
        lo = np.zeros_like(dt)
        hi = np.full_like(dt, 180.0)
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            ok = self.time_s(mid) <= dt
            lo = np.where(ok, mid, lo)
            hi = np.where(ok, hi, mid)
        out = np.where(self.time_s(180.0) <= dt, 180.0, lo)
        return np.where(self.time_s(0.0) > dt, -1.0, out)

    def feasible(self, angle_deg, dt_s, tol_s: float = 1e-9) -> np.ndarray:
        """True where a slew of angle_deg fits in dt_s (within tol_s)."""
        return self.time_s(angle_deg) <= np.asarray(dt_s, np.float64) + tol_s
