"""Contact plans: the directed windows during which one node can send to another.

A contact is directed (``src`` -> ``dst``); a bidirectional link appears as two contacts, as in
the study's plan (tests/fixtures/paper_inputs/contact_plan_3p_8s.csv) and in ION's ``a contact``.
Node names are the satellites' names (``sat_PS``, or ``sat_PPPP_SSSS`` beyond 9 planes x 9 slots:
msgs_json/names.py) and ``gs_<name>`` for ground stations; the ipn node number (RFC 9171 section
4.2.5.1.2) of a satellite is its name's digits (``10*P + S``, ``10000*P + S``) and of the i-th
ground station (0-based, scenario order) is ``100 + i``. A DTN node outside the constellation (the
ground segment's bundle agent, a gateway's terrestrial peer: ground_station/ground_agent.py) is named
``ipn_<N>`` after its node number N.

File formats (the study's CSV, ION, HDTN JSON) are read and written by
orbit_clock/contact_plan_io.py.

Checked by tests/unit/test_contact_plan_io.py (node numbers through every format) and
tests/unit/test_cgr.py (plans built from these types).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from msgs_json.names import STATION_NODE_BASE, is_sat_name, sat_from_number, sat_number

__all__ = ["GS_NODE_BASE", "Contact", "ContactPlan", "canonical_node", "ipn_node", "node_name", "node_number"]

GS_NODE_BASE = STATION_NODE_BASE
_STUDY_RE = re.compile(r"^(?:s|Sat|SAT)([1-9])([1-9])$")  # the study's spellings of sat_PS


@dataclass(frozen=True, order=True)
class Contact:
    """One directed contact window.

    start_s, end_s: [s] since the scenario epoch; rate_bps [bit/s]; range_light_s: one-way light
    time [s] (taken constant over the window, as CGR's range entries are).
    """

    start_s: float
    end_s: float
    src: str
    dst: str
    rate_bps: float
    range_light_s: float

    @property
    def duration_s(self) -> float:
        return self.end_s - self.start_s

    @property
    def volume_bits(self) -> float:
        return self.duration_s * self.rate_bps


@dataclass
class ContactPlan:
    """A list of contacts sorted by (start_s, src, dst), plus the node names it spans."""

    contacts: list[Contact]

    def __post_init__(self) -> None:
        self.contacts = sorted(self.contacts, key=lambda c: (c.start_s, c.src, c.dst, c.end_s))

    def __len__(self) -> int:
        return len(self.contacts)

    def __iter__(self):
        return iter(self.contacts)

    @property
    def nodes(self) -> list[str]:
        return sorted({c.src for c in self.contacts} | {c.dst for c in self.contacts})

    def pairs(self) -> set[tuple[str, str]]:
        """Unordered node pairs that have at least one contact."""
        return {tuple(sorted((c.src, c.dst))) for c in self.contacts}

    def open_at(self, t_s: float) -> list[Contact]:
        """Contacts with start_s <= t_s < end_s."""
        return [c for c in self.contacts if c.start_s <= t_s < c.end_s]


_SAT_NUMBERS: dict[str, int] = {}  # satellite name -> number, filled as names are seen


def node_number(name: str, ground_stations: list[str] | None = None) -> int:
    """ipn node number of a node name: a satellite's digits (msgs_json/names.py); gs_<x> -> 100 +
    index in ground_stations."""
    n = _SAT_NUMBERS.get(name)
    if n is not None:
        return n
    if is_sat_name(name):
        n = _SAT_NUMBERS[name] = sat_number(name)
        return n
    if name.startswith("gs_") and ground_stations is not None and name in ground_stations:
        return GS_NODE_BASE + ground_stations.index(name)
    if name.startswith("ipn_") and name[4:].isdigit() and name[4] != "0":
        return int(name[4:])
    raise ValueError(f"node name {name!r}: not a satellite (sat_PS, sat_PPPP_SSSS), nor a known ground station")


def node_name(number: int, ground_stations: list[str] | None = None) -> str:
    """Inverse of node_number."""
    name = sat_from_number(number)
    if name is not None:
        return name
    if ground_stations is not None and 0 <= number - GS_NODE_BASE < len(ground_stations):
        return ground_stations[number - GS_NODE_BASE]
    raise ValueError(f"ipn node number {number}: not a satellite (11..99, 10001..) nor a known ground station")


def ipn_node(number: int) -> str:
    """The name of a DTN node outside the constellation by its ipn node number (``ipn_<N>``)."""
    if not 0 < int(number) < 1 << 64:
        raise ValueError(f"ipn node number {number}: must be 1..2^64-1")
    return f"ipn_{int(number)}"


def canonical_node(name: str) -> str:
    """The study's spellings (s11, Sat11) -> sat_11; other names unchanged."""
    m = _STUDY_RE.match(name)
    return f"sat_{m.group(1)}{m.group(2)}" if m else name
