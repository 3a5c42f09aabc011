"""Catalogue element sets: TLE / 3LE and CCSDS OMM files (XML, KVN, JSON, CSV) -> SGP4 satellites.

Formats (all read into one :class:`ElementSet` per satellite, the OMM keywords as text):

* TLE / 3LE (NORAD two-line elements, optionally each after a name line, "0 NAME" or "NAME"):
  the fixed columns of Hoots & Roehrich, Spacetrack Report #3 (1980), with the modulo-10 checksum of
  each line (digits, '-' counts 1; sgp4.io.compute_checksum) checked, and Alpha-5 catalogue numbers
  (a letter for the leading digits, I and O skipped) read;
* CCSDS OMM, CCSDS 502.0-B-3 "Orbit Data Messages" section 4, the SGP4/SDP4 mean elements with
  their TLE parameters (MEAN_ELEMENT_THEORY SGP/SGP4): the XML of the standard's XML schema (read
  by ``sgp4.omm.parse_xml``), the KVN text form (``KEYWORD = value [unit]`` lines, one OMM after
  each ``CCSDS_OMM_VERS``), the JSON array CelesTrak serves (the same keywords as keys) and the CSV
  with those keywords as header (``sgp4.omm.parse_csv``).

Every element set becomes a satellite through one path, ``sgp4.omm.initialize`` (sgp4init with
the WGS-72 constants the elements are fitted with, Vallado et al., AIAA 2006-6753): a TLE is first
written out as the OMM keywords its columns hold (decimal text kept as written, the epoch to the
microsecond), so a TLE and the OMM of the same elements give the same SGP4 satellite, bit for bit.

Validity: SGP4 element sets are a fit over a few days of tracking; their error grows by about 1-3 km
a day in low orbit (Vallado et al. 2006, section 1; Kelso, "Validation of SGP4 and IS-GPS-200D
against GPS precision ephemerides", AAS 07-127). The project uses an element set at most
:data:`VALIDITY_DAYS` days from its epoch, either way: a run must start no earlier than the newest
set's epoch minus that and end no later than the oldest set's epoch plus that.

Bad input is one line naming the file, the line (the OMM's first line, its XML segment, its JSON
object or CSV row) and the problem: :class:`ElementsError`.

How we know it is right: tests/unit/test_elements.py - each TLE propagated through this path equals
sgp4's own TLE reader (``Satrec.twoline2rv``) within 1 m over a day; the same elements as TLE, 3LE,
OMM XML, KVN, JSON and CSV give identical satellites; a bad checksum, a short line, a missing OMM
keyword, a repeated catalogue number are one line naming file and line.
"""

from __future__ import annotations

import datetime as _dt
import io
import json
import math
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from decimal import Decimal, InvalidOperation
from pathlib import Path

from sgp4 import omm
from sgp4.api import Satrec
from sgp4.io import compute_checksum

from msgs_json.names import MAX_NORAD, catalogue_sat_name
from msgs_json.text_input import TextInputError, read_text

__all__ = [
    "VALIDITY_DAYS",
    "ElementSet",
    "ElementsError",
    "read_elements",
    "read_omm",
    "read_tle",
    "validity_error",
]

VALIDITY_DAYS = 7.0  # an element set is used at most this many days from its epoch (module docstring)
MAX_ELEMENT_FILE_BYTES = 64 * 2 ** 20  # the whole active catalogue as OMM XML is ~30 MB

# the OMM keywords SGP4 needs (CCSDS 502.0-B-3 table 4-3; sgp4.omm.initialize reads them)
REQUIRED = ("NORAD_CAT_ID", "EPOCH", "MEAN_MOTION", "ECCENTRICITY", "INCLINATION", "RA_OF_ASC_NODE",
            "ARG_OF_PERICENTER", "MEAN_ANOMALY", "BSTAR", "MEAN_MOTION_DOT", "MEAN_MOTION_DDOT")
# keywords sgp4.omm.initialize copies into the satellite record but SGP4 does not use: defaults
_OPTIONAL = {"CLASSIFICATION_TYPE": "U", "OBJECT_ID": "", "EPHEMERIS_TYPE": "0", "ELEMENT_SET_NO": "999",
             "REV_AT_EPOCH": "0"}


class ElementsError(ValueError):
    """An element file that cannot be used; the message is one line naming file, line and problem."""


@dataclass(frozen=True)
class ElementSet:
    """One satellite's mean elements: ``fields`` are OMM keywords -> text (every :data:`REQUIRED`
    one, EPOCH as ``YYYY-MM-DDTHH:MM:SS.ffffff``); ``label`` the catalogue's name ("" when none);
    ``where`` the file and line it came from."""

    norad: int
    label: str
    fields: tuple[tuple[str, str], ...]
    epoch: _dt.datetime  # UTC, aware
    where: str

    @property
    def name(self) -> str:
        """The satellite's node name (msgs_json/names.py catalogue form)."""
        return catalogue_sat_name(self.norad)

    @property
    def epoch_utc(self) -> str:
        return self.epoch.strftime("%Y-%m-%dT%H:%M:%S.%f") + "Z"

    def field(self, key: str) -> str:
        return dict(self.fields)[key]

    def satrec(self) -> Satrec:
        """The SGP4 satellite (WGS-72, improved mode) through ``sgp4.omm.initialize``."""
        f = dict(_OPTIONAL)
        f.update(self.fields)
        sat = Satrec()
        omm.initialize(sat, f)
        if sat.error:
            raise ElementsError(f"{self.where}: SGP4 cannot use these elements (sgp4init error {sat.error})")
        return sat


# ---- reading -------------------------------------------------------------------------------------
def read_elements(path: str | Path, kind: str) -> list[ElementSet]:
    """The element sets of a ``kind`` 'tle' or 'omm' file, in file order."""
    if kind == "tle":
        return read_tle(path)
    if kind == "omm":
        return read_omm(path)
    raise ValueError(f"element file kind {kind!r}: must be 'tle' or 'omm'")


def _text(path: Path, what: str) -> str:
    try:
        return read_text(path, what, MAX_ELEMENT_FILE_BYTES)
    except TextInputError as exc:
        raise ElementsError(str(exc)) from None
    except OSError as exc:
        raise ElementsError(f"{path}: cannot read the {what} ({exc.strerror or exc})") from None


def _check_unique(sets: list[ElementSet], path: Path) -> list[ElementSet]:
    seen: dict[int, str] = {}
    for e in sets:
        if e.norad in seen:
            raise ElementsError(f"{e.where}: NORAD {e.norad} again (first at {seen[e.norad]}); one element set "
                                "per satellite")
        seen[e.norad] = e.where
    if not sets:
        raise ElementsError(f"{path}: no element sets in the file")
    return sets


# ---- TLE / 3LE -----------------------------------------------------------------------------------
_ALPHA5 = "ABCDEFGHJKLMNPQRSTUVWXYZ"  # Alpha-5: A = 10 .. Z = 33 (I and O skipped)


def _catalogue_number(text: str, where: str) -> int:
    t = text.strip()
    if t[:1].isalpha() and t[:1].upper() in _ALPHA5 and t[1:].isdigit() and len(t) == 5:
        return (10 + _ALPHA5.index(t[0].upper())) * 10000 + int(t[1:])
    if not t.isdigit():
        raise ElementsError(f"{where}: catalogue number {text!r} (columns 3-7) is not a number")
    return int(t)


def _implied(text: str, what: str, where: str) -> str:
    """A TLE 'implied decimal point' field (' 12345-4' = 0.12345e-4) as decimal text."""
    t = text.strip().replace(" ", "")
    m = re.fullmatch(r"([+-]?)(\d{1,5})([+-]\d)", t)
    if m is None:
        raise ElementsError(f"{where}: {what} {text!r} is not a TLE exponent field like ' 12345-4'")
    return f"{m.group(1)}0.{m.group(2)}e{m.group(3)}"


def _number(text: str, what: str, where: str, prefix: str = "") -> str:
    t = text.strip()
    try:
        v = float(prefix + t)
    except ValueError:
        v = math.nan
    if not t or not math.isfinite(v):
        raise ElementsError(f"{where}: {what} {text!r} is not a number")
    return prefix + t


def _tle_epoch(text: str, where: str) -> _dt.datetime:
    t = text.strip()
    try:
        yy, day = int(t[:2]), Decimal(t[2:])
    except (ValueError, InvalidOperation):
        raise ElementsError(f"{where}: epoch {text!r} (columns 19-32) is not YYDDD.DDDDDDDD") from None
    if not 1 <= day < 367:
        raise ElementsError(f"{where}: epoch day of year {day} outside 1..366")
    year = 2000 + yy if yy < 57 else 1900 + yy  # Spacetrack Report #3: 57..99 -> 19xx
    us = int(((day - 1) * 86_400_000_000).to_integral_value())  # to the microsecond, half to even
    return _dt.datetime(year, 1, 1, tzinfo=_dt.UTC) + _dt.timedelta(microseconds=us)


def _check_line(line: str, n: int, where: str) -> None:
    if len(line) < 69:
        raise ElementsError(f"{where}: TLE line {n} has {len(line)} characters, needs 69 (with its checksum)")
    if not line[68].isdigit():
        raise ElementsError(f"{where}: TLE line {n} has no checksum digit in column 69 (got {line[68]!r})")
    want = compute_checksum(line)
    if int(line[68]) != want:
        raise ElementsError(f"{where}: TLE line {n} checksum is {line[68]}, its columns 1-68 give {want} "
                            "(a damaged line)")


def _tle_fields(name: str, l1: str, l2: str, where: str, where2: str) -> ElementSet:
    _check_line(l1, 1, where)
    _check_line(l2, 2, where2)
    norad = _catalogue_number(l1[2:7], where)
    if _catalogue_number(l2[2:7], where2) != norad:
        raise ElementsError(f"{where2}: catalogue number {l2[2:7].strip()!r} differs from line 1's {l1[2:7].strip()!r}")
    if not 1 <= norad <= MAX_NORAD:
        raise ElementsError(f"{where}: catalogue number {norad} outside 1..{MAX_NORAD}")
    epoch = _tle_epoch(l1[18:32], where)
    intl = l1[9:17].strip()
    fields = {
        "OBJECT_NAME": name,
        "OBJECT_ID": (f"{'20' if int(intl[:2] or 0) < 57 else '19'}{intl[:2]}-{intl[2:]}" if len(intl) > 2 else ""),
        "CLASSIFICATION_TYPE": l1[7].strip() or "U",
        "NORAD_CAT_ID": str(norad),
        "EPOCH": epoch.strftime("%Y-%m-%dT%H:%M:%S.%f"),
        "MEAN_MOTION_DOT": _number(l1[33:43], "first derivative of mean motion (columns 34-43)", where),
        "MEAN_MOTION_DDOT": _implied(l1[44:52], "second derivative of mean motion (columns 45-52)", where),
        "BSTAR": _implied(l1[53:61], "BSTAR (columns 54-61)", where),
        "EPHEMERIS_TYPE": l1[62].strip() or "0",
        "ELEMENT_SET_NO": l1[64:68].strip() or "999",
        "INCLINATION": _number(l2[8:16], "inclination (columns 9-16)", where2),
        "RA_OF_ASC_NODE": _number(l2[17:25], "right ascension of the node (columns 18-25)", where2),
        "ECCENTRICITY": _number(l2[26:33], "eccentricity (columns 27-33)", where2, prefix="0."),
        "ARG_OF_PERICENTER": _number(l2[34:42], "argument of perigee (columns 35-42)", where2),
        "MEAN_ANOMALY": _number(l2[43:51], "mean anomaly (columns 44-51)", where2),
        "MEAN_MOTION": _number(l2[52:63], "mean motion (columns 53-63)", where2),
        "REV_AT_EPOCH": l2[63:68].strip() or "0",
    }
    if not fields["EPHEMERIS_TYPE"].isdigit():
        fields["EPHEMERIS_TYPE"] = "0"
    if not fields["ELEMENT_SET_NO"].isdigit():
        fields["ELEMENT_SET_NO"] = "999"
    if not fields["REV_AT_EPOCH"].isdigit():
        fields["REV_AT_EPOCH"] = "0"
    return _element_set(fields, where)


def read_tle(path: str | Path) -> list[ElementSet]:
    """Element sets of a TLE or 3LE file (blank lines skipped)."""
    path = Path(path)
    lines = [(k + 1, ln.rstrip("\r\n").rstrip()) for k, ln in enumerate(_text(path, "TLE file").splitlines())]
    lines = [(k, ln) for k, ln in lines if ln.strip()]
    out, i, name = [], 0, ""
    while i < len(lines):
        k, ln = lines[i]
        if ln.startswith("1 "):
            if i + 1 >= len(lines) or not lines[i + 1][1].startswith("2 "):
                raise ElementsError(f"{path}:{k}: TLE line 1 is not followed by a line 2 (starting '2 ')")
            k2, ln2 = lines[i + 1]
            out.append(_tle_fields(name, ln, ln2, f"{path}:{k}", f"{path}:{k2}"))
            name, i = "", i + 2
        elif ln.startswith("2 "):
            raise ElementsError(f"{path}:{k}: TLE line 2 without a line 1 before it")
        else:
            if name:
                raise ElementsError(f"{path}:{k}: expected TLE line 1 (starting '1 ') after the name line "
                                    f"{name!r}, got {ln[:30]!r}")
            name = ln[2:].strip() if ln.startswith("0 ") else ln.strip()
            i += 1
    if name:
        raise ElementsError(f"{path}:{lines[-1][0]}: name line {name!r} without its two TLE lines")
    return _check_unique(out, path)


# ---- OMM -----------------------------------------------------------------------------------------
_EPOCH_RE = re.compile(r"^(\d{4})-(?:(\d{2})-(\d{2})|(\d{3}))T(\d{2}):(\d{2}):(\d{2})(?:\.(\d+))?Z?$")


def _omm_epoch(text: str, where: str) -> _dt.datetime:
    m = _EPOCH_RE.match(text.strip())
    if m is None:
        raise ElementsError(f"{where}: EPOCH {text!r} is not YYYY-MM-DDThh:mm:ss[.f] (UTC)")
    y, mo, d, doy, hh, mi, ss, frac = m.groups()
    try:
        base = (_dt.datetime(int(y), int(mo), int(d), tzinfo=_dt.UTC) if doy is None
                else _dt.datetime(int(y), 1, 1, tzinfo=_dt.UTC) + _dt.timedelta(days=int(doy) - 1))
    except ValueError as exc:
        raise ElementsError(f"{where}: EPOCH {text!r}: {exc}") from None
    us = int((Decimal("0." + frac) * 1_000_000).to_integral_value()) if frac else 0
    return base + _dt.timedelta(hours=int(hh), minutes=int(mi), seconds=int(ss), microseconds=us)


def _element_set(raw: dict, where: str) -> ElementSet:
    """An ElementSet from OMM keyword -> value (text or number), checked."""
    f = {str(k).strip().upper(): ("" if v is None else str(v).strip()) for k, v in raw.items()}
    missing = [k for k in REQUIRED if not f.get(k)]
    if missing:
        raise ElementsError(f"{where}: OMM without {', '.join(missing)} (SGP4 needs {', '.join(REQUIRED)})")
    for k in REQUIRED[2:]:
        try:
            v = float(f[k])
        except ValueError:
            v = math.nan
        if not math.isfinite(v):
            raise ElementsError(f"{where}: {k} {f[k]!r} is not a number")
    if not f["NORAD_CAT_ID"].isdigit() or not 1 <= int(f["NORAD_CAT_ID"]) <= MAX_NORAD:
        raise ElementsError(f"{where}: NORAD_CAT_ID {f['NORAD_CAT_ID']!r} is not a catalogue number 1..{MAX_NORAD}")
    if not 0.0 <= float(f["ECCENTRICITY"]) < 1.0:
        raise ElementsError(f"{where}: ECCENTRICITY {f['ECCENTRICITY']} outside 0..1")
    if not float(f["MEAN_MOTION"]) > 0.0:
        raise ElementsError(f"{where}: MEAN_MOTION {f['MEAN_MOTION']} must be > 0 [rev/day]")
    if not 0.0 <= float(f["INCLINATION"]) <= 180.0:
        raise ElementsError(f"{where}: INCLINATION {f['INCLINATION']} outside 0..180 deg")
    theory = f.get("MEAN_ELEMENT_THEORY", "SGP4").upper()
    if theory not in ("SGP4", "SGP/SGP4", "SGP", "SDP4"):
        raise ElementsError(f"{where}: MEAN_ELEMENT_THEORY {theory!r}: only SGP4 mean elements can be used")
    epoch = _omm_epoch(f["EPOCH"], where)
    f["EPOCH"] = epoch.strftime("%Y-%m-%dT%H:%M:%S.%f")  # what sgp4.omm.initialize parses
    f["NORAD_CAT_ID"] = str(int(f["NORAD_CAT_ID"]))
    for k, default in _OPTIONAL.items():
        if k in ("EPHEMERIS_TYPE", "ELEMENT_SET_NO", "REV_AT_EPOCH") and not f.get(k, "").isdigit():
            f[k] = default
    keep = tuple(sorted((k, v) for k, v in f.items() if k in REQUIRED or k in _OPTIONAL))
    es = ElementSet(int(f["NORAD_CAT_ID"]), f.get("OBJECT_NAME", ""), keep, epoch, where)
    es.satrec()  # SGP4 accepts them (else one line)
    return es


def _kvn(text: str, path: Path) -> list[tuple[dict, str]]:
    out, cur, start = [], None, 0
    for k, ln in enumerate(text.splitlines(), 1):
        s = ln.strip()
        if not s or s.startswith("COMMENT"):
            continue
        if "=" not in s:
            raise ElementsError(f"{path}:{k}: not a KVN line 'KEYWORD = value': {s[:40]!r}")
        key, val = (p.strip() for p in s.split("=", 1))
        val = re.sub(r"\s*\[[^\]]*\]\s*$", "", val)  # a unit: 'MEAN_MOTION = 14.3 [rev/day]'
        if key == "CCSDS_OMM_VERS":
            if cur is not None:
                out.append((cur, f"{path}:{start}"))
            cur, start = {}, k
            continue
        if cur is None:
            raise ElementsError(f"{path}:{k}: KVN OMM must start with 'CCSDS_OMM_VERS = ...', got {key!r}")
        cur[key] = val
    if cur is not None:
        out.append((cur, f"{path}:{start}"))
    return out


def _json(text: str, path: Path) -> list[tuple[dict, str]]:
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ElementsError(f"{path}:{exc.lineno}: not valid JSON ({exc.msg})") from None
    items = doc if isinstance(doc, list) else [doc]
    out = []
    for i, it in enumerate(items):
        if not isinstance(it, dict):
            raise ElementsError(f"{path}: JSON object {i + 1}: expected an object of OMM keywords, got {type(it).__name__}")
        out.append((it, f"{path}: JSON object {i + 1}"))
    return out


def _xml(text: str, path: Path) -> list[tuple[dict, str]]:
    # a default namespace (xmlns="urn:ccsds:schema:ndmxml") would hide the plain tag names
    # sgp4.omm.parse_xml looks for; prefixed ones (xmlns:xsi) do not
    text = re.sub(r'\sxmlns="[^"]*"', "", text)
    try:
        segs = list(omm.parse_xml(io.StringIO(text)))
    except ET.ParseError as exc:
        raise ElementsError(f"{path}:{exc.position[0]}: not well-formed XML ({exc})") from None
    except (AttributeError, TypeError):  # sgp4.omm.parse_xml: a segment without metadata/meanElements/...
        raise ElementsError(f"{path}: an OMM XML segment lacks its metadata, meanElements or tleParameters "
                            "(CCSDS 502.0-B-3 section 4)") from None
    return [(f, f"{path}: XML segment {i + 1}") for i, f in enumerate(segs)]


def _csv(text: str, path: Path) -> list[tuple[dict, str]]:
    return [(row, f"{path}:{i + 2}") for i, row in enumerate(omm.parse_csv(io.StringIO(text)))]


def read_omm(path: str | Path) -> list[ElementSet]:
    """Element sets of a CCSDS OMM file: XML, KVN, JSON or CSV (told apart by the first characters)."""
    path = Path(path)
    text = _text(path, "OMM file")
    head = text.lstrip()[:200]
    if head.startswith("<"):
        raw = _xml(text, path)
    elif head.startswith(("[", "{")):
        raw = _json(text, path)
    elif head.startswith(("CCSDS_OMM_VERS", "COMMENT")):
        raw = _kvn(text, path)
    elif "NORAD_CAT_ID" in head.splitlines()[0] and "," in head.splitlines()[0]:
        raw = _csv(text, path)
    else:
        raise ElementsError(f"{path}: not an OMM file (XML '<ndm>', KVN 'CCSDS_OMM_VERS = ...', a JSON array "
                            "or a CSV with OMM keywords as header)")
    return _check_unique([_element_set(f, where) for f, where in raw], path)


# ---- validity ------------------------------------------------------------------------------------
def validity_error(sets, start: _dt.datetime, end: _dt.datetime) -> str | None:
    """Why a run from ``start`` to ``end`` (UTC) cannot use the element sets ``sets`` (one phrase),
    or None: it must start no earlier than the newest epoch minus :data:`VALIDITY_DAYS` and end no
    later than the oldest epoch plus it."""
    sets = list(sets)
    if not sets:
        return None
    newest = max(sets, key=lambda e: e.epoch)
    oldest = min(sets, key=lambda e: e.epoch)
    lo = newest.epoch - _dt.timedelta(days=VALIDITY_DAYS)
    hi = oldest.epoch + _dt.timedelta(days=VALIDITY_DAYS)
    fmt = "%Y-%m-%dT%H:%M:%SZ"
    if start < lo or end > hi:
        span = (f"{lo.strftime(fmt)} .. {hi.strftime(fmt)}" if lo <= hi else
                f"none: the epochs are {(newest.epoch - oldest.epoch).total_seconds() / 86400:.1f} days apart")
        return (f"the run {start.strftime(fmt)} .. {end.strftime(fmt)} is outside the element sets' validity "
                f"({VALIDITY_DAYS:g} days either side of each epoch: newest {newest.name} {newest.epoch.strftime(fmt)}, "
                f"oldest {oldest.name} {oldest.epoch.strftime(fmt)}; usable {span})")
    return None
