"""MCAP bags: write in tmp_path, read back with BOTH `mcap` (+ mcap-ros2-support) and `rosbags`;
on the scenario's clock (log times and /clock = epoch + t_ns, UTC) with CRCs `mcap` validates."""

from __future__ import annotations

import shutil

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bringup.errors import UserError
from bringup.recording.bag import (
    CLOCK_TYPE,
    STRING,
    TYPESTORE,
    BagReader,
    BagWriter,
    clock_cdr,
    string_cdr,
    string_from_cdr,
)
from msgs_json.envelope import Envelope

S = 1_000_000_000


def _envelopes():
    return [
        Envelope(0, "orbit_clock", 0, "/orbit/contacts", '{"a": 1}'),
        Envelope(2 * S, "sat_11", 0, "/sat_11/observations", '{"gp": 3, "note": "héllo"}'),
        Envelope(2 * S, "sat_11", 1, "/sat_11/dtn/out", b"\x9f\x89\x07\x00bundle\xff"),
        Envelope(5 * S + 7, "sat_12", 0, "/sat_11/dtn/in", b""),
        Envelope(9 * S, "sat_12", 1, "/sat_12/observations", "{}"),
    ]


EPOCH_NS = 946_727_968 * S  # 2000-01-01T11:59:28Z, the paper scenario's epoch


def _write(path, envs, epoch_ns=0, **kw):
    fix = TYPESTORE.types["sensor_msgs/msg/NavSatFix"]
    with BagWriter(path, custom={"scenario": "paper", "seed": "1"}, epoch_ns=epoch_ns, **kw) as bag:
        for t in (0, 3 * S, 6 * S, 9 * S):
            bag.write_clock(t)
        for e in envs:
            bag.write_envelope(e)
        raw = TYPESTORE.serialize_cdr(
            TYPESTORE.deserialize_cdr(TYPESTORE.serialize_cdr(_fix(fix), "sensor_msgs/msg/NavSatFix"),
                                      "sensor_msgs/msg/NavSatFix"), "sensor_msgs/msg/NavSatFix")
        bag.write_raw("/sat_11/fix", "sensor_msgs/msg/NavSatFix", bytes(raw), 4 * S)
    return bag


def _fix(fix):
    import numpy as np

    T = TYPESTORE.types
    return fix(header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=4, nanosec=0), frame_id="earth"),
               status=T["sensor_msgs/msg/NavSatStatus"](status=0, service=0), latitude=12.5, longitude=-45.0,
               altitude=710000.0, position_covariance=np.zeros(9), position_covariance_type=0)


@pytest.mark.parametrize("epoch_ns", [0, EPOCH_NS])
def test_round_trip_with_rosbags(tmp_path, epoch_ns):
    envs = _envelopes()
    bag = _write(tmp_path / "bag", envs, epoch_ns)
    assert bag.counts["/clock"] == 4 and bag.counts["/sat_11/dtn/out"] == 1
    with BagReader(tmp_path / "bag") as r:
        assert r.epoch_ns == epoch_ns
        assert list(r.envelopes()) == envs  # exact, bytes and text, in log-time order
        assert r.start_ns == 0 and r.end_ns == 9 * S and r.count == 10  # t_ns: the epoch taken off
        stats = {t.topic: (t.msgtype, t.count) for t in r.topics()}
        assert stats["/clock"] == (CLOCK_TYPE, 4) and stats["/sat_11/observations"] == (STRING, 1)
        times = [m.log_time_ns for m in r.messages()]
        assert times == sorted(times)
        typed = {topic: msg for topic, _, msg in r.typed(["/clock", "/sat_11/fix"])}
        assert typed["/sat_11/fix"].latitude == 12.5
        assert (typed["/clock"].clock.sec, typed["/clock"].clock.nanosec) == (epoch_ns // S + 9, 0)  # UTC
    # the metadata.yaml a rosbag2 user expects
    meta = (tmp_path / "bag" / "metadata.yaml").read_text()
    for key in ("storage_identifier: mcap", "version: 9", "offered_qos_profiles", "scenario: paper"):
        assert key in meta
    assert ("epoch_utc: '2000-01-01T11:59:28Z'" in meta or "epoch_utc: 2000-01-01T11:59:28Z" in meta) == bool(epoch_ns)


@pytest.mark.parametrize("epoch_ns", [0, EPOCH_NS])
def test_round_trip_with_mcap_reader(tmp_path, epoch_ns):
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    envs = _envelopes()
    _write(tmp_path / "bag", envs, epoch_ns)
    path = next((tmp_path / "bag").glob("*.mcap"))
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()], validate_crcs=True)
        header = reader.get_header()
        summary = reader.get_summary()
        assert header.profile == "ros2"
        assert {ch.message_encoding for ch in summary.channels.values()} == {"cdr"}
        assert {s.encoding for s in summary.schemas.values()} == {"ros2msg"}
        assert all("offered_qos_profiles" in ch.metadata for ch in summary.channels.values())
        assert {ci.compression for ci in summary.chunk_indexes} == {"zstd"}
        assert summary.statistics.message_start_time == epoch_ns  # where a viewer's timeline starts
        assert summary.statistics.message_end_time == epoch_ns + 9 * S
        got = [(ch.topic, m.log_time, m.publish_time, dec)
               for _, ch, m, dec in reader.iter_decoded_messages(log_time_order=True)]
        (meta,) = [m for m in reader.iter_metadata() if m.name == "rosbag2"]
        assert (f"epoch_ns: '{epoch_ns}'" in meta.metadata["serialized_metadata"]) == bool(epoch_ns)
    from msgs_json.wire import decode_envelope

    assert all(pt == lt for _, lt, pt, _ in got)
    strings = [(t, lt, decode_envelope(d.data, t)) for t, lt, _, d in got if t not in ("/clock", "/sat_11/fix")]
    assert [e for _, _, e in strings] == envs
    assert all(lt == epoch_ns + e.t_ns for _, lt, e in strings)  # log time: the UTC instant
    clocks = [(d.clock.sec, d.clock.nanosec) for t, _, _, d in got if t == "/clock"]
    assert clocks == [(epoch_ns // S + k, 0) for k in (0, 3, 6, 9)]
    assert [d.altitude for t, _, _, d in got if t == "/sat_11/fix"] == [710000.0]


def test_crcs_are_written_and_validated(tmp_path):
    """Every chunk's uncompressed CRC, the data section's and the summary's are written (rosbags
    writes 0, "not computed"); mcap validates the first two, and a flipped byte is caught."""
    import struct
    import zlib

    from mcap.reader import make_reader
    from mcap.records import Chunk, DataEnd, Footer
    from mcap.stream_reader import CRCValidationError, StreamReader

    for compress in (True, False):
        d = tmp_path / f"bag{int(compress)}"
        _write(d, _envelopes() * 40, EPOCH_NS, compress=compress)
        path = next(d.glob("*.mcap"))
        records = list(StreamReader(str(path), validate_crcs=True).records)  # chunk + data section CRCs
        chunks = [r for r in StreamReader(str(path), emit_chunks=True).records if isinstance(r, Chunk)]
        (data_end,) = [r for r in records if isinstance(r, DataEnd)]
        (footer,) = [r for r in records if isinstance(r, Footer)]
        assert chunks and all(c.uncompressed_crc != 0 for c in chunks) and data_end.data_section_crc != 0
        raw = path.read_bytes()
        assert footer.summary_crc == zlib.crc32(raw[footer.summary_start:len(raw) - 8 - 4])
        with open(path, "rb") as f:
            assert sum(1 for _ in make_reader(f, validate_crcs=True).iter_messages()) == 205
    # a flipped byte in a message of the uncompressed bag: the chunk CRC no longer matches
    raw = bytearray(path.read_bytes())
    i = raw.index(b"orbit_clock")  # an envelope source: message data only
    raw[i] ^= 0x20
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(bytes(raw))
    with open(bad, "rb") as f, pytest.raises(CRCValidationError, match="in Chunk"):
        list(make_reader(f, validate_crcs=True).iter_messages())
    assert struct.unpack_from("<I", raw, len(raw) - 12)[0] == footer.summary_crc


@settings(max_examples=100, deadline=None)
@given(st.text(max_size=300))
def test_string_cdr_matches_rosbags_serializer(text):
    ref = bytes(TYPESTORE.serialize_cdr(TYPESTORE.types[STRING](data=text), STRING))
    assert string_cdr(text) == ref
    assert string_from_cdr(ref) == text


def test_clock_cdr_matches_rosbags_serializer():
    T = TYPESTORE.types
    msg = T[CLOCK_TYPE](clock=T["builtin_interfaces/msg/Time"](sec=21599, nanosec=999_999_999))
    assert clock_cdr(21599 * S + 999_999_999) == bytes(TYPESTORE.serialize_cdr(msg, CLOCK_TYPE))


def test_bag_closed_on_exception_stays_readable(tmp_path):
    with pytest.raises(KeyboardInterrupt), BagWriter(tmp_path / "bag") as bag:
        bag.write_envelope(_envelopes()[1])
        raise KeyboardInterrupt
    assert len(list(BagReader(tmp_path / "bag").envelopes())) == 1


def test_writer_refuses_existing_path_and_bad_input(tmp_path):
    (tmp_path / "bag").mkdir()
    with pytest.raises(UserError, match="already exists"):
        BagWriter(tmp_path / "bag")
    with BagWriter(tmp_path / "b2") as bag:
        with pytest.raises(ValueError, match="unknown message type"):
            bag.write_raw("/x", "nope_msgs/msg/Nope", b"", 0)
        with pytest.raises(ValueError, match="log time"):
            bag.write_clock(-1)


def _one_line_user_error(path, match):
    with pytest.raises(UserError, match=match) as ei, BagReader(path) as r:
        list(r.messages())
    assert "\n" not in str(ei.value)


def test_missing_truncated_or_not_a_bag(tmp_path):
    _one_line_user_error(tmp_path / "nowhere", "not found")
    (tmp_path / "empty").mkdir()
    _one_line_user_error(tmp_path / "empty", "no metadata.yaml")
    junk = tmp_path / "junk"
    junk.mkdir()
    (junk / "metadata.yaml").write_text("{{{ not yaml")
    _one_line_user_error(junk, "metadata.yaml is not YAML")
    _write(tmp_path / "bag", _envelopes())
    # not an mcap at all (a cut one is read as far as it goes: tests/unit/test_bag_recovery.py)
    shutil.copytree(tmp_path / "bag", tmp_path / "garbage")
    next((tmp_path / "garbage").glob("*.mcap")).write_bytes(b"hello world" * 100)
    _one_line_user_error(tmp_path / "garbage", "bag .*garbage.*not an MCAP file")


def test_mcap_file_path_is_accepted(tmp_path):
    _write(tmp_path / "bag", _envelopes())
    assert BagReader(next((tmp_path / "bag").glob("*.mcap"))).count == 10


def test_bag_info_command(tmp_path, capsys):
    import json

    from bringup.cli.main import main

    _write(tmp_path / "bag", _envelopes())
    assert main(["bag-info", str(tmp_path / "bag")]) == 0
    out = capsys.readouterr().out
    assert "messages:  10" in out and "duration:  9.000 s" in out
    assert any(line.split() == ["/clock", CLOCK_TYPE, "4"] for line in out.splitlines())
    assert main(["bag-info", "--json", str(tmp_path / "bag")]) == 0
    s = json.loads(capsys.readouterr().out)
    assert (s["messages"], s["start_ns"], s["end_ns"]) == (10, 0, 9 * S)
    assert {t["topic"]: t["count"] for t in s["topics"]}["/sat_11/dtn/in"] == 1
    assert main(["bag-info", str(tmp_path / "missing")]) == 2
    err = capsys.readouterr().err
    assert err.strip().count("\n") == 0 and "not found" in err
