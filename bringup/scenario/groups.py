"""The constellation's groups in a scenario file: the schema of one ``[constellation]`` table (a
Walker shell or a catalogue file, with its own instrument / acs / isl overrides) and the rules
between its keys. What the groups become (named satellites, orbits, payload): fleet.py.

How we know it is right: tests/unit/test_fleet.py (each rule broken in turn: one line naming the
key) and tests/unit/test_scenario.py (every key of the paper scenario's Walker table).
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Annotated, Literal

import msgspec

from msgs_json.names import MAX_NORAD, MAX_PLANES, MAX_SATS, constellation_limits_error

__all__ = ["AcsOverride", "ConstellationCfg", "InstrumentOverride", "IslOverride", "group_errors"]

Pos = Annotated[float, msgspec.Meta(gt=0)]
NonNeg = Annotated[float, msgspec.Meta(ge=0)]


class _G(msgspec.Struct, forbid_unknown_fields=True, frozen=True, kw_only=True):
    pass


class InstrumentOverride(_G, kw_only=True, omit_defaults=True):
    """A constellation group's own payload (bringup/scenario/fleet.py): unset keys take [instrument]'s."""
    footprint_km: Pos | None = None
    for_off_nadir_deg: Annotated[float, msgspec.Meta(gt=0, lt=90)] | None = None


class AcsOverride(_G, kw_only=True, omit_defaults=True):
    """A group's own slew model: unset keys take [acs]'s."""
    slew_coeffs_s: Annotated[list[float], msgspec.Meta(min_length=1, max_length=8)] | None = None
    slew_margin_s: NonNeg | None = None


class IslOverride(_G, kw_only=True, omit_defaults=True):
    """A group's own ISL radio: unset keys take [isl]'s (a link runs at the lower rate and closes at
    the shorter range of its two ends)."""
    rate_bps: Pos | None = None
    max_range_km: Pos | None = None


class ConstellationCfg(_G, kw_only=True, omit_defaults=True):
    """One group of the constellation: a Walker shell (pattern .. raan0_deg) or the satellites of a
    catalogue file (tle_file or omm_file, optionally only norad_ids of it), with its own payload and
    bus (instrument, acs, isl) where given (bringup/scenario/fleet.py)."""
    pattern: Literal["star", "delta"] = "star"
    total_sats: Annotated[int, msgspec.Meta(ge=1, le=MAX_SATS)] | None = None
    planes: Annotated[int, msgspec.Meta(ge=1, le=MAX_PLANES)] | None = None
    phasing_f: Annotated[int, msgspec.Meta(ge=0)] = 1
    altitude_km: Annotated[float, msgspec.Meta(gt=150, lt=40000)] | None = None
    inclination_deg: Annotated[float, msgspec.Meta(ge=0, le=180)] | None = None
    raan0_deg: Annotated[float, msgspec.Meta(ge=0, lt=360)] = 0.0
    tle_file: str = ""
    omm_file: str = ""
    norad_ids: Annotated[list[Annotated[int, msgspec.Meta(ge=1, le=MAX_NORAD)]], msgspec.Meta(max_length=MAX_SATS)] = []
    instrument: InstrumentOverride | None = None
    acs: AcsOverride | None = None
    isl: IslOverride | None = None

    @property
    def is_walker(self) -> bool:
        return not (self.tle_file or self.omm_file)

    @property
    def sats_per_plane(self) -> int:
        return self.total_sats // self.planes


_WALKER_KEYS = ("total_sats", "planes", "altitude_km", "inclination_deg")


def group_errors(sc) -> Iterator[tuple[str, str]]:
    """(dotted key, what is wrong) of each broken rule of the scenario's groups, in file order."""
    for i, c in enumerate(sc.groups):
        pre = f"constellation[{i}]" if isinstance(sc.constellation, list) else "constellation"
        if c.tle_file and c.omm_file:
            yield f"{pre}.omm_file", "a group reads one file: tle_file or omm_file (give two groups for both)"
        given = [k for k in _WALKER_KEYS if getattr(c, k) is not None]
        if not c.is_walker:
            if given:
                yield (f"{pre}.{given[0]}", ("a catalogue group (tle_file / omm_file) takes no Walker keys; "
                                             "give the Walker shell its own [[constellation]] table"))
            continue
        if c.norad_ids:
            yield f"{pre}.norad_ids", "selects satellites of a tle_file or omm_file, and this group has none"
        missing = [k for k in _WALKER_KEYS if k not in given]
        if missing:
            yield (f"{pre}.{missing[0]}", ("missing: a Walker shell needs total_sats, planes, altitude_km and "
                                           "inclination_deg (or give tle_file / omm_file for catalogue satellites)"))
            continue
        why = constellation_limits_error(c.total_sats, c.planes)
        if why is not None:
            yield f"{pre}.total_sats", why
        if c.phasing_f >= c.planes and c.planes > 1:
            yield f"{pre}.phasing_f", f"must be in 0..P-1 = 0..{c.planes - 1}, got {c.phasing_f}"
