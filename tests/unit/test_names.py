"""Satellite names beyond 9 x 9 (msgs_json/names.py): order, node numbers, limits, and the same
names through every place they travel - topics, message schemas, contact plan files (CSV, ION, HDTN
JSON), BPv7 EIDs, bags and the report of a whole run.

Oracle: the names are built from (plane, slot); everything read back must give the same (plane,
slot), and sorting by name must be sorting by (plane, slot).
"""

from __future__ import annotations

import io
import json
from datetime import UTC, datetime

import msgspec
import pytest

from bringup.cli.main import main
from bringup.recording.bag import BagReader
from bringup.scenario.config import ScenarioError, load_scenario
from msgs_json import codec, topics
from msgs_json import schemas as S
from msgs_json.names import (
    MAX_SATS,
    MAX_STATIONS,
    STATION_NODE_BASE,
    is_sat_name,
    sat_from_number,
    sat_name,
    sat_names,
    sat_number,
    sat_plane_slot,
)
from orbit_clock.contact_plan import Contact, ContactPlan, canonical_node, node_name, node_number
from orbit_clock.contact_plan_io import parse_contact_plan, write_contact_plan
from orbit_clock.walker import walker_elements
from sat_node.dtn.bpv7 import Bundle, decode_bundle, encode_bundle, ipn
from sat_node.dtn.routing_blocks import next_hops_of, peek_next_hops, recipients_of, set_routing

SHAPES = [(3, 8), (9, 9), (1, 1), (10, 1), (1, 10), (3, 32), (10, 24), (12, 40), (40, 25), (1, 1000), (1000, 1)]
EPOCH = datetime(2000, 1, 1, 11, 59, 28, tzinfo=UTC)


def test_short_form_up_to_nine_by_nine_long_form_beyond():
    assert sat_names(3, 8)[:3] == ["sat_11", "sat_12", "sat_13"] and sat_names(3, 8)[-1] == "sat_38"
    assert all(len(n) == 6 for n in sat_names(9, 9))
    assert sat_names(10, 1)[9] == "sat_0010_0001"
    assert sat_names(1, 10)[9] == "sat_0001_0010"
    assert sat_name(12, 20, 12, 20) == "sat_0012_0020" and sat_number("sat_0012_0020") == 120020
    assert sat_number("sat_38") == 38


@pytest.mark.parametrize("planes,per_plane", SHAPES)
def test_order_numbers_and_round_trips(planes, per_plane):
    names = sat_names(planes, per_plane)
    ps = [(p, s) for p in range(1, planes + 1) for s in range(1, per_plane + 1)]
    assert names == sorted(names) and len(set(names)) == len(names)
    assert [sat_plane_slot(n) for n in names] == ps
    numbers = [sat_number(n) for n in names]
    assert numbers == sorted(numbers) and len(set(numbers)) == len(numbers)
    assert all(sat_from_number(k) == n for k, n in zip(numbers, names, strict=True))
    assert all(node_name(node_number(n)) == n and is_sat_name(n) for n in names)
    assert all(topics.sat_of_topic(topics.dtn_out_topic(n)) == n for n in names)
    # the same names from the Walker generator, whose planes and slots say the same
    els = walker_elements(pattern="delta", total_sats=planes * per_plane, planes=planes, phasing_f=0,
                          altitude_km=710.0, inclination_deg=53.0, raan0_deg=0.0, epoch=EPOCH)
    assert [e.name for e in els] == names and [(e.plane, e.slot) for e in els] == ps


def test_node_number_ranges_never_meet():
    short = {sat_number(n) for n in sat_names(9, 9)}
    stations = set(range(STATION_NODE_BASE, STATION_NODE_BASE + MAX_STATIONS))
    long_lo = min(sat_number(n) for n in sat_names(1000, 1) + sat_names(1, 1000))
    assert max(short) < min(stations) and max(stations) < long_lo
    gs = [f"gs_{k}" for k in range(MAX_STATIONS)]
    assert node_name(STATION_NODE_BASE + MAX_STATIONS - 1, gs) == gs[-1]
    for bad in (0, 10, 20, 100, 10000, 20000, 10**8, -11, "11", 11.0):
        assert sat_from_number(bad) is None
    for bad in ("sat_10", "sat_01", "sat_1", "sat_0000_0001", "sat_0001_0000", "sat_001_001", "sat_1_1",
                "Sat11", "sat_0001_00001", "", None):
        assert not is_sat_name(bad)
        with pytest.raises(ValueError):
            topics.schedule_topic(bad)
    assert canonical_node("Sat38") == "sat_38" and canonical_node("s11") == "sat_11"
    assert canonical_node("sat_0012_0020") == "sat_0012_0020"


def test_message_schemas_take_both_forms():
    for sat in ("sat_11", "sat_0012_0020"):
        msg = S.Observation(sat=sat, gp=3, t_ns=5, assumed_value=1.0, recorded_value=2.0, schedule_version=1)
        assert codec.decode(topics.observations_topic(sat), codec.encode(msg)).sat == sat
        ev = S.BundleForwarded(sat=sat, t_ns=1, bundle_id="b", src=sat, dst="sat_0001_0002", priority=1,
                               creation_ns=0, next_hop="gs_troll")
        assert codec.decode(topics.dtn_events_topic(sat), codec.encode(ev)).src == sat
    for bad in ("sat_10", "sat_0000_0003", "sat_001_002"):
        with pytest.raises(msgspec.ValidationError):
            msgspec.json.decode(msgspec.json.encode({"sat": bad, "gp": 1, "t_ns": 1, "assumed_value": 1.0,
                                                     "recorded_value": 1.0, "schedule_version": 1}),
                                type=S.Observation)


@pytest.mark.parametrize("fmt", ["csv", "ion", "hdtn-json"])
def test_contact_plan_files_carry_the_names(fmt):
    names = sat_names(12, 40)
    gs = ["gs_svalbard", "gs_troll"]
    pairs = [(names[0], names[1]), (names[-1], names[0]), (names[479], gs[1]), (gs[0], names[40])]
    plan = ContactPlan([Contact(float(10 * k), float(10 * k + 100), a, b, 1000.0, 0.02)
                        for k, (a, b) in enumerate(pairs)])
    s = io.StringIO()
    write_contact_plan(plan, fmt, s, ground_stations=gs, epoch_utc=EPOCH)
    back = parse_contact_plan(s.getvalue(), fmt, ground_stations=gs, epoch_utc=EPOCH)
    assert [(c.src, c.dst) for c in back] == [(c.src, c.dst) for c in plan]
    if fmt == "hdtn-json":
        rows = json.loads(s.getvalue())["contacts"]
        assert [(r["source"], r["dest"]) for r in rows][:2] == [(10001, 10002), (120040, 10001)]


def test_bundle_eids_and_routing_blocks_carry_node_numbers():
    src, dst, hop = "sat_0012_0040", "sat_0001_0001", "sat_0003_0007"
    b = Bundle(dest=ipn(node_number(dst), 1), src=ipn(node_number(src), 1), creation_ms=1000, seq=3,
               lifetime_ms=900_000, payload=b"x")
    set_routing(b, [(node_number(dst), 1, 900_000)], {node_number(hop): (node_number(dst),)})
    data = encode_bundle(b)
    back = decode_bundle(data)
    assert node_name(back.src[0]) == src and node_name(back.dest[0]) == dst
    assert [node_name(r[0]) for r in recipients_of(back)] == [dst]
    assert {node_name(k): [node_name(x) for x in v] for k, v in next_hops_of(back).items()} == {hop: [dst]}
    assert [node_name(n) for n in peek_next_hops(data)] == [hop]


def test_limits_are_one_line(capsys):
    sc = load_scenario("paper")
    assert sc.with_overrides(sats=MAX_SATS, planes=40).sat_names[-1] == "sat_0040_0025"
    for kw, key in (({"sats": MAX_SATS + 1}, "constellation.total_sats"), ({"sats": 0}, "constellation.total_sats"),
                    ({"sats": 100, "planes": 7}, "constellation.total_sats"),
                    ({"planes": 0}, "constellation.planes")):
        with pytest.raises(ScenarioError) as e:
            sc.with_overrides(**kw)
        assert key in str(e.value) and "\n" not in str(e.value)
    for argv in (["constellation", "--sats", str(MAX_SATS + 1)], ["constellation", "--sats", "96", "--planes", "5"]):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "constellation.total_sats" in err[0], err


def test_cli_lists_long_names(tmp_path):
    out = tmp_path / "c.json"
    assert main(["constellation", "--sats", "96", "--planes", "6", "--format", "json", "--out", str(out)]) == 0
    sats = json.loads(out.read_text())["satellites"]
    assert [s["name"] for s in sats] == sat_names(6, 16)


def test_a_whole_run_with_long_names(tmp_path):
    """20 satellites in 2 planes (long names), 40 min, local engine: the bag's topics, the messages'
    satellite fields, the bundles' EIDs, recipients and next hops and the report all name the same
    20 satellites."""
    out = tmp_path / "run"
    assert main(["run", "--engine", "local", "--sats", "20", "--planes", "2", "--hours", "0.67", "--no-plots",
                 "--no-progress", "--out", str(out)]) == 0
    names = set(sat_names(2, 10))
    rep = json.loads((out / "report.json").read_text())
    assert rep["n_sats"] == 20 and rep["dtn"]["bundles_delivered"] > 0
    with BagReader(out / "bag") as bag:
        per_sat = {topics.sat_of_topic(t.topic) for t in bag.topics()} - {None}
        assert per_sat == names
        seen_src, seen_dst = set(), set()
        for env in bag.envelopes():
            if topics.is_bytes_topic(env.topic):
                b = decode_bundle(env.data)
                seen_src.add(node_name(b.src[0]))
                seen_dst.update(node_name(r[0]) for r in recipients_of(b))
                seen_dst.update(node_name(n) for n in peek_next_hops(env.data))
            elif env.topic.endswith("/observations"):
                assert codec.decode(env.topic, env.data).sat == topics.sat_of_topic(env.topic)
    assert seen_src and seen_src <= names and seen_dst and seen_dst <= names


def test_catalogue_names_never_meet_walker_or_station_numbers():
    """sat_n<NORAD> (a TLE / OMM satellite): valid ROS name, node number 10^8 + NORAD, above every
    Walker number (sat_9999_9999 = 99999999) and the stations'; round trips through every reader."""
    from msgs_json.names import (
        CATALOGUE_NODE_BASE,
        MAX_NORAD,
        catalogue_sat_name,
        is_catalogue_name,
        sat_norad,
    )

    for norad in (1, 5, 40697, 99999, 339999, MAX_NORAD):
        name = catalogue_sat_name(norad)
        assert name == f"sat_n{norad}" and is_sat_name(name) and is_catalogue_name(name)
        assert sat_number(name) == CATALOGUE_NODE_BASE + norad and sat_from_number(sat_number(name)) == name
        assert sat_norad(name) == norad
        assert topics.dtn_in_topic(name) == f"/{name}/dtn/in"
        assert msgspec.convert(name, S.SatName) == name
        with pytest.raises(ValueError):
            sat_plane_slot(name)
    assert sat_number("sat_9999_9999") < CATALOGUE_NODE_BASE + 1
    assert STATION_NODE_BASE + MAX_STATIONS < 10001
    assert sat_from_number(CATALOGUE_NODE_BASE) is None  # NORAD 0 is no satellite
    for bad in ("sat_n0", "sat_n012", "sat_n1234567890", "sat_nx", "sat_N5"):
        assert not is_sat_name(bad), bad
    for bad in (0, -3, MAX_NORAD + 1, "5", 5.0):
        with pytest.raises(ValueError):
            catalogue_sat_name(bad)
    # contact plan files carry them as ipn numbers and names
    plan = ContactPlan([Contact(0.0, 10.0, "sat_n40697", "sat_11", 1000.0, 0.01),
                        Contact(0.0, 10.0, "sat_11", "sat_n40697", 1000.0, 0.01)])
    assert node_number("sat_n40697") == 100040697 and node_name(100040697) == "sat_n40697"
    for fmt in ("csv", "ion", "hdtn-json"):
        buf = io.StringIO()
        write_contact_plan(plan, fmt, buf, epoch_utc=EPOCH)
        back = parse_contact_plan(buf.getvalue(), fmt, epoch_utc=EPOCH)
        assert sorted((c.src, c.dst) for c in back.contacts) == sorted((c.src, c.dst) for c in plan.contacts), fmt
    # a bundle to and from one round-trips its EIDs
    b = Bundle(src=ipn(sat_number("sat_n40697"), 1), dest=ipn(sat_number("sat_11"), 1),
               creation_ms=1, seq=0, lifetime_ms=1000, payload=b"x")
    back = decode_bundle(encode_bundle(b))
    assert sat_from_number(back.src[0]) == "sat_n40697" and sat_from_number(back.dest[0]) == "sat_11"
