"""CLI: constellation / access / contacts subcommands (bringup/cli)."""

from __future__ import annotations

import csv
import json

import pytest

from bringup.cli.main import main
from orbit_clock.contact_plan_io import read_contact_plan


def test_constellation_json_and_csv(tmp_path):
    out = tmp_path / "c.json"
    assert main(["constellation", "--scenario", "paper", "--format", "json", "--out", str(out)]) == 0
    doc = json.loads(out.read_text())
    sats = doc["satellites"]
    assert len(sats) == 24 and sats[0]["name"] == "sat_11" and sats[-1]["name"] == "sat_38"
    assert {s["raan_deg"] for s in sats} == {0.0, 60.0, 120.0}
    assert all(s["sma_km"] == 7088.137 and s["inc_deg"] == 98.5 for s in sats)
    assert sats[0]["epoch_utc"] == "2000-01-01T11:59:28.000Z"
    out2 = tmp_path / "c.csv"
    assert main(["constellation", "--format", "csv", "--sats", "6", "--out", str(out2)]) == 0
    rows = list(csv.DictReader(out2.open()))
    assert [r["name"] for r in rows] == ["sat_11", "sat_12", "sat_21", "sat_22", "sat_31", "sat_32"]


def test_access_csv_columns(tmp_path):
    out = tmp_path / "a.csv"
    assert main(["access", "--scenario", "paper", "--hours", "1", "--out", str(out)]) == 0
    rows = list(csv.DictReader(out.open()))
    assert list(rows[0]) == ["sat", "region", "gp", "lat_deg", "lon_deg", "start_s", "end_s", "min_off_nadir_deg"]
    assert rows and all(0 <= float(r["start_s"]) < float(r["end_s"]) <= 3600 for r in rows)
    assert all(float(r["min_off_nadir_deg"]) <= 55.0 for r in rows)


def test_contacts_formats_round_trip(tmp_path):
    names = ["gs_svalbard", "gs_mcmurdo"]
    counts = {}
    for fmt, suffix in (("csv", "csv"), ("ion", "rc"), ("hdtn-json", "json")):
        out = tmp_path / f"p.{suffix}"
        assert main(["contacts", "--hours", "2", "--format", fmt, "--out", str(out)]) == 0
        plan = read_contact_plan(out, fmt, ground_stations=names)
        counts[fmt] = len(plan)
        assert any(x.src.startswith("gs_") for x in plan) and any(x.src.startswith("sat_") for x in plan)
    assert len(set(counts.values())) == 1 and counts["csv"] > 100
    out = tmp_path / "isl.csv"
    assert main(["contacts", "--hours", "2", "--links", "isl", "--out", str(out)]) == 0
    assert not any(x.src.startswith("gs_") for x in read_contact_plan(out))


def test_bad_scenario_is_one_line(capsys):
    assert main(["contacts", "--scenario", "no_such_scenario"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no such file" in err[0]


def test_contacts_at_any_epoch_and_now(tmp_path, capsys):
    from datetime import UTC, datetime, timedelta

    from orbit_clock.contact_plan_io import read_contact_plan as read

    paper, later = tmp_path / "paper.rc", tmp_path / "later.rc"
    assert main(["contacts", "--hours", "1", "--format", "ion", "--out", str(paper)]) == 0
    assert main(["contacts", "--hours", "1", "--format", "ion", "--ion-times", "absolute",
                 "--epoch", "2026-11-27T12:00:00Z", "--out", str(later)]) == 0
    text = later.read_text()
    body = [ln for ln in text.splitlines() if not ln.startswith("#")]
    assert body[0] == "@ 2026/11/27-12:00:00" and body[1].startswith("a contact 2026/11/27-")
    assert not any(" +" in ln for ln in body)
    # the same orbits from a later start: the Walker pattern is defined at the epoch, so the ISL
    # windows are the same seconds after it (ION's reading of both files, each from its own '@');
    # the ground passes are not (the Earth turned differently under them)
    gs = ["gs_svalbard", "gs_troll"]
    a, b = ([(c.start_s, c.end_s, c.src, c.dst) for c in read(f, "ion", ground_stations=gs) if c.src[:3] == c.dst[:3]]
            for f in (paper, later))
    assert len(a) > 10 and a == b
    before = datetime.now(UTC).replace(microsecond=0)
    now = tmp_path / "now.rc"
    assert main(["contacts", "--hours", "1", "--format", "ion", "--epoch", "now", "--out", str(now)]) == 0
    stamp = next(ln for ln in now.read_text().splitlines() if ln.startswith("@ "))[2:]
    t = datetime.strptime(stamp, "%Y/%m/%d-%H:%M:%S").replace(tzinfo=UTC)
    assert before <= t <= datetime.now(UTC) + timedelta(seconds=1)
    for bad in ("yesterday", "2026-11-27T12:00:00", "1999-12-31T23:59:59Z", "2026-11-27T12:00:00+01:00Z"):
        with pytest.raises(SystemExit):
            main(["contacts", "--epoch", bad])
        assert "--epoch" in capsys.readouterr().err
    assert main(["contacts", "--ion-times", "absolute"]) == 2
    assert "--ion-times applies to --format ion only" in capsys.readouterr().err
