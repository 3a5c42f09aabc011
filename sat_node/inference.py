"""What one observation tells the others: the inference a bundle carries (and a downlink, on the ground).

Nag et al. (ICAPS SPARK 2019, section 4, Table 1 line 4) have every observing satellite share, for each
GP observation, the value it recorded and its insight about the observed region (the model parameters
Omega and Delta). Here an :class:`Inference` holds:

* ``src``, ``gp``, ``t_ns`` - who observed which GP when;
* ``value`` - the value the observer inferred from its image: the recorded (true) value through its
  own inference noise (:class:`sat_node.value.Belief`);
* ``region`` - the observed GP's region (index in the scenario's list), and the region insight:
  ``omega`` - the observer's estimate of the region's departure from the a-priori forecast, the
  weighted mean of ``ln(inferred / forecast)`` over every observation of the region it knows
  (weights decaying with age, sat_node/knowledge.py), and ``delta`` - how fast that changes [1/h].

How a receiver uses it depends on its knowledge model (sat_node/knowledge.py): ``observed`` (the
default) updates its belief of the GP (and, spread in space, of its neighbours) from ``value`` and of
the whole region from ``omega``/``delta`` - only what the payload carries; the ``region-truth``
sensitivity takes the bundle's time as entitling it to the true field of the whole region as of
``t_ns`` (an upper bound, not something a receiver can do).

Wire form (the bundle payload, :func:`encode_inference` / :func:`decode_inference`): compact JSON
``{"src","gp","t_ns","v","r","om","de"}``, values rounded to 1e-3 (value) and 1e-4 (insight), about
100 bytes - inside the study's 1645 inference bits. A payload that does not decode or holds a field
out of range raises ValueError naming the field (the satellite counts and drops it).

How we know it is right (tests/unit/test_knowledge.py): every inference survives encode/decode to
its rounding; malformed payloads (not JSON, missing or mistyped fields, negative GP or time, NaN)
raise ValueError; a flood seen by one satellite reaches another through this payload and changes
what it plans.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass

__all__ = ["Inference", "decode_inference", "encode_inference"]


@dataclass(frozen=True)
class Inference:
    """One observation's news (module docstring): who, which GP, when, inferred value, region insight."""

    src: str
    gp: int
    t_ns: int
    value: float
    region: int
    omega: float = 0.0
    delta: float = 0.0

    @property
    def t_s(self) -> float:
        return self.t_ns / 1e9


def encode_inference(inf: Inference) -> bytes:
    """The bundle payload of an inference (compact JSON, module docstring)."""
    return json.dumps({"src": inf.src, "gp": int(inf.gp), "t_ns": int(inf.t_ns), "v": round(float(inf.value), 3),
                       "r": int(inf.region), "om": round(float(inf.omega), 4), "de": round(float(inf.delta), 4)},
                      separators=(",", ":")).encode()


def _num(d: dict, key: str, *, lo: float = -math.inf) -> float:
    v = d[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < lo:
        raise ValueError(f"inference payload: bad {key!r} ({v!r})")
    return float(v)


def decode_inference(data: bytes) -> Inference:
    """An inference from a bundle payload; ValueError (naming the field) when it is not one."""
    try:
        d = json.loads(data)
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"inference payload: not JSON ({exc})") from None
    if not isinstance(d, dict):
        raise ValueError("inference payload: not a JSON object")
    try:
        src, gp, t_ns, r = d["src"], d["gp"], d["t_ns"], d["r"]
        value, omega, delta = _num(d, "v", lo=0.0), _num(d, "om"), _num(d, "de")
    except KeyError as exc:
        raise ValueError(f"inference payload: missing {exc.args[0]!r}") from None
    for key, v in (("gp", gp), ("t_ns", t_ns), ("r", r)):
        if isinstance(v, bool) or not isinstance(v, int) or v < 0:
            raise ValueError(f"inference payload: bad {key!r} ({v!r})")
    if not isinstance(src, str) or not src:
        raise ValueError(f"inference payload: bad 'src' ({src!r})")
    return Inference(src=src, gp=gp, t_ns=t_ns, value=value, region=r, omega=omega, delta=delta)
