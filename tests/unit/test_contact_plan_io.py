"""Contact plan files (orbit_clock/contact_plan_io.py): the study's CSV, ION, HDTN JSON, both ways,
and the lines we write checked against how ION and HDTN read them.

The two mirrors below restate the other projects' reading rules, independently of our reader:
* ionadmin (nasa-jpl/ION-DTN ici/utils/ionadmin.c ``processLine`` / ``executeAdd``, ici/library/ion.c
  ``readTimestamp``): whitespace tokens (at most 9), ``#`` comments, ``@ TIME`` sets the reference
  time, ``a contact FROM_T TO_T FROM TO RATE [CONF]`` (7 or 8 tokens, start "0"/"-1" are the
  hypothetical/registration forms), ``a range FROM_T TO_T A B OWLT`` (7 tokens); a time is
  ``+N`` (reference + strtol(N, base 0)) or ``%4d/%2d/%2d-%2d:%2d:%2d`` UTC; node numbers > 0;
  RATE and OWLT ``strtol(.., 0)``; end must be after start. The mirror also reports every token
  whose number strtol would cut short (a fraction, an exponent) or read in another base.
* HDTN (nasa/HDTN module/router/src/router.cpp ``ProcessContacts``, common/cgr/src/libcgr.cpp
  ``cp_load``): Boost ptree keeps each JSON value's text; ``get<int>(key, 0)`` /
  ``get<time_t>(key, 0)`` / ``get<uint64_t>(key)`` extract it with a stream and accept it only when
  the whole text is one integer (otherwise the default, or an exception for rateBitsPerSec, whose
  handler falls back to the rate 0).
HDTN's own example plans (module/router/contact_plans/*.json, checked by hand at commit ad79ba0)
hold JSON integers in every field, ``owlt`` absent in some, and ``rateBitsPerSec`` as a string of
digits in contactPlanIpn2.1.json; the fixtures below have those field types (our own numbers).
"""

import io
import json
import math
import re
from datetime import UTC, datetime

import pytest

from orbit_clock.contact_plan import Contact, ContactPlan
from orbit_clock.contact_plan_io import (
    CONTACT_PLAN_FORMATS,
    ContactPlanError,
    parse_contact_plan,
    read_contact_plan,
    write_contact_plan,
)

EPOCH = datetime(2000, 1, 1, 11, 59, 28, tzinfo=UTC)
EPOCH_S = 946727968
PLAN = ContactPlan([Contact(0.0, 21600.0, "sat_11", "sat_12", 1000.0, 2e-05),
                    Contact(381.5, 2340.498, "sat_11", "sat_21", 8000.0, 1.2)])


def _write(plan, fmt, **kw) -> str:
    s = io.StringIO()
    write_contact_plan(plan, fmt, s, epoch_utc=EPOCH, **kw)
    return s.getvalue()


# -- the mirror of ionadmin ----------------------------------------------------------------------------

def _strtol0(tok: str) -> tuple[int, str]:
    """strtol(tok, &end, 0): (value, the part it did not read)."""
    m = re.match(r"\s*([+-]?)(0[xX][0-9a-fA-F]+|0[0-7]*|[1-9][0-9]*)", tok)
    if not m:
        return 0, tok
    d = m.group(2)
    v = int(d, 16) if d[:2].lower() == "0x" else (int(d, 8) if d.startswith("0") and len(d) > 1 else int(d))
    return (-v if m.group(1) == "-" else v), tok[m.end():]


def ionadmin(text: str):
    """(contacts, ranges, problems): absolute (from, to, a, b, value) as ionadmin would store them,
    and the tokens it would read differently from what they say."""
    ref, contacts, ranges, problems = None, [], [], []

    def number(tok, what):
        v, rest = _strtol0(tok)
        if rest or (tok.lstrip("+-").startswith("0") and tok.lstrip("+-") != "0"):
            problems.append(f"{what} {tok!r} read as {v}")
        return v

    def when(tok):
        if tok.startswith("+"):
            if ref is None:
                problems.append(f"relative time {tok} with no reference time (counts from ionadmin's start)")
            return (ref or 0) + number(tok[1:], "time")
        m = re.fullmatch(r"(\d{1,4})/(\d{1,2})/(\d{1,2})-(\d{1,2}):(\d{1,2}):(\d{1,2})", tok)
        assert m, f"timestamp format invalid: {tok}"
        return int(datetime(*map(int, m.groups()), tzinfo=UTC).timestamp())

    for line in text.splitlines():
        tokens = line.split()
        if not tokens or tokens[0].startswith("#"):
            continue
        assert len(tokens) <= 9, f"too many tokens: {line}"
        if tokens[0] == "@":
            assert len(tokens) == 2 and tokens[1] != "0", line
            ref = when(tokens[1])
        elif tokens[:2] == ["a", "contact"]:
            assert len(tokens) in (7, 8), f"syntax error: {line}"
            assert tokens[2] not in ("0", "-1"), f"not a scheduled contact: {line}"
            t0, t1 = when(tokens[2]), when(tokens[3])
            a, b = number(tokens[4], "node"), number(tokens[5], "node")
            assert a > 0 and b > 0 and t1 > t0, line
            contacts.append((t0, t1, a, b, number(tokens[6], "rate")))
        elif tokens[:2] == ["a", "range"]:
            assert len(tokens) == 7, f"syntax error: {line}"
            t0, t1 = when(tokens[2]), when(tokens[3])
            assert t1 > t0, line
            ranges.append((t0, t1, number(tokens[4], "node"), number(tokens[5], "node"), number(tokens[6], "owlt")))
        else:
            raise AssertionError(f"not a contact plan command: {line}")
    return contacts, ranges, problems


# -- the mirror of HDTN's ptree reads -----------------------------------------------------------------

def _ptree(text: str) -> dict:
    """JSON as Boost's json_parser keeps it: every value as its text."""
    return json.loads(text, parse_int=str, parse_float=str, parse_constant=str)


def _get_int(row: dict, key: str, lo: int, hi: int, default=None):
    """ptree get<T>(key[, default]): the value when its whole text is one integer in T's range;
    else the default (or ptree_bad_data when there is none: None here)."""
    v = row.get(key)
    if isinstance(v, str) and re.fullmatch(r"\s*[+-]?\d+\s*", v) and lo <= int(v) <= hi:
        return int(v)
    return default


INT, TIME_T, U64 = (-2**31, 2**31 - 1), (-2**63, 2**63 - 1), (0, 2**64 - 1)


def hdtn(text: str) -> list[dict]:
    """Each contact as HDTN's router (ProcessContacts) and CGR (cp_load) read it."""
    out = []
    for row in _ptree(text)["contacts"]:
        rate = _get_int(row, "rateBitsPerSec", *U64)
        if rate is None:  # GetRateBpsFromPtree: then the deprecated "rate" [Mb/s], then 0
            rate = (_get_int(row, "rate", *U64) or 0) * 1_000_000
        out.append({"contact": _get_int(row, "contact", *INT, default=0),
                    "source": _get_int(row, "source", *INT, default=0), "dest": _get_int(row, "dest", *INT, default=0),
                    "startTime": _get_int(row, "startTime", *INT, default=0),
                    "endTime": _get_int(row, "endTime", *INT, default=0),
                    "cgr_start": _get_int(row, "startTime", *TIME_T, default=0),
                    "cgr_end": _get_int(row, "endTime", *TIME_T, default=0),
                    "owlt": _get_int(row, "owlt", *TIME_T, default=0), "rateBitsPerSec": rate})
    return out


# -- the tests ----------------------------------------------------------------------------------------

def test_study_plan(paper_inputs):
    p = read_contact_plan(paper_inputs / "contact_plan_3p_8s.csv", rate_bps=1000)
    assert len(p) == 1384 and len(p.nodes) == 24 and all(c.rate_bps == 1000 for c in p)
    assert p.contacts[0] == Contact(0.0, 21600.0, "sat_11", "sat_12", 1000.0, 2e-05)


def _rounded(c: Contact, fmt: str) -> Contact:
    rate = math.floor(c.rate_bps / 8) * 8 if fmt == "ion" else math.floor(c.rate_bps)
    return Contact(float(math.ceil(c.start_s)), float(math.floor(c.end_s)), c.src, c.dst, float(rate),
                   float(math.ceil(c.range_light_s)))


@pytest.mark.parametrize("fmt", CONTACT_PLAN_FORMATS)
def test_round_trip(fmt, paper_inputs):
    for plan in (PLAN, read_contact_plan(paper_inputs / "contact_plan_3p_8s.csv", rate_bps=1000)):
        back = parse_contact_plan(_write(plan, fmt), fmt)
        if fmt == "csv":
            assert back.contacts == plan.contacts
            continue
        assert back.contacts == ContactPlan([_rounded(c, fmt) for c in plan]).contacts
        for got, c in zip(back, plan, strict=True):  # (the plans sort the same way: no start crosses a second)
            assert c.start_s <= got.start_s < got.end_s <= c.end_s  # written window inside the true one
            assert got.range_light_s >= c.range_light_s and got.rate_bps <= c.rate_bps


def test_ion_text_exact():
    lines = [x for x in _write(PLAN, "ion").splitlines() if not x.startswith("#")]
    assert lines == ["@ 2000/01/01-11:59:28",
                     "a contact +0 +21600 11 12 125",  # ION rates are bytes/s
                     "a contact +382 +2340 11 21 1000",  # [381.5, 2340.498] rounded inward
                     "a range +0 +21600 11 12 1",  # 20 us of light time, rounded up to ION's whole seconds
                     "a range +382 +2340 11 21 2"]


def test_ion_absolute_times_mean_the_same_instants():
    lines = [x for x in _write(PLAN, "ion", ion_times="absolute").splitlines() if not x.startswith("#")]
    assert lines == ["@ 2000/01/01-11:59:28",
                     "a contact 2000/01/01-11:59:28 2000/01/01-17:59:28 11 12 125",
                     "a contact 2000/01/01-12:05:50 2000/01/01-12:38:28 11 21 1000",  # +382, +2340
                     "a range 2000/01/01-11:59:28 2000/01/01-17:59:28 11 12 1",
                     "a range 2000/01/01-12:05:50 2000/01/01-12:38:28 11 21 2"]
    # ionadmin (the mirror) reads both forms as the same instants, whatever '@' came before
    rel, rel_ranges, p1 = ionadmin(_write(PLAN, "ion"))
    other_ref = "@ 2026/11/27-12:00:00\n" + "\n".join(ln for ln in lines if not ln.startswith("@"))
    ab, ab_ranges, p2 = ionadmin(other_ref)
    assert p1 == p2 == [] and rel == ab and rel_ranges == ab_ranges
    assert parse_contact_plan("\n".join(lines), "ion").contacts == parse_contact_plan(_write(PLAN, "ion"), "ion").contacts
    with pytest.raises(ContactPlanError, match="ion_times"):
        _write(PLAN, "ion", ion_times="sometimes")


def test_ion_mirror_catches_what_ionadmin_reads_differently():
    # the plan as we wrote it before whole seconds: fractions cut by strtol, owlt 2e-05 read as 2 s
    old = "a contact +381.5 +2340.498 11 21 1000\na range +0 +21600 11 12 2e-05\n"
    _c, ranges, problems = ionadmin("@ 2000/01/01-11:59:28\n" + old)
    assert ranges[0][4] == 2 and len(problems) == 3, problems
    _c, _r, problems = ionadmin(old)
    assert any("no reference time" in p for p in problems)
    _c, _r, problems = ionadmin("@ 2000/01/01-11:59:28\na contact +010 +20 11 12 125\n")
    assert problems == ["time '010' read as 8"]


def test_paper_plan_as_ionadmin_reads_it():
    from bringup.scenario.config import load_scenario
    from orbit_clock.ground_passes import ground_contact_plan, station_names
    from orbit_clock.isl import isl_contact_plan
    from orbit_clock.propagation import build_constellation

    sc = load_scenario("paper")
    assert sc.epoch == EPOCH
    cons = build_constellation(sc)
    plan = ContactPlan(isl_contact_plan(sc, cons).contacts + ground_contact_plan(sc, cons).contacts)
    gs = station_names(sc)
    text = io.StringIO()
    w = write_contact_plan(plan, "ion", text, ground_stations=gs, epoch_utc=sc.epoch)
    contacts, ranges, problems = ionadmin(text.getvalue())
    assert problems == []
    assert w.written == len(contacts) == len(ranges) == len(plan) - len(w.dropped) and len(plan) > 1500
    kept = [c for c in plan if c not in w.dropped]
    for (t0, t1, a, b, rate), (r0, r1, ra, rb, owlt), c in zip(contacts, ranges, kept, strict=True):
        assert EPOCH_S + c.start_s <= t0 < t1 <= EPOCH_S + c.end_s and t0 - 1 < EPOCH_S + c.start_s
        assert t1 + 1 > EPOCH_S + c.end_s and rate * 8 == c.rate_bps and (r0, r1, ra, rb) == (t0, t1, a, b)
        assert owlt == 1 >= c.range_light_s  # LEO light times: milliseconds, rounded up to 1 s
    assert all(c.duration_s < 2 for c in w.dropped)


def test_ion_reading_follows_ionadmin():
    text = ("# hand-written\n@ 2000/01/01-11:59:28\na contact +10 +20 11 12 125\n@ +100\n"
            "a contact +0 2000/01/01-12:02:00 12 11 125 0.9\na range +0 +1000 11 12 3\n1 11 ''\n")
    p = parse_contact_plan(text, "ion")  # times from the first '@'
    assert p.contacts == [Contact(10.0, 20.0, "sat_11", "sat_12", 1000.0, 0.0),
                          Contact(100.0, 152.0, "sat_12", "sat_11", 1000.0, 3.0)]  # range of the other direction
    earlier = datetime(2000, 1, 1, 11, 59, 0, tzinfo=UTC)  # another epoch: the same instants, other numbers
    assert [c.start_s for c in parse_contact_plan(text, "ion", epoch_utc=earlier)] == [38.0, 128.0]
    with pytest.raises(ContactPlanError, match="before any '@'"):
        parse_contact_plan("a contact +10 +20 11 12 125\n", "ion")
    with pytest.raises(ContactPlanError, match="no fixed instant"):
        parse_contact_plan("@ 0\na contact +10 +20 11 12 125\n", "ion")
    with pytest.raises(ContactPlanError, match=r"<text>:2"):
        parse_contact_plan("@ 2000/01/01-11:59:28\na contact +10 +20 11 12\n", "ion")


def test_hdtn_mirror_reads_hdtn_shaped_plans_and_ours():
    # field types of HDTN's own examples: integers everywhere; no owlt; the rate as a string of digits
    examples = [
        ('{"contacts": [{"contact": 0, "source": 102, "dest": 11, "startTime": 0, "endTime": 2000, '
         '"rateBitsPerSec": 1000000000, "owlt": 1}]}'),
        ('{"contacts": [{"contact": 0, "source": 11, "dest": 12, "startTime": 5, "endTime": 50, '
         '"rateBitsPerSec": 1000}]}'),
        ('{"contacts": [{"contact": 0, "source": 11, "dest": 13, "startTime": 10, "endTime": 20, '
         '"rateBitsPerSec": "1000000000", "owlt": 1}]}'),
    ]
    for text in examples:
        (row,) = hdtn(text)
        assert row["endTime"] > row["startTime"] and row["rateBitsPerSec"] > 0
        (ours,) = parse_contact_plan(text, "hdtn-json", ground_stations=["gs_a", "gs_b", "gs_c"])
        assert (ours.start_s, ours.end_s, ours.rate_bps) == (row["startTime"], row["endTime"], row["rateBitsPerSec"])
    # ours: every field read as written, none falls back to a default
    text = _write(PLAN, "hdtn-json")
    doc = json.loads(text)["contacts"]
    assert hdtn(text) == [dict(r, cgr_start=r["startTime"], cgr_end=r["endTime"]) for r in doc]
    assert [(r["startTime"], r["endTime"], r["rateBitsPerSec"], r["owlt"]) for r in doc] == \
        [(0, 21600, 1000, 1), (382, 2340, 8000, 2)]
    unix = json.loads(_write(PLAN, "hdtn-json", unix_time=True))["contacts"]
    assert [r["startTime"] for r in unix] == [EPOCH_S, EPOCH_S + 382]


def test_hdtn_mirror_shows_what_floats_did():
    # the plan as we wrote it before whole numbers: HDTN read endTime 0 (never open) and rate 0
    old = ('{"contacts": [{"contact": 0, "source": 11, "dest": 21, "startTime": 381.5, "endTime": 2340.498, '
           '"rateBitsPerSec": 8000.0, "owlt": 1.2}]}')
    (row,) = hdtn(old)
    assert (row["startTime"], row["endTime"], row["rateBitsPerSec"], row["owlt"]) == (0, 0, 0, 0)
    with pytest.raises(ContactPlanError, match=r"contact 0: startTime = 381.5 is not an integer.*get<int>"):
        parse_contact_plan(old, "hdtn-json")


def test_window_with_no_whole_second_is_left_out_and_counted():
    plan = ContactPlan([Contact(10.2, 10.9, "sat_11", "sat_12", 1000.0, 0.01),
                        Contact(20.5, 22.5, "sat_11", "sat_12", 1000.0, 0.01)])
    s = io.StringIO()
    w = write_contact_plan(plan, "hdtn-json", s, epoch_utc=EPOCH)
    assert w.written == 1 and w.dropped == [plan.contacts[0]]
    assert [(r["startTime"], r["endTime"]) for r in json.loads(s.getvalue())["contacts"]] == [(21, 22)]


def test_errors_name_the_file(tmp_path, paper_inputs):
    with pytest.raises(ContactPlanError, match="rate"):
        read_contact_plan(paper_inputs / "contact_plan_3p_8s.csv")
    bad = tmp_path / "bad.csv"
    bad.write_text("start_s,end_s,origin,destination,range_light_s\n1,x,s11,s12,0\n")
    with pytest.raises(ContactPlanError, match=r"bad.csv:2"):
        read_contact_plan(bad, rate_bps=1)
    with pytest.raises(ContactPlanError, match="suffix"):
        read_contact_plan(tmp_path / "plan.xyz")
    with pytest.raises(ContactPlanError, match="epoch_utc"):
        write_contact_plan(PLAN, "ion", io.StringIO())
    with pytest.raises(ContactPlanError, match="below ION's 1 byte/s"):
        write_contact_plan(ContactPlan([Contact(0, 10, "sat_11", "sat_12", 7.0, 0)]), "ion", io.StringIO(),
                           epoch_utc=EPOCH)
