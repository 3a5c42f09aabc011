"""Satellite names, their ipn node numbers, and the constellation sizes the project accepts.

One scheme, used for topics (``/<sat>/...``), bags, contact plans (CSV, ION, HDTN JSON), bundle
EIDs and reports (docs/design.md section 4):

* a constellation of at most 9 planes of at most 9 satellites (the study's 24/3/1 among them) names
  its satellites ``sat_PS``: plane P and slot S, one digit each, from 1 (the study's Sat11..Sat38);
  the ipn node number (RFC 9171 section 4.2.5.1.2) is the name's two digits, ``10*P + S`` (11..99);
* any larger constellation names every satellite ``sat_PPPP_SSSS``: plane and slot zero-padded to
  4 digits (``sat_0012_0020`` is plane 12, slot 20); the ipn node number is the name's eight digits
  as one integer, ``10000*P + S`` (10001..99999999);
* a satellite from a catalogue (a TLE / 3LE or CCSDS OMM file, orbit_clock/elements.py) is named by
  its NORAD catalogue number, ``sat_n<NORAD>`` without padding (``sat_n40697`` is Sentinel-2A,
  catalogue number 40697, 1..999999999 as OMM's NORAD_CAT_ID carries); its ipn node number is
  :data:`CATALOGUE_NODE_BASE` + NORAD (100040697), above every Walker number. The catalogue's own
  name ("SENTINEL-2A") is a label beside it (``constellation constellation``), never the node name:
  it may hold any character and need not be unique.

Within a constellation every name has the same width, so names sort as (plane, slot) do, and a
name alone gives its plane, slot and node number (no table needed: the ISL medium and the bundle
agents turn node numbers from the wire back into names). The three forms never share a node
number (the letter ``n`` keeps the catalogue form apart from the digit-only Walker forms, and its
numbers start where theirs end), nor with ground stations (``gs_<name>``: 100 + the station's index, at most
:data:`MAX_STATIONS`).

Limits (the scenario file and the CLI's ``--sats`` refuse anything beyond them, in one line):
1 <= satellites <= :data:`MAX_SATS`, 1 <= planes <= :data:`MAX_PLANES`, the satellites split evenly
into the planes. Names and node numbers would carry 9999 x 9999; :data:`MAX_SATS` is what the
project checks (contact plans against a brute force up to 240 satellites, name round trips at
1000: tests/unit/test_names.py, tests/unit/test_scale_plans.py).

How we know it is right: tests/unit/test_names.py (both Walker forms: plane-major order equals sorted
order, name -> node number -> name, every file format and topic round trip, limits refused; the
catalogue form: round trips, no number shared with a Walker or station number).
"""

from __future__ import annotations

import functools
import re

__all__ = [
    "CATALOGUE_NODE_BASE",
    "MAX_NORAD",
    "MAX_PLANES",
    "MAX_SATS",
    "MAX_STATIONS",
    "SAT_NAME_PATTERN",
    "STATION_NODE_BASE",
    "catalogue_sat_name",
    "constellation_limits_error",
    "is_catalogue_name",
    "is_sat_name",
    "sat_from_number",
    "sat_name",
    "sat_names",
    "sat_norad",
    "sat_number",
    "sat_plane_slot",
]

MAX_SATS = 1000  # satellites in one constellation
MAX_PLANES = MAX_SATS  # orbital planes (one satellite per plane at most)
STATION_NODE_BASE = 100  # ipn node number of the first ground station
MAX_STATIONS = 1000  # ground stations: node numbers 100..1099, below the long form's 10001

_SHORT_MAX = 9  # planes and slots of the short form sat_PS
_LONG_DIGITS = 4  # digits of plane and slot in the long form
_LONG_BASE = 10 ** _LONG_DIGITS
CATALOGUE_NODE_BASE = 10 ** 8  # ipn node number of NORAD 0: above the long form's 9999_9999
MAX_NORAD = 999_999_999  # OMM NORAD_CAT_ID: up to 9 digits

# the short form (digits 1..9), the long form (4 digits each, not all zero) or the catalogue form
SAT_NAME_PATTERN = r"^sat_(?:[1-9][1-9]|(?!0000)[0-9]{4}_(?!0000)[0-9]{4}|n[1-9][0-9]{0,8})$"
_SAT_RE = re.compile(SAT_NAME_PATTERN)


def constellation_limits_error(total_sats: int, planes: int) -> str | None:
    """What is wrong with a constellation of ``total_sats`` in ``planes`` (one phrase), or None."""
    if not 1 <= total_sats <= MAX_SATS:
        return f"satellites must be 1..{MAX_SATS}, got {total_sats}"
    if not 1 <= planes <= MAX_PLANES:
        return f"planes must be 1..{MAX_PLANES}, got {planes}"
    if total_sats % planes:
        return f"{total_sats} satellites do not split evenly into {planes} planes"
    return None


def _short(planes: int, per_plane: int) -> bool:
    return planes <= _SHORT_MAX and per_plane <= _SHORT_MAX


def sat_name(plane: int, slot: int, planes: int, per_plane: int) -> str:
    """The name of satellite ``slot`` (1..per_plane) of plane ``plane`` (1..planes) in a constellation
    of ``planes`` planes of ``per_plane`` satellites."""
    if not (1 <= plane <= planes and 1 <= slot <= per_plane):
        raise ValueError(f"satellite plane {plane} slot {slot}: outside {planes} planes x {per_plane} slots")
    if _short(planes, per_plane):
        return f"sat_{plane}{slot}"
    if planes >= _LONG_BASE or per_plane >= _LONG_BASE:
        raise ValueError(f"{planes} planes x {per_plane} slots: names carry at most {_LONG_BASE - 1} of each")
    return f"sat_{plane:0{_LONG_DIGITS}d}_{slot:0{_LONG_DIGITS}d}"


def sat_names(planes: int, per_plane: int) -> list[str]:
    """Every satellite's name, plane-major (plane 1 slot 1, plane 1 slot 2, ...): also sorted order.
    A new list each call (made once per size: a 1000-satellite run asks for it once per participant)."""
    return list(_sat_names_tuple(planes, per_plane))


@functools.lru_cache(maxsize=16)
def _sat_names_tuple(planes: int, per_plane: int) -> tuple[str, ...]:
    return tuple(sat_name(p, s, planes, per_plane) for p in range(1, planes + 1) for s in range(1, per_plane + 1))


def is_sat_name(name: object) -> bool:
    return isinstance(name, str) and _SAT_RE.match(name) is not None


def catalogue_sat_name(norad: int) -> str:
    """The name of the catalogue satellite with NORAD number ``norad`` (1..:data:`MAX_NORAD`)."""
    if type(norad) is not int or not 1 <= norad <= MAX_NORAD:
        raise ValueError(f"NORAD catalogue number {norad!r}: must be 1..{MAX_NORAD}")
    return f"sat_n{norad}"


def is_catalogue_name(name: object) -> bool:
    return is_sat_name(name) and name[4] == "n"


def sat_norad(name: str) -> int:
    """The NORAD number of a catalogue satellite's name; ValueError for anything else."""
    if not is_catalogue_name(name):
        raise ValueError(f"satellite name {name!r}: not a catalogue name sat_n<NORAD>")
    return int(name[5:])


def sat_plane_slot(name: str) -> tuple[int, int]:
    """(plane, slot) of a Walker satellite name of either form; ValueError for anything else (a
    catalogue satellite has no plane or slot)."""
    if not is_sat_name(name) or is_catalogue_name(name):
        raise ValueError(f"satellite name {name!r}: not sat_PS (1..9 each) nor sat_PPPP_SSSS")
    body = name[4:]
    if len(body) == 2:
        return int(body[0]), int(body[1])
    return int(body[:_LONG_DIGITS]), int(body[_LONG_DIGITS + 1:])


def sat_number(name: str) -> int:
    """The ipn node number of a satellite name: sat_PS -> 10P+S; sat_PPPP_SSSS -> 10000P+S;
    sat_n<NORAD> -> CATALOGUE_NODE_BASE + NORAD."""
    if is_catalogue_name(name):
        return CATALOGUE_NODE_BASE + sat_norad(name)
    p, s = sat_plane_slot(name)
    return 10 * p + s if len(name) == 6 else _LONG_BASE * p + s


def sat_from_number(number: int) -> str | None:
    """The satellite name of an ipn node number (inverse of :func:`sat_number`), or None when the
    number is no satellite's."""
    if type(number) is not int:
        return None
    if 11 <= number <= 99 and number % 10:
        return f"sat_{number}"
    if CATALOGUE_NODE_BASE < number <= CATALOGUE_NODE_BASE + MAX_NORAD:
        return f"sat_n{number - CATALOGUE_NODE_BASE}"
    p, s = divmod(number, _LONG_BASE)
    if 1 <= p < _LONG_BASE and s >= 1:
        return f"sat_{p:0{_LONG_DIGITS}d}_{s:0{_LONG_DIGITS}d}"
    return None
