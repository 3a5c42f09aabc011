"""Contact plan files in the formats DTN users load: the study's CSV, ION's ionadmin lines, HDTN JSON.

* ``csv``: the study's table (tests/fixtures/paper_inputs/contact_plan_3p_8s.csv): a header row
  ``start_s,end_s,origin,destination[,rate_bps],range_light_s``, times in seconds since the scenario
  epoch. The study's file has no rate column (its link budget gives 1 kb/s): pass ``rate_bps=``
  when reading such a file. We write the six-tuple with the rate column, at full precision.
* ``ion``: ionadmin commands (ION's ici/utils/ionadmin.c, ``executeAdd``; grammar in its
  ionrc(5) page). The file starts with an absolute reference time, ``@ yyyy/mm/dd-hh:mm:ss`` (UTC:
  ionadmin's ``case '@'`` reads it with ``readTimestampUTC``, ici/library/ion.c), the scenario
  epoch, so the plan means the same instants whenever ionadmin runs (a plan of bare ``+N`` times
  counts from when ionadmin started). Then ``a contact +START +END FROM TO RATE`` (RATE in
  *bytes*/s) and ``a range +START +END FROM TO OWLT`` (one per directed contact: ionrc(5) says
  ranges are directional), node numbers are ipn node numbers (:func:`node_number`).
* ``hdtn-json``: HDTN's ``{"contacts": [{"contact", "source", "dest", "startTime", "endTime",
  "rateBitsPerSec", "owlt"}]}`` with ipn node numbers. HDTN reads every field as an integer with
  Boost property_tree: module/router/src/router.cpp ``Router::Impl::ProcessContacts`` uses
  ``get<int>("startTime", 0)`` / ``get<int>("endTime", 0)`` (a value that is not an integer, e.g.
  ``206.279``, silently becomes the default 0, so the contact never opens) and
  ``GetRateBpsFromPtree``'s ``get<uint64_t>("rateBitsPerSec")`` (``1000000.0`` throws; the rate
  becomes 0); common/cgr/src/libcgr.cpp ``cp_load`` reads ``startTime``/``endTime``/``owlt`` with
  ``get<time_t>`` and ``source``/``dest`` with ``get<nodeId_t>``. Times count from the HDTN router's
  start, or are Unix seconds with its ``--use-unix-timestamp`` (``unix_time=True`` here).

Whole numbers, and how we round: ION's relative times, rates and light times are read with
``strtol`` (a fraction is cut off: ``+381.5`` is 381; our former ``2e-05`` light time read as 2 s)
and HDTN's with ptree's integer reads, so both formats get whole numbers only, rounded so that the
written plan never promises more than the true one: a contact's window is rounded *inward* on the
absolute clock (start up, end down: the written window lies inside the true one, so a transmission
either tool schedules in it can really happen), a contact left with less than one whole second is
left out (counted in :class:`Written`), rates are rounded down (ION: bytes/s, HDTN: bits/s), and the
one-way light time is rounded *up* to whole seconds (no predicted arrival is earlier than the true
one; ionrc(5): ranges are constant "to within one light second"; the ISL's few milliseconds become
1 s, the value ION's and HDTN's own example plans use for near links).

Reading follows the same tools' rules: ION lines as ionadmin reads them (``@`` reference times,
absolute ``yyyy/mm/dd-hh:mm:ss`` or ``+N`` relative times, integers read like ``strtol``), returned
in seconds since ``epoch_utc`` (default: the file's first ``@`` reference time); HDTN fields must be
integers (a field HDTN would read as 0 is an error naming the contact and the field).

Every plan read is checked before use (:func:`checked_contacts`): numbers finite, 0 <= start < end
<= :data:`MAX_PLAN_TIME_S`, 1 <= rate <= 1e15 bit/s, 0 <= light time <= :data:`MAX_LIGHT_S`; the
same directed link listed twice with the same window and figures is one contact (merged, and said
through ``on_duplicate``, or refused when no such callback is given), and two different windows of
one directed link that overlap are refused (CGR would count the link's capacity twice). Files are
read as UTF-8 text, at most :data:`MAX_PLAN_BYTES` (msgs_json/text_input.py).

How we know it is right: tests/unit/test_contact_plan_io.py (every format written and read back
within the rounding rules; the study's plan; every line we write checked against a mirror of
ionadmin's grammar and of HDTN's ptree reads, HDTN's own example plans' field types included).
"""

from __future__ import annotations

import calendar
import csv
import io
import json
import math
import re
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path

from msgs_json.text_input import TextInputError, read_text
from orbit_clock.contact_plan import Contact, ContactPlan, canonical_node, node_name, node_number

__all__ = ["CONTACT_PLAN_FORMATS", "MAX_LIGHT_S", "MAX_PLAN_BYTES", "MAX_PLAN_TIME_S", "ContactPlanError",
           "Written", "checked_contacts", "guess_format", "parse_contact_plan", "read_contact_plan",
           "whole_second_contacts", "write_contact_plan"]

CONTACT_PLAN_FORMATS = ("csv", "ion", "hdtn-json")
# ionadmin's time stamp (ici/library/ion.c timestampInFormat / timestampOutFormat)
_ION_TS = "%Y/%m/%d-%H:%M:%S"
_ION_TS_RE = re.compile(r"^(\d{1,4})/(\d{1,2})/(\d{1,2})-(\d{1,2}):(\d{1,2}):(\d{1,2})")
# ION keeps times as POSIX seconds up to MAX_POSIX_TIME (19 January 2038); HDTN reads times as int
_INT32_MAX = 2**31 - 1
# Bounds of a plan we read: times within half of the engines' int64-nanosecond clock (a time plus a
# light time plus a queue never overflows it; ~146 years), light times up to 1e6 s (11.6 days: the
# farthest spacecraft is under one light day away), rates 1 bit/s (ION's least, 1 byte/s, is 8) to 1 Pb/s
MAX_PLAN_TIME_S = 2**62 / 1e9
MAX_LIGHT_S = 1e6
_MIN_RATE_BPS, _MAX_RATE_BPS = 1.0, 1e15
MAX_PLAN_BYTES = 512 * 2**20


class ContactPlanError(ValueError):
    """A contact plan file that cannot be read or written: the message names the file and line."""


@dataclass
class Written:
    """What :func:`write_contact_plan` wrote: contacts written and those left out (no whole second
    left inside their window), for the CLI to report."""

    written: int = 0
    dropped: list[Contact] = field(default_factory=list)


def guess_format(path) -> str:
    """Format from the file suffix: .csv -> csv, .json -> hdtn-json, .rc/.ionrc/.txt/.ion -> ion."""
    suffix = Path(path).suffix.lower()
    if suffix == ".csv":
        return "csv"
    if suffix == ".json":
        return "hdtn-json"
    if suffix in (".rc", ".ionrc", ".ion", ".txt", ".cp"):
        return "ion"
    raise ContactPlanError(f"{path}: cannot tell the contact plan format from the suffix {suffix!r}; "
                           f"give one of {', '.join(CONTACT_PLAN_FORMATS)}")


def read_contact_plan(path, fmt: str | None = None, *, rate_bps: float | None = None,
                      ground_stations: list[str] | None = None, epoch_utc: datetime | None = None,
                      on_duplicate=None) -> ContactPlan:
    """Read a contact plan file (format from ``fmt`` or the suffix). ``rate_bps`` fills a CSV
    without a rate column (and overrides nothing else); ``epoch_utc``: the instant ION times are
    counted from (default: the file's first ``@`` reference time); ``on_duplicate(line)``: told of
    each contact listed twice, which is merged (None: a duplicate is an error)."""
    path = Path(path)
    fmt = fmt or guess_format(path)
    try:
        text = read_text(path, "contact plan", MAX_PLAN_BYTES)
    except TextInputError as exc:
        raise ContactPlanError(str(exc)) from None
    return parse_contact_plan(text, fmt, rate_bps=rate_bps, ground_stations=ground_stations, where=str(path),
                              epoch_utc=epoch_utc, on_duplicate=on_duplicate)


def parse_contact_plan(text: str, fmt: str, *, rate_bps: float | None = None,
                       ground_stations: list[str] | None = None, where: str = "<text>",
                       epoch_utc: datetime | None = None, on_duplicate=None) -> ContactPlan:
    if fmt == "csv":
        contacts = _parse_csv(text, rate_bps, where)
    elif fmt == "ion":
        contacts = _parse_ion(text, ground_stations, where, epoch_utc)
    elif fmt == "hdtn-json":
        contacts = _parse_hdtn(text, ground_stations, where)
    else:
        raise ContactPlanError(f"{where}: unknown contact plan format {fmt!r} "
                               f"(one of {', '.join(CONTACT_PLAN_FORMATS)})")
    return ContactPlan(checked_contacts(contacts, where, on_duplicate))


def _describe(c: Contact) -> str:
    return f"{c.src}->{c.dst} [{c.start_s:g}, {c.end_s:g}] s"


def checked_contacts(contacts: list[Contact], where: str, on_duplicate=None) -> list[Contact]:
    """``contacts`` within the bounds (module docstring), exact duplicates merged (each told to
    ``on_duplicate``, or an error without it); ContactPlanError naming the first bad contact."""
    for i, c in enumerate(contacts, start=1):
        nums = (c.start_s, c.end_s, c.rate_bps, c.range_light_s)
        if not all(isinstance(x, (int, float)) and math.isfinite(x) for x in nums):
            raise ContactPlanError(f"{where}: contact {i} ({c.src}->{c.dst}): start, end, rate and range must be "
                                   f"finite numbers, got {nums}")
        if not 0.0 <= c.start_s < c.end_s <= MAX_PLAN_TIME_S:
            raise ContactPlanError(f"{where}: contact {i} {_describe(c)}: need 0 <= start < end <= "
                                   f"{MAX_PLAN_TIME_S:.3g} s")
        if not _MIN_RATE_BPS <= c.rate_bps <= _MAX_RATE_BPS:
            raise ContactPlanError(f"{where}: contact {i} {_describe(c)}: rate {c.rate_bps:g} bit/s outside "
                                   f"{_MIN_RATE_BPS:g}..{_MAX_RATE_BPS:g}")
        if not 0.0 <= c.range_light_s <= MAX_LIGHT_S:
            raise ContactPlanError(f"{where}: contact {i} {_describe(c)}: one-way light time {c.range_light_s:g} s "
                                   f"outside 0..{MAX_LIGHT_S:g}")
        if c.src == c.dst:
            raise ContactPlanError(f"{where}: contact {i} {_describe(c)}: a node's contact with itself")
    out: list[Contact] = []
    last: dict[tuple[str, str], Contact] = {}
    dups = 0
    for c in sorted(contacts, key=lambda c: (c.src, c.dst, c.start_s, c.end_s, c.rate_bps, c.range_light_s)):
        prev = last.get((c.src, c.dst))
        if prev is not None and c.start_s < prev.end_s:
            if c == prev:
                dups += 1
                continue
            raise ContactPlanError(f"{where}: contacts {_describe(prev)} and {_describe(c)} overlap: one directed "
                                   "link has one window at a time (CGR would count its capacity twice)")
        last[(c.src, c.dst)] = c
        out.append(c)
    if dups:
        line = f"{where}: {dups} contacts listed twice (same link, window, rate and range): each counted once"
        if on_duplicate is None:
            raise ContactPlanError(line.replace("each counted once", "remove the copies"))
        on_duplicate(line)
    return out


def _parse_csv(text: str, rate_bps, where) -> list[Contact]:
    reader = csv.DictReader(io.StringIO(text))
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


# -- ION ----------------------------------------------------------------------------------------------

def _strtol(tok: str) -> int:
    """C ``strtol(tok, NULL, 0)`` as ionadmin calls it: leading whitespace, sign, then the longest
    prefix in base 16 (0x), 8 (leading 0) or 10; no digits: 0."""
    m = re.match(r"\s*([+-]?)(0[xX][0-9a-fA-F]+|0[0-7]*|[1-9][0-9]*)", tok)
    if not m:
        return 0
    digits = m.group(2)
    if digits[:2] in ("0x", "0X"):
        v = int(digits, 16)
    elif digits.startswith("0"):
        v = int(digits, 8) if len(digits) > 1 else 0
    else:
        v = int(digits)
    return -v if m.group(1) == "-" else v


def _ion_time(tok: str, ref: int | None, where: str) -> int:
    """ionadmin's readTimestampUTC: ``+N`` = ref + strtol(N); else a UTC ``yyyy/mm/dd-hh:mm:ss``."""
    if tok.startswith("+"):
        if ref is None:
            raise ContactPlanError(f"{where}: relative time {tok!r} before any '@' reference time: ionadmin "
                                   "would count it from when it started; give an '@ yyyy/mm/dd-hh:mm:ss' line "
                                   "or absolute times")
        return ref + _strtol(tok[1:])
    m = _ION_TS_RE.match(tok)
    if not m:
        raise ContactPlanError(f"{where}: time {tok!r} is neither +SECONDS nor yyyy/mm/dd-hh:mm:ss")
    y, mo, d, h, mi, s = (int(g) for g in m.groups())
    try:  # mktime normalises out-of-range fields; a plan we read should not need it
        return calendar.timegm(datetime(y, mo, d, h, mi, s, tzinfo=UTC).timetuple())
    except ValueError as exc:
        raise ContactPlanError(f"{where}: time {tok!r}: {exc}") from None


def _parse_ion(text: str, gs, where, epoch_utc: datetime | None) -> list[Contact]:
    ref: int | None = None
    first_ref: int | None = None
    contacts: list[tuple[int, int, int, int, int, int]] = []  # (line, from, to, a, b, bytes/s)
    ranges: list[tuple[int, int, int, int, int]] = []
    for line_no, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        tok = line.split()
        at = f"{where}:{line_no}"
        try:
            if tok[0] == "@":
                if len(tok) != 2 or tok[1] == "0":
                    raise ContactPlanError(f"{at}: '@' needs one time; '@ 0' (ionadmin's current time) is no "
                                           "fixed instant")
                ref = _ion_time(tok[1], ref, at)
                first_ref = ref if first_ref is None else first_ref
            elif tok[:2] == ["a", "contact"] and len(tok) in (7, 8):
                if tok[2] in ("0", "-1"):  # ionadmin: hypothetical / registration contacts
                    continue
                contacts.append((line_no, _ion_time(tok[2], ref, at), _ion_time(tok[3], ref, at),
                                 _strtol(tok[4]), _strtol(tok[5]), _strtol(tok[6])))
            elif tok[:2] == ["a", "range"] and len(tok) == 7:
                ranges.append((_ion_time(tok[2], ref, at), _ion_time(tok[3], ref, at), _strtol(tok[4]),
                               _strtol(tok[5]), _strtol(tok[6])))
            elif tok[0] == "a":
                raise ContactPlanError(f"{at}: not an ionadmin 'a contact' (7-8 tokens) or 'a range' (7 tokens) "
                                       f"line: {raw.strip()!r}")
            # other ionadmin commands (1, s, m, ^, !) are not part of a plan: ignored
        except ValueError as exc:
            raise ContactPlanError(str(exc) if isinstance(exc, ContactPlanError) else
                                   f"{at}: bad ION line {raw.strip()!r}") from None
    if epoch_utc is not None:
        zero = calendar.timegm(epoch_utc.astimezone(UTC).timetuple())
    else:
        absolute = [c[1] for c in contacts]
        zero = first_ref if first_ref is not None else (min(absolute) if absolute else 0)
    out = []
    for line_no, t0, t1, a, b, rate in contacts:
        owlt = 0
        for r0, r1, ra, rb, rl in ranges:  # this direction's range, else the other's (ionrc(5))
            if (ra, rb) == (a, b) and r0 <= t0 and t1 <= r1:
                owlt = rl
                break
        else:
            for r0, r1, ra, rb, rl in ranges:
                if (ra, rb) == (b, a) and r0 <= t0 and t1 <= r1:
                    owlt = rl
                    break
        try:
            out.append(Contact(float(t0 - zero), float(t1 - zero), node_name(a, gs), node_name(b, gs),
                               8.0 * rate, float(owlt)))
        except ValueError as exc:
            raise ContactPlanError(f"{where}:{line_no}: {exc}") from None
    return out


# -- HDTN ---------------------------------------------------------------------------------------------

_PTREE_INT = re.compile(r"^\s*[+-]?\d+\s*$")


def _hdtn_int(row: dict, key: str, i: int, where: str, *, required: bool = True, default: int = 0) -> int:
    """An integer field as HDTN's Boost ptree reads it (a JSON integer, or a string holding one)."""
    if key not in row:
        if required:
            raise ContactPlanError(f"{where}: contact {i} has no {key!r}")
        return default
    v = row[key]
    if isinstance(v, bool) or not (isinstance(v, int) or (isinstance(v, str) and _PTREE_INT.match(v))):
        raise ContactPlanError(f"{where}: contact {i}: {key} = {v!r} is not an integer; HDTN reads it with "
                               f"Boost ptree get<int>/get<uint64_t> and would use 0")
    return int(v)


def _parse_hdtn(text: str, gs, where) -> list[Contact]:
    try:
        doc = json.loads(text)
        rows = doc["contacts"]
        if not isinstance(rows, list):
            raise TypeError("'contacts' is not a list")
    except (ValueError, KeyError, TypeError, RecursionError) as exc:
        raise ContactPlanError(f"{where}: not an HDTN JSON contact plan: {exc}") from None
    out = []
    for i, r in enumerate(rows):
        if not isinstance(r, dict):
            raise ContactPlanError(f"{where}: contact {i} is not an object")
        src, dst = _hdtn_int(r, "source", i, where), _hdtn_int(r, "dest", i, where)
        t0, t1 = _hdtn_int(r, "startTime", i, where), _hdtn_int(r, "endTime", i, where)
        rate = _hdtn_int(r, "rateBitsPerSec", i, where)
        owlt = _hdtn_int(r, "owlt", i, where, required=False)
        try:
            out.append(Contact(float(t0), float(t1), node_name(src, gs), node_name(dst, gs), float(rate), float(owlt)))
        except ValueError as exc:
            raise ContactPlanError(f"{where}: contact {i}: {exc}") from None
    return out


# -- writing ------------------------------------------------------------------------------------------

def _fmt(x: float) -> str:
    return str(int(x)) if float(x).is_integer() else repr(float(x))


def whole_second_contacts(plan: ContactPlan, zero_s: int = 0) -> tuple[list[tuple[int, int, Contact]], list[Contact]]:
    """Each contact's window in whole seconds of a clock where the plan's t = 0 is ``zero_s``,
    rounded inward: (ceil(zero_s + start), floor(zero_s + end), contact); contacts with no whole
    second left are returned apart."""
    kept, dropped = [], []
    for c in plan:
        a, b = math.ceil(zero_s + c.start_s), math.floor(zero_s + c.end_s)
        if b > a:
            kept.append((a, b, c))
        else:
            dropped.append(c)
    return kept, dropped


def write_contact_plan(plan: ContactPlan, fmt: str, stream, *, ground_stations: list[str] | None = None,
                       epoch_utc: datetime | None = None, unix_time: bool = False,
                       ion_times: str = "relative") -> Written:
    """Write ``plan`` to a text stream in ``fmt`` (csv | ion | hdtn-json).

    ``epoch_utc``: the scenario epoch (the instant of t = 0; required for ION, whose file starts with
    it as the ``@`` reference time, and for HDTN with ``unix_time``, which writes Unix seconds for
    HDTN's ``--use-unix-timestamp``; otherwise HDTN times are seconds since the epoch).
    ``ion_times``: ``relative`` (``+N`` after the ``@`` line) or ``absolute`` (every contact and
    range start and end as ``yyyy/mm/dd-hh:mm:ss`` UTC, ionadmin's other form: the lines mean the same
    instants whatever reference time the node holds, e.g. when loaded after another file's ``@``)."""
    out = Written()
    if ion_times not in ("relative", "absolute"):
        raise ContactPlanError(f"ion_times {ion_times!r}: 'relative' or 'absolute'")
    if fmt == "csv":
        w = csv.writer(stream, lineterminator="\n")
        w.writerow(["start_s", "end_s", "origin", "destination", "rate_bps", "range_light_s"])
        for c in plan:
            w.writerow([_fmt(c.start_s), _fmt(c.end_s), c.src, c.dst, _fmt(c.rate_bps), repr(c.range_light_s)])
        out.written = len(plan)
        return out
    if fmt not in CONTACT_PLAN_FORMATS:
        raise ContactPlanError(f"unknown contact plan format {fmt!r} (one of {', '.join(CONTACT_PLAN_FORMATS)})")
    if epoch_utc is not None and epoch_utc.tzinfo is None:
        raise ContactPlanError("epoch_utc must be timezone-aware (UTC)")
    if fmt == "ion" and epoch_utc is None:
        raise ContactPlanError("an ION plan starts with its epoch ('@' line): give epoch_utc")
    if unix_time and epoch_utc is None:
        raise ContactPlanError("unix_time needs epoch_utc")
    epoch_s = epoch_utc.timestamp() if epoch_utc is not None else 0.0
    # the reference second: the epoch's whole second; t = 0 is zero_s on that clock
    ref = math.floor(epoch_s)
    absolute = fmt == "ion" or unix_time
    kept, out.dropped = whole_second_contacts(plan, (epoch_s - ref) if fmt == "ion" else (epoch_s if unix_time else 0.0))
    if absolute and kept and max(b for _a, b, _c in kept) + (ref if fmt == "ion" else 0) > _INT32_MAX:
        raise ContactPlanError("contact plan ends after 19 January 2038, which ION and HDTN cannot represent")
    nn = {n: node_number(n, ground_stations) for n in plan.nodes}
    if fmt == "ion":
        stamp = datetime.fromtimestamp(ref, UTC).strftime(_ION_TS)
        how = "+N = N s after it" if ion_times == "relative" else "times are absolute (UTC)"
        stream.write(f"# contact plan (ionadmin commands). Reference time: the scenario epoch {stamp} UTC; {how}"
                     "\n# (windows rounded inward to whole seconds, rates in bytes/s rounded down, one-way "
                     "light times in s rounded up)\n")
        stream.write(f"@ {stamp}\n")

        def when(t: int) -> str:
            return f"+{t}" if ion_times == "relative" else datetime.fromtimestamp(ref + t, UTC).strftime(_ION_TS)

        for a, b, c in kept:
            rate = math.floor(c.rate_bps / 8.0)
            if rate < 1:
                raise ContactPlanError(f"contact {c.src}->{c.dst} at {c.start_s} s: rate {c.rate_bps} bit/s is below "
                                       "ION's 1 byte/s")
            stream.write(f"a contact {when(a)} {when(b)} {nn[c.src]} {nn[c.dst]} {rate}\n")
        for a, b, c in kept:
            stream.write(f"a range {when(a)} {when(b)} {nn[c.src]} {nn[c.dst]} {math.ceil(c.range_light_s)}\n")
    else:
        rows = []
        for i, (a, b, c) in enumerate(kept):
            rate = math.floor(c.rate_bps)
            if rate < 1:
                raise ContactPlanError(f"contact {c.src}->{c.dst} at {c.start_s} s: rate {c.rate_bps} bit/s is below "
                                       "1 bit/s")
            rows.append({"contact": i, "source": nn[c.src], "dest": nn[c.dst], "startTime": a, "endTime": b,
                         "rateBitsPerSec": rate, "owlt": math.ceil(c.range_light_s)})
        if rows and max(r["endTime"] for r in rows) > _INT32_MAX:
            raise ContactPlanError("contact plan times exceed HDTN's int startTime/endTime (2^31 - 1 s)")
        json.dump({"contacts": rows}, stream, indent=1)
        stream.write("\n")
    out.written = len(kept)
    return out
