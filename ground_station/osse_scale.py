"""From a field's physical units to the study's value scale 1..256 (``[value.grid] scale``).

The study (Nag et al., ICAPS SPARK 2019, section 5) scores each GP and slot on an integer scale
1..256. A model's output is in physical units (rain rate in mm/h, river stage in m, soil moisture in
m3/m3); the scenario chooses how those become values, applied to the field after it is interpolated
onto the GPs and slot starts (ground_station/osse_io.py), then rounded half to even and held in
1..256:

* ``none``: the file's values are already 1..256 (the project's own files); anything outside is an
  error, as before.
* ``linear`` with ``low``, ``high``: ``v = 1 + 255 (x - low) / (high - low)``, clipped to 1..256: low
  and below score 1, high and above 256.
* ``log`` with ``0 < low < high``: ``v = 1 + 255 (ln x - ln low) / (ln high - ln low)``, clipped; x <= low
  (zero and negative values included) scores 1. For quantities spanning decades (rain rates, discharge).
* ``quantile``: ``v = 1 + 255 F(x)``, F the empirical distribution of the truth's values over every GP
  and slot of the run: a reference value x of average rank r among n scores ``F = (r - 1) / (n - 1)``
  (ties share their mean rank), values between reference values are interpolated linearly, and
  values beyond them clamp. The lowest truth value scores 1, the highest 256, the median ~128.5: a
  field-independent spread (the value distribution a rank-based study needs). A forecast is mapped
  with the truth's F, so the two stay comparable. A run whose truth is one constant scores 128.5.

How we know it is right (tests/unit/test_geo_fields.py): each method against values worked by hand
(linear 0..51: 10.2 -> 52; log 0.1..100: 1 -> 86, 10 -> 171; quantile of [3, 1, 2, 2, 5]: 1 -> 1,
2 -> 97, 3 -> 192, 4 -> 224, 5 -> 256), the clipping ends, and one-line errors for bad parameters.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ground_station.osse import VALUE_MAX, VALUE_MIN, OsseError

__all__ = ["SCALES", "ValueScale", "scale_values"]

SCALES = ("none", "linear", "log", "quantile")


@dataclass(frozen=True)
class ValueScale:
    """How physical values become 1..256 (module docstring)."""

    method: str = "none"
    low: float = 0.0
    high: float = 0.0

    def problem(self) -> str | None:
        """What is wrong with the parameters (None: nothing), naming the scenario keys."""
        if self.method not in SCALES:
            return f"value.grid.scale '{self.method}': not one of {', '.join(SCALES)}"
        if self.method in ("linear", "log"):
            if not (math.isfinite(self.low) and math.isfinite(self.high) and self.high > self.low):
                return (f"value.grid.scale '{self.method}' needs value.grid.low < value.grid.high (got low "
                        f"{self.low:g}, high {self.high:g})")
            if self.method == "log" and not self.low > 0:
                return f"value.grid.scale 'log' needs value.grid.low > 0 (got {self.low:g})"
        return None

    @property
    def physical(self) -> bool:
        """True when the file holds physical values (anything but ``none``)."""
        return self.method != "none"


def _quantile_f(x: np.ndarray, reference: np.ndarray) -> np.ndarray:
    ref = np.asarray(reference, dtype=np.float64).ravel()
    if ref.size == 0:
        raise OsseError("value.grid.scale 'quantile': no reference values")
    u, counts = np.unique(ref, return_counts=True)
    if u.size == 1:
        return np.full(np.shape(x), 0.5)
    first = np.cumsum(counts) - counts + 1  # the 1-based rank of each distinct value's first copy
    f = (first + (counts - 1) / 2.0 - 1.0) / (ref.size - 1)
    return np.interp(x, u, f)


def scale_values(x, scale: ValueScale, reference=None) -> np.ndarray:
    """Physical values ``x`` as int16 1..256 by ``scale``; ``reference`` the truth's values (quantile).
    ``none`` only rounds and checks (values must already be 1..256)."""
    bad = scale.problem()
    if bad:
        raise OsseError(bad)
    x = np.asarray(x, dtype=np.float64)
    if scale.method == "none":
        v = x
    elif scale.method == "linear":
        v = 1.0 + (VALUE_MAX - VALUE_MIN) * (x - scale.low) / (scale.high - scale.low)
    elif scale.method == "log":
        with np.errstate(divide="ignore", invalid="ignore"):
            lx = np.log(np.maximum(x, scale.low))
        v = 1.0 + (VALUE_MAX - VALUE_MIN) * (lx - math.log(scale.low)) / (math.log(scale.high) - math.log(scale.low))
    else:
        v = 1.0 + (VALUE_MAX - VALUE_MIN) * _quantile_f(x, x if reference is None else reference)
    return np.clip(np.rint(v), VALUE_MIN, VALUE_MAX).astype(np.int16)
