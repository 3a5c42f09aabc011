"""Contact plans: the directed windows during which one node can send to another.

A contact is directed (``src`` -> ``dst``); a bidirectional link appears as two contacts, as in
the study's plan (../shared/paper_inputs/contact_plan_3p_8s.csv) and in ION's ``a contact``.
Node names are ``sat_PS`` for satellites and ``gs_<name>`` for ground stations; the ipn node
number (RFC 9171 section 4.2.5.1.2) of ``sat_PS`` is ``10*P + S`` and of the i-th ground station
(0-based, scenario order) is ``100 + i``.

File formats (read and write; owned by the DTN work, see the functions below this header):
the study's six-tuple CSV, ION ``a contact`` / ``a range`` lines, HDTN JSON.

Checked by tests/unit/test_contact_plan_io.py (each format written and read back, and the study's
own plan read).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

__all__ = ["Contact", "ContactPlan", "node_number", "node_name", "canonical_node", "GS_NODE_BASE"]

GS_NODE_BASE = 100
_SAT_RE = re.compile(r"^(?:sat_|s|Sat|SAT)(\d)(\d)$")


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


_SAT_NUMBERS: dict[str, int] = {}  # satellite name -> number, filled as names are seen (at most 81)


def node_number(name: str, ground_stations: list[str] | None = None) -> int:
    """ipn node number of a node name: sat_PS -> 10P+S; gs_<x> -> 100 + index in ground_stations."""
    n = _SAT_NUMBERS.get(name)
    if n is not None:
        return n
    m = _SAT_RE.match(name)
    if m:
        n = _SAT_NUMBERS[name] = 10 * int(m.group(1)) + int(m.group(2))
        return n
    if name.startswith("gs_") and ground_stations is not None and name in ground_stations:
        return GS_NODE_BASE + ground_stations.index(name)
    raise ValueError(f"node name {name!r}: not sat_PS, nor a known ground station")


def node_name(number: int, ground_stations: list[str] | None = None) -> str:
    """Inverse of node_number."""
    if 11 <= number <= 99 and number % 10:
        return f"sat_{number}"
    if ground_stations is not None and 0 <= number - GS_NODE_BASE < len(ground_stations):
        return ground_stations[number - GS_NODE_BASE]
    raise ValueError(f"ipn node number {number}: not a satellite (11..99) nor a known ground station")


def canonical_node(name: str) -> str:
    """The study's spellings (s11, Sat11) -> sat_11; other names unchanged."""
    m = _SAT_RE.match(name)
    return f"sat_{m.group(1)}{m.group(2)}" if m else name


# ---------------------------------------------------------------------------------------------
# File I/O (DTN work). Three formats, read and write:
#
# * ``csv``: the study's table (../shared/paper_inputs/contact_plan_3p_8s.csv): a header row
#   ``start_s,end_s,origin,destination[,rate_bps],range_light_s``. The study's file has no rate
#   column (its link budget gives 1 kb/s): pass ``rate_bps=`` when reading such a file. We write
#   the six-tuple with the rate column.
# * ``ion``: ION contact-plan commands ``a contact +START +END FROM TO RATE`` (RATE in *bytes*/s, as
#   ION's ``ionrc`` wants) and ``a range +START +END FROM TO OWLT`` (OWLT in seconds). Node
#   numbers are ipn node numbers (node_number). Times are seconds relative to the epoch; ION takes
#   whole seconds, we write fractional seconds only where the plan has them (ION rounds), and OWLT
#   is written with full precision (ION itself keeps whole seconds: a 2e-5 s range becomes 0).
# * ``hdtn-json``: HDTN's contact plan ``{"contacts": [{"contact", "source", "dest", "startTime",
#   "endTime", "rateBitsPerSec", "owlt"}]}`` with ipn node numbers.
#
# How we know it is right: round trips through every format give the same plan (tests/unit/
# test_contact_plan_io.py), the study's file reads to 1384 contacts over 24 satellites.
# ---------------------------------------------------------------------------------------------

import csv as _csv  # noqa: E402
import io as _io  # noqa: E402
import json as _json  # noqa: E402
from pathlib import Path as _Path  # noqa: E402

__all__ += ["ContactPlanError", "CONTACT_PLAN_FORMATS", "read_contact_plan", "write_contact_plan",
            "parse_contact_plan", "guess_format"]

CONTACT_PLAN_FORMATS = ("csv", "ion", "hdtn-json")


class ContactPlanError(ValueError):
    """A contact plan file that cannot be read: the message names the file and line."""


def guess_format(path) -> str:
    """Format from the file suffix: .csv -> csv, .json -> hdtn-json, .rc/.ionrc/.txt/.ion -> ion."""
    suffix = _Path(path).suffix.lower()
    if suffix == ".csv":
        return "csv"
    if suffix == ".json":
        return "hdtn-json"
    if suffix in (".rc", ".ionrc", ".ion", ".txt", ".cp"):
        return "ion"
    raise ContactPlanError(f"{path}: cannot tell the contact plan format from the suffix {suffix!r}; "
                           f"give one of {', '.join(CONTACT_PLAN_FORMATS)}")


def read_contact_plan(path, fmt: str | None = None, *, rate_bps: float | None = None,
                      ground_stations: list[str] | None = None) -> ContactPlan:
    """Read a contact plan file (format from ``fmt`` or the suffix). ``rate_bps`` fills a CSV
    without a rate column (and overrides nothing else)."""
    path = _Path(path)
    fmt = fmt or guess_format(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ContactPlanError(f"{path}: cannot read contact plan: {exc.strerror or exc}") from None
    return parse_contact_plan(text, fmt, rate_bps=rate_bps, ground_stations=ground_stations, where=str(path))


def parse_contact_plan(text: str, fmt: str, *, rate_bps: float | None = None,
                       ground_stations: list[str] | None = None, where: str = "<text>") -> ContactPlan:
    if fmt == "csv":
        contacts = _parse_csv(text, rate_bps, where)
    elif fmt == "ion":
        contacts = _parse_ion(text, ground_stations, where)
    elif fmt == "hdtn-json":
        contacts = _parse_hdtn(text, ground_stations, where)
    else:
        raise ContactPlanError(f"{where}: unknown contact plan format {fmt!r} "
                               f"(one of {', '.join(CONTACT_PLAN_FORMATS)})")
    for c in contacts:
        if not (c.end_s > c.start_s >= 0.0) or c.rate_bps <= 0 or c.range_light_s < 0:
            raise ContactPlanError(f"{where}: bad contact {c.src}->{c.dst} [{c.start_s}, {c.end_s}] "
                                   f"rate {c.rate_bps} range {c.range_light_s}")
    return ContactPlan(contacts)


def _parse_csv(text: str, rate_bps, where) -> list[Contact]:
    reader = _csv.DictReader(_io.StringIO(text))
    need = {"start_s", "end_s", "origin", "destination", "range_light_s"}
    if reader.fieldnames is None or not need <= set(reader.fieldnames):
        raise ContactPlanError(f"{where}: CSV header must hold {sorted(need)} (+ optional rate_bps), "
                               f"got {reader.fieldnames}")
    has_rate = "rate_bps" in reader.fieldnames
    if not has_rate and rate_bps is None:
        raise ContactPlanError(f"{where}: the CSV has no rate_bps column; give the rate (e.g. --rate-bps 1000)")
    out = []
    for line, row in enumerate(reader, start=2):
        try:
            rate = float(row["rate_bps"]) if has_rate else float(rate_bps)
            out.append(Contact(float(row["start_s"]), float(row["end_s"]), canonical_node(row["origin"].strip()),
                               canonical_node(row["destination"].strip()), rate, float(row["range_light_s"])))
        except (TypeError, ValueError, AttributeError):
            raise ContactPlanError(f"{where}:{line}: bad contact row {row}") from None
    return out


def _num(tok: str) -> float:
    return float(tok[1:] if tok.startswith("+") else tok)


def _parse_ion(text: str, gs, where) -> list[Contact]:
    contacts: dict[tuple, list] = {}
    ranges: list[tuple[float, float, int, int, float]] = []
    for line_no, raw in enumerate(text.splitlines(), start=1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        tok = line.split()
        try:
            if tok[:2] == ["a", "contact"] and len(tok) >= 7:
                contacts[(line_no,)] = [_num(tok[2]), _num(tok[3]), int(tok[4]), int(tok[5]), 8.0 * float(tok[6])]
            elif tok[:2] == ["a", "range"] and len(tok) >= 7:
                ranges.append((_num(tok[2]), _num(tok[3]), int(tok[4]), int(tok[5]), float(tok[6])))
            # other ionrc commands (m, s, ...) are not part of a plan: ignored
        except ValueError:
            raise ContactPlanError(f"{where}:{line_no}: bad ION line {raw.strip()!r}") from None
    out = []
    for (line_no,), (t0, t1, a, b, rate) in sorted(contacts.items()):
        owlt = 0.0
        for r0, r1, ra, rb, rl in ranges:  # a range is symmetric in ION: A-B covers B-A
            if {ra, rb} == {a, b} and r0 <= t0 and t1 <= r1:
                owlt = rl
                break
        try:
            out.append(Contact(t0, t1, node_name(a, gs), node_name(b, gs), rate, owlt))
        except ValueError as exc:
            raise ContactPlanError(f"{where}:{line_no}: {exc}") from None
    return out


def _parse_hdtn(text: str, gs, where) -> list[Contact]:
    try:
        doc = _json.loads(text)
        rows = doc["contacts"]
        return [Contact(float(r["startTime"]), float(r["endTime"]), node_name(int(r["source"]), gs),
                        node_name(int(r["dest"]), gs), float(r["rateBitsPerSec"]), float(r.get("owlt", 0.0)))
                for r in rows]
    except (ValueError, KeyError, TypeError) as exc:
        raise ContactPlanError(f"{where}: not an HDTN JSON contact plan: {exc}") from None


def _fmt_t(x: float) -> str:
    return str(int(x)) if float(x).is_integer() else repr(float(x))


def write_contact_plan(plan: ContactPlan, fmt: str, stream, *, ground_stations: list[str] | None = None) -> None:
    """Write ``plan`` to a text stream in ``fmt`` (csv | ion | hdtn-json)."""
    if fmt == "csv":
        w = _csv.writer(stream, lineterminator="\n")
        w.writerow(["start_s", "end_s", "origin", "destination", "rate_bps", "range_light_s"])
        for c in plan:
            w.writerow([_fmt_t(c.start_s), _fmt_t(c.end_s), c.src, c.dst, _fmt_t(c.rate_bps), repr(c.range_light_s)])
    elif fmt == "ion":
        stream.write("# contact plan (ION ionrc commands); times in s after the scenario epoch; rate in bytes/s\n")
        for c in plan:
            a, b = node_number(c.src, ground_stations), node_number(c.dst, ground_stations)
            stream.write(f"a contact +{_fmt_t(c.start_s)} +{_fmt_t(c.end_s)} {a} {b} {_fmt_t(c.rate_bps / 8.0)}\n")
        for c in plan:
            a, b = node_number(c.src, ground_stations), node_number(c.dst, ground_stations)
            stream.write(f"a range +{_fmt_t(c.start_s)} +{_fmt_t(c.end_s)} {a} {b} {_fmt_t(c.range_light_s)}\n")
    elif fmt == "hdtn-json":
        rows = [{"contact": i, "source": node_number(c.src, ground_stations), "dest": node_number(c.dst, ground_stations),
                 "startTime": c.start_s, "endTime": c.end_s, "rateBitsPerSec": c.rate_bps, "owlt": c.range_light_s}
                for i, c in enumerate(plan)]
        _json.dump({"contacts": rows}, stream, indent=1)
        stream.write("\n")
    else:
        raise ContactPlanError(f"unknown contact plan format {fmt!r} (one of {', '.join(CONTACT_PLAN_FORMATS)})")
