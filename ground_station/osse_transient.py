"""A flood-value field with a chosen transiency, episodic events, and the forecast issued at the epoch.

The study's precipitation field (Nag et al., ICAPS SPARK 2019, section 5: a WRF-Hydro OSSE) has a
15-min transiency: what a satellite saw a quarter of an hour ago says little about the ranking of
the GPs now. This module builds a synthetic stand-in whose time scale is a parameter, defined and
*measured* the same way (:func:`rank_correlation`, :func:`measured_transiency_min`): the
transiency is the lag at which the Spearman rank correlation of all GP values falls to 0.5.

Model, per region (own random stream, seeded by ``(seed, crc32(name))``; the susceptibility map is
the storm-cell model's, :func:`ground_station.osse._susceptibility`: rivers and basins):

* **Rain-flood intensity** ``I = c exp(sigma X(g, t))``: ``X`` a zero-mean unit-variance Gaussian
  field, Gaussian spatial correlation of length ``scale_km`` (random Fourier features, ``n_features``
  of them), each feature's two amplitudes an Ornstein-Uhlenbeck process in time with e-folding time
  ``tau`` (exact AR(1) steps from slot to slot), so ``corr(X(g, t), X(g, t + d)) = exp(-d / tau)``.
* **Episodic events** (flash floods, cells that appear without warning): a Poisson number per
  region (``events_per_h``), each a Gaussian bump (radius ``event_radius_km``) of intensity
  ``event_intensity`` that appears at full strength in one slot and drains with e-folding time
  ``event_life`` x transiency.
  ``flash_floods = False`` (scenario key ``value.flash_floods``) leaves them out of truth and
  forecast alike, drawing the same random numbers, so the rest of the field is the same.
* **Value** ``v = 1 + round(255 (1 - exp(-s (b + I + E))))``: integer 1..256, as the storm-cell model.

Choosing ``tau`` for a transiency ``T``: the value is a monotone function of the latent
``ln s + sigma X`` (where the events are absent and ``I >> b``), whose Pearson correlation at lag
``d`` is ``(V_s + sigma^2 exp(-d / tau)) / (V_s + sigma^2)`` (``V_s``: variance of ``ln s`` over the
region's GPs). For Gaussian variables Spearman's rho is ``(6 / pi) asin(r / 2)``; it is 0.5 at
``r = 2 sin(pi / 12) = 0.5176``. ``tau`` is solved from that at ``d = T``. The events, the
background ``b`` and the integer rounding move the measured figure a little: it is measured and
reported, never assumed (tests check it within 20 % of the preset over several seeds).

The forecast (what a planner may know a priori, issued at the epoch with the state of the field
then): the conditional median of the intensity, ``c exp(sigma X(g, 0) exp(-t / tau))`` (the
Ornstein-Uhlenbeck process's conditional mean of ``X``), plus the events already present at the
epoch; the events born later are not in it.

How we know it is right (tests/unit/test_osse_transient.py): the measured transiency is within
20 % of 15 and 60 min on several seeds; :func:`rank_correlation` equals scipy's Spearman on random
fields with ties; the forecast equals the truth at the epoch and contains no event born later; the
same seed gives the same field; without flash floods the field is the one with them wherever no
event reaches (tests/unit/test_osse_resolution.py).
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from ground_station.osse import (
    VALUE_MAX,
    VALUE_MIN,
    OsseError,
    SyntheticParams,
    _susceptibility,
    local_km,
)
from ground_station.osse_stats import measured_transiency_min, spearman

__all__ = ["TransientParams", "lag_correlation_for_half", "tau_for_transiency", "transient_field_arrays",
           "transient_region_values"]

@dataclass(frozen=True)
class TransientParams:
    """Knobs of the transient field (units in names). ``transiency_min`` is the target lag [min]."""

    transiency_min: float = 15.0
    scale_km: float = 10.0
    n_features: int = 256
    sigma: float = 1.0
    intensity: float = 0.6
    background: float = 0.04
    events_per_h: float = 1.0
    event_radius_km: tuple[float, float] = (3.0, 8.0)
    event_intensity: tuple[float, float] = (3.0, 8.0)
    event_life: tuple[float, float] = (1.0, 3.0)
    # False: the events are drawn (the same random stream, so the rest of the field is the same) but
    # not put into the truth or the forecast
    flash_floods: bool = True


def lag_correlation_for_half(s: np.ndarray, p: TransientParams, rng: np.random.Generator,
                             draws: int = 8) -> float:
    """The correlation ``r`` of the dynamic part between two times at which the Spearman rank
    correlation of the values ``v(s, X)`` over these GPs is 0.5, for this susceptibility map
    (module docstring): bisection on ``r`` with ``draws`` fixed pairs of standard normal fields."""
    z1 = rng.standard_normal((draws, s.size))
    z2 = rng.standard_normal((draws, s.size))

    def rho_at(r: float) -> float:
        a = _to_value(s, p.background + p.intensity * np.exp(p.sigma * z1))
        b = _to_value(s, p.background + p.intensity * np.exp(p.sigma * (r * z1 + math.sqrt(1 - r * r) * z2)))
        return float(np.mean([spearman(a[i], b[i]) for i in range(draws)]))

    lo, hi = 0.0, 0.999
    if rho_at(lo) >= 0.5:
        raise OsseError(f"transient OSSE: the static part alone ranks the GPs (Spearman {rho_at(lo):.2f} "
                        ">= 0.5 for independent dynamics): no transiency can be met")
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        if rho_at(mid) < 0.5:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def tau_for_transiency(transiency_s: float, r_half: float) -> float:
    """The e-folding time [s] of the dynamic part whose correlation is ``r_half`` at ``transiency_s``."""
    if not transiency_s > 0:
        raise OsseError(f"transient OSSE: transiency must be > 0, got {transiency_s}")
    return transiency_s / -math.log(r_half)


def transient_region_values(rng: np.random.Generator, x_km: np.ndarray, y_km: np.ndarray, half_km: float,
                            n_slots: int, slot_s: float, p: TransientParams, *, tau_scale: float = 1.0,
                            storm: SyntheticParams | None = None) -> tuple[np.ndarray, np.ndarray, dict]:
    """int16 (truth, forecast) [n_slots, n_pts] for one region, and what was drawn (events, tau).

    ``tau_scale`` multiplies the time constant solved from the transiency (see
    :func:`transient_field_arrays`, which corrects it from the measured field)."""
    s = _susceptibility(rng, x_km, y_km, half_km, storm or SyntheticParams())
    r_half = lag_correlation_for_half(s, p, np.random.default_rng(rng.integers(2 ** 63)))
    tau_s = tau_scale * tau_for_transiency(60.0 * p.transiency_min, r_half)
    m = int(p.n_features)
    k = rng.normal(0.0, 1.0 / p.scale_km, size=(m, 2))           # Gaussian covariance, length scale_km
    phase = x_km[:, None] * k[None, :, 0] + y_km[:, None] * k[None, :, 1]
    cos_f, sin_f = np.cos(phase), np.sin(phase)                    # [n_pts, m]
    a = rng.standard_normal(m)
    b = rng.standard_normal(m)
    rho = math.exp(-slot_s / tau_s)
    t_mid = (np.arange(n_slots) + 0.5) * slot_s
    # events: born uniformly over [-2 h, horizon]; those born at or before the epoch are foreseen
    horizon_s = n_slots * slot_s
    t_first = -7200.0
    n_ev = int(rng.poisson(p.events_per_h * (horizon_s - t_first) / 3600.0))
    events = []
    for _ in range(n_ev):
        events.append({"t0_s": float(rng.uniform(t_first, horizon_s)),
                       "x_km": float(rng.uniform(-half_km, half_km)), "y_km": float(rng.uniform(-half_km, half_km)),
                       "radius_km": float(rng.uniform(*p.event_radius_km)),
                       "intensity": float(rng.uniform(*p.event_intensity)),
                       "life_s": float(rng.uniform(*p.event_life)) * 60.0 * p.transiency_min})
    x0 = (cos_f @ a + sin_f @ b) / math.sqrt(m)                   # X at the first slot's middle
    truth = np.empty((n_slots, x_km.size), dtype=np.int16)
    forecast = np.empty_like(truth)
    for j in range(n_slots):
        if j > 0:
            eps = math.sqrt(1.0 - rho * rho)
            a = rho * a + eps * rng.standard_normal(m)
            b = rho * b + eps * rng.standard_normal(m)
        x = (cos_f @ a + sin_f @ b) / math.sqrt(m)
        ev_all = np.zeros_like(x_km)
        ev_known = np.zeros_like(x_km)
        for e in events if p.flash_floods else ():
            age = t_mid[j] - e["t0_s"]
            if age < 0:
                continue
            bump = e["intensity"] * math.exp(-age / e["life_s"]) * np.exp(
                -0.5 * ((x_km - e["x_km"]) ** 2 + (y_km - e["y_km"]) ** 2) / e["radius_km"] ** 2)
            ev_all += bump
            if e["t0_s"] <= 0.0:
                ev_known += bump
        lead = t_mid[j] - t_mid[0]
        x_f = x0 * math.exp(-lead / tau_s)
        truth[j] = _to_value(s, p.background + p.intensity * np.exp(p.sigma * x) + ev_all)
        forecast[j] = _to_value(s, p.background + p.intensity * np.exp(p.sigma * x_f) + ev_known)
    return truth, forecast, {"tau_s": tau_s, "events": events}


def _to_value(s: np.ndarray, intensity: np.ndarray) -> np.ndarray:
    v = 1.0 + np.rint(255.0 * (1.0 - np.exp(-s * intensity)))
    return np.clip(v, VALUE_MIN, VALUE_MAX).astype(np.int16)


def transient_field_arrays(gps, *, region_names: Sequence[str], region_centers_deg, region_sizes_km,
                           horizon_s: float, slot_s: float, seed: int, params: TransientParams,
                           tolerance: float = 0.03, max_rounds: int = 6) -> tuple[np.ndarray, np.ndarray, dict]:
    """(truth, forecast, meta) int16 [n_slots, n_gp] over ground points ``gps`` (GroundPointArrays).

    The time constant solved per region (module docstring) ignores the episodic events and the
    finite horizon; the field is then measured (:func:`measured_transiency_min`, all GPs) and the
    time constants scaled by ``requested / measured`` and the field drawn again from the same random
    numbers, until the measured transiency is within ``tolerance`` of the request or after
    ``max_rounds`` (the measured figure is in ``meta`` either way). The time constants are calibrated
    on the field with its flash floods; ``params.flash_floods = False`` then draws the same field
    without them."""
    n_slots = math.ceil(horizon_s / slot_s - 1e-9)
    want = float(params.transiency_min)
    scale = 1.0
    rounds = []

    def draw(p: TransientParams, scale: float):
        truth = np.empty((n_slots, len(gps)), dtype=np.int16)
        forecast = np.empty_like(truth)
        drawn = {}
        for r, name in enumerate(region_names):
            idx = np.flatnonzero(gps.region_index == r)
            rng = np.random.default_rng(np.random.SeedSequence([int(seed), zlib.crc32(name.encode("utf-8")), 23]))
            lat0, lon0 = region_centers_deg[r]
            x, y = local_km(gps.lat_deg[idx], gps.lon_deg[idx], lat0, lon0)
            t, f, d = transient_region_values(rng, x, y, 0.5 * float(region_sizes_km[r]), n_slots, slot_s, p,
                                              tau_scale=scale)
            truth[:, idx] = t
            forecast[:, idx] = f
            drawn[name] = d
        return truth, forecast, drawn

    # calibrated with the flash floods in (the field's dynamics do not depend on the switch)
    with_floods = replace(params, flash_floods=True)
    for _ in range(max_rounds):
        truth, forecast, drawn = draw(with_floods, scale)
        got = measured_transiency_min(truth, slot_s)
        rounds.append({"tau_scale": scale, "transiency_min": got})
        if got is None or abs(got - want) <= tolerance * want:
            break
        scale *= want / got
    if not params.flash_floods:
        truth, forecast, drawn = draw(params, scale)
    return truth, forecast, {"regions": drawn, "calibration": rounds, "flash_floods": bool(params.flash_floods)}
