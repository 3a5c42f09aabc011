"""Catalogue element sets (orbit_clock/elements.py): TLE / 3LE and CCSDS OMM (XML, KVN, JSON, CSV).

Oracles: sgp4's own TLE reader (``Satrec.twoline2rv``, WGS-72) for the TLE path; the same elements
written as every format must give the same SGP4 satellite, bit for bit; bad files are one line
naming file, line and problem (and exit 2 through the CLI). The element sets are real: CelesTrak's
TLEs of the three Sentinel-2 satellites of 1 October 2026, transcribed here.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from sgp4.api import WGS72, Satrec

from orbit_clock.elements import VALIDITY_DAYS, ElementsError, read_omm, read_tle, validity_error
from tests.catalogue_files import OMM, S2, write_omm, write_tle


def _track(sat: Satrec, hours: float = 24.0):
    jd = np.full(200, 2461314.5)
    fr = np.linspace(0.0, hours / 24.0, 200)
    e, r, v = sat.sgp4_array(jd, fr)
    assert not e.any()
    return r, v


def test_tle_path_equals_sgp4_own_reader(tmp_path):
    """Each satellite through the OMM keywords and sgp4.omm.initialize flies as sgp4's own TLE
    reader flies it: within 1 m and 1 mm/s over a day (the epoch is kept to the microsecond)."""
    sets = read_tle(write_tle(tmp_path / "s2.tle"))
    assert [e.name for e in sets] == ["sat_n40697", "sat_n42063", "sat_n60989"]
    assert [e.label for e in sets] == ["SENTINEL-2A", "SENTINEL-2B", "SENTINEL-2C"]
    assert sets[0].epoch_utc == "2026-10-01T07:09:57.007008Z"
    for e, (_n, l1, l2) in zip(sets, S2):
        ra, va = _track(e.satrec())
        rb, vb = _track(Satrec.twoline2rv(l1, l2, WGS72))
        assert np.abs(ra - rb).max() < 1e-3 and np.abs(va - vb).max() < 1e-6


@pytest.mark.parametrize("fmt", ["2le", "3le0", "xml", "kvn", "json", "csv"])
def test_every_format_gives_the_same_satellites(tmp_path, fmt):
    ref = read_tle(write_tle(tmp_path / "ref.tle"))
    if fmt in ("2le", "3le0"):
        got = read_tle(write_tle(tmp_path / "x.tle", three_line=fmt != "2le", zero=True))
    else:
        got = read_omm(write_omm(tmp_path / f"x.{fmt}", fmt))
    assert [e.norad for e in got] == [e.norad for e in ref]
    assert [e.epoch for e in got] == [e.epoch for e in ref]
    for a, b in zip(got, ref):
        ra, va = _track(a.satrec())
        rb, vb = _track(b.satrec())
        assert np.array_equal(ra, rb) and np.array_equal(va, vb)  # bit for bit


def _one_line(exc) -> str:
    msg = str(exc.value)
    assert "\n" not in msg
    return msg


def test_bad_checksum_names_file_and_line(tmp_path):
    p = write_tle(tmp_path / "bad.tle")
    text = p.read_text().replace("347.6046 0001070", "347.6047 0001070")  # one digit off, checksum kept
    p.write_text(text)
    with pytest.raises(ElementsError) as exc:
        read_tle(p)
    msg = _one_line(exc)
    assert msg.startswith(f"{p}:3: ") and "checksum" in msg


@pytest.mark.parametrize("damage,needle", [
    (lambda t: t.replace("14.30818852588907", "14.30818852"), ":3: TLE line 2 has 63 characters"),
    (lambda t: t.replace("1 40697U", "X 40697U"), ":2: expected TLE line 1"),
    (lambda t: t + "1 40697U 15028A   26274.29857647 -.00000002  00000+0  15863-4 0  9990\n"
                   "2 40697  98.5653 347.6046 0001070  85.9280 274.2026 14.30818852588907\n", "NORAD 40697 again"),
])
def test_damaged_tle_files(tmp_path, damage, needle):
    p = write_tle(tmp_path / "d.tle")
    p.write_text(damage(p.read_text()))
    with pytest.raises(ElementsError) as exc:
        read_tle(p)
    assert needle in _one_line(exc) and str(p) in str(exc.value)


@pytest.mark.parametrize("fmt,where", [("kvn", ":6"), ("json", ": JSON object 2"), ("xml", ": XML segment 2"),
                                       ("csv", ":3")])
def test_omm_missing_a_field(tmp_path, fmt, where):
    sets = [dict(o) for o in OMM]
    del sets[1]["MEAN_MOTION"]
    if fmt == "csv":
        sets[1]["MEAN_MOTION"] = ""
    p = write_omm(tmp_path / f"m.{fmt}", fmt, sets)
    if fmt == "kvn":  # the second OMM starts at its CCSDS_OMM_VERS line
        where = f":{p.read_text().splitlines().index('CCSDS_OMM_VERS = 2.0', 1) + 1}"
    with pytest.raises(ElementsError) as exc:
        read_omm(p)
    msg = _one_line(exc)
    assert msg.startswith(f"{p}{where}: OMM without MEAN_MOTION"), msg


def test_omm_xml_with_a_default_namespace(tmp_path):
    p = write_omm(tmp_path / "ns.xml", "xml")
    p.write_text(p.read_text().replace("<ndm>", '<ndm xmlns="urn:ccsds:schema:ndmxml" '
                                       'xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance">'))
    assert [e.norad for e in read_omm(p)] == [40697, 42063, 60989]


def test_not_an_omm_and_bad_values(tmp_path):
    p = tmp_path / "x.txt"
    p.write_text("hello\n")
    with pytest.raises(ElementsError, match="not an OMM file"):
        read_omm(p)
    sets = [dict(OMM[0], ECCENTRICITY="1.5")]
    with pytest.raises(ElementsError, match="ECCENTRICITY 1.5 outside"):
        read_omm(write_omm(tmp_path / "e.json", "json", sets))
    sets = [dict(OMM[0], EPOCH="yesterday")]
    with pytest.raises(ElementsError, match="EPOCH 'yesterday'"):
        read_omm(write_omm(tmp_path / "e.kvn", "kvn", sets))


def test_validity_window():
    import datetime as dt

    sets = read_omm_list()
    newest = max(e.epoch for e in sets)
    oldest = min(e.epoch for e in sets)
    assert validity_error(sets, newest, newest + dt.timedelta(hours=6)) is None
    early = newest - dt.timedelta(days=VALIDITY_DAYS, seconds=1)
    assert "outside the element sets' validity" in validity_error(sets, early, newest)
    late = oldest + dt.timedelta(days=VALIDITY_DAYS, seconds=1)
    assert "outside" in validity_error(sets, newest, late)


def read_omm_list():
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        return read_omm(write_omm(Path(d) / "s.json", "json"))


@pytest.mark.parametrize("flag,fmt", [("--tle", "tle"), ("--omm", "kvn")])
def test_cli_bad_inputs_are_one_line_exit_2(tmp_path, flag, fmt):
    if fmt == "tle":
        p = write_tle(tmp_path / "bad.tle")
        p.write_text(p.read_text().replace("98.5698", "98.5699"))
        needle = f"{p}:6: TLE line 2 checksum"
    else:
        sets = [dict(o) for o in OMM]
        del sets[0]["BSTAR"]
        p = write_omm(tmp_path / "bad.kvn", "kvn", sets)
        needle = f"{p}:1: OMM without BSTAR"
    r = subprocess.run([sys.executable, "-m", "bringup.cli", "constellation", flag, str(p)],
                       capture_output=True, text=True, timeout=60, check=False)
    assert r.returncode == 2
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and needle in lines[0], r.stderr


def test_alpha5_catalogue_numbers(tmp_path):
    """Alpha-5 (a letter for the two leading digits, I and O skipped): A0001 = 100001, Z9999 = 339999,
    as sgp4's own reader reads them."""
    from sgp4.io import fix_checksum

    _n, l1, l2 = S2[0]
    for alpha, norad in (("A0001", 100001), ("J2345", 182345), ("Z9999", 339999)):
        a1, a2 = fix_checksum(l1[:2] + alpha + l1[7:68]), fix_checksum(l2[:2] + alpha + l2[7:68])
        p = tmp_path / f"{alpha}.tle"
        p.write_text(f"{a1}\n{a2}\n")
        (e,) = read_tle(p)
        assert e.norad == norad == Satrec.twoline2rv(a1, a2, WGS72).satnum and e.name == f"sat_n{norad}"
