"""Bags cut, killed or lied about: the reader keeps every whole chunk and trusts the .mcap file.

Oracles:
* the ``mcap`` library (an independent reader) on the complete file gives, chunk by chunk, the
  messages each chunk holds (its records flattened in file order: a chunk's messages, then its
  message indexes) and the summary's chunk indexes give where each chunk ends; a copy cut at byte
  X must read back exactly the messages of the chunks that end at or before X, in order;
* a writer process SIGKILLed after N flushed chunks leaves at least those N chunks' messages;
* metadata.yaml edited (a topic renamed, counts x10) or taken from another bag: the warning names
  the difference, and topics, counts and the report are the .mcap's (equal to the untouched bag's).
"""

from __future__ import annotations

import json
import os
import random
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from bringup.cli.main import main
from bringup.errors import UserError
from bringup.recording.bag import BagReader, BagWriter
from msgs_json.envelope import Envelope

S = 1_000_000_000
EPOCH_NS = 946_727_968 * S


def _write(path: Path, steps: int = 400, span_ns: int | None = 60 * S) -> list[tuple[str, int, bytes]]:
    """A bag of ``steps`` 10-s steps (a /clock and three envelopes each); returns what was written."""
    wrote = []
    with BagWriter(path, epoch_ns=EPOCH_NS, chunk_span_ns=span_ns, custom={"scenario": "test"}) as bag:
        for k in range(steps):
            t = k * 10 * S
            bag.write_clock(t)
            envs = [Envelope(t, "sat_11", k, "/sat_11/observations", json.dumps({"k": k, "pad": "x" * 200})),
                    Envelope(t, "sat_12", k, "/sat_12/dtn/events", json.dumps({"k": k})),
                    Envelope(t, "router", k, "/dtn/medium", os.urandom(64))]
            bag.write_envelopes(envs)
    with BagReader(path) as r:
        return [(m.topic, m.log_time_ns, m.cdr) for m in r.messages()]


def _chunks_by_mcap(mcap: Path) -> list[tuple[int, int]]:
    """(chunk end offset, messages in it) per chunk, from the ``mcap`` library."""
    from mcap.reader import make_reader
    from mcap.records import Message, MessageIndex
    from mcap.stream_reader import StreamReader

    with open(mcap, "rb") as f:
        ends = [ci.chunk_start_offset + ci.chunk_length for ci in make_reader(f).get_summary().chunk_indexes]
    counts, n, prev_index = [], 0, False
    for rec in StreamReader(str(mcap)).records:
        if isinstance(rec, Message):
            if prev_index:
                counts.append(n)
                n, prev_index = 0, False
            n += 1
        elif isinstance(rec, MessageIndex):
            prev_index = True
    counts.append(n)
    assert len(counts) == len(ends)
    return list(zip(ends, counts, strict=True))


def _cut(src: Path, dst: Path, nbytes: int, keep_yaml: bool = False) -> Path:
    dst.mkdir()
    data = (src / f"{src.name}.mcap").read_bytes()
    (dst / f"{src.name}.mcap").write_bytes(data[:nbytes])
    if keep_yaml:
        shutil.copy(src / "metadata.yaml", dst / "metadata.yaml")
    return dst


def test_cut_anywhere_keeps_every_whole_chunk(tmp_path):
    full = _write(tmp_path / "bag")
    mcap = tmp_path / "bag" / "bag.mcap"
    chunks = _chunks_by_mcap(mcap)
    assert len(chunks) >= 30  # one chunk per minute of sim time (bag.py CHUNK_SPAN_NS)
    size = mcap.stat().st_size
    rng = random.Random(7)
    cuts = [end for end, _ in chunks] + [end - 1 for end, _ in chunks] + [rng.randrange(40, size) for _ in range(25)]
    for i, x in enumerate(sorted(set(cuts))):
        expect = sum(n for end, n in chunks if end <= x)
        with BagReader(_cut(tmp_path / "bag", tmp_path / f"cut{i}", x)) as r:
            got = [(m.topic, m.log_time_ns, m.cdr) for m in r.messages()]
            assert got == full[:expect], x
            assert r.count == expect and not r.complete and r.lost_data
            assert r.epoch_ns == EPOCH_NS  # from the leading metadata record
            assert "was not closed by its writer" in r.recovery and f"recovered {expect} messages" in r.recovery
            if expect:
                assert r.end_ns == full[expect - 1][1]


def test_only_the_footer_cut_reads_everything(tmp_path):
    full = _write(tmp_path / "bag")
    size = (tmp_path / "bag" / "bag.mcap").stat().st_size
    for i, cut in enumerate((8, 20, 500)):
        with BagReader(_cut(tmp_path / "bag", tmp_path / f"c{i}", size - cut)) as r:
            assert [(m.topic, m.log_time_ns, m.cdr) for m in r.messages()] == full
            assert not r.complete and not r.lost_data and "data section is whole" in r.recovery


def test_a_damaged_chunk_is_skipped_and_named(tmp_path):
    full = _write(tmp_path / "bag", span_ns=None)
    chunks = _chunks_by_mcap(tmp_path / "bag" / "bag.mcap")
    size = (tmp_path / "bag" / "bag.mcap").stat().st_size
    d = _cut(tmp_path / "bag", tmp_path / "bad", size - 8)
    raw = bytearray((d / "bag.mcap").read_bytes())
    raw[chunks[0][0] - 100] ^= 0xFF  # inside the first chunk's compressed records
    (d / "bag.mcap").write_bytes(bytes(raw))
    with BagReader(d) as r:
        got = [(m.topic, m.log_time_ns, m.cdr) for m in r.messages()]
        assert got == full[chunks[0][1]:]
        assert "damaged chunks skipped: chunk at byte" in r.recovery and r.lost_data


def test_header_only_empty_and_garbage(tmp_path):
    _write(tmp_path / "bag", steps=2)
    with BagReader(_cut(tmp_path / "bag", tmp_path / "head", 60)) as r:  # header + part of the epoch record
        assert r.count == 0 and list(r.messages()) == [] and not r.complete
    for name, data in (("empty", b""), ("junk", b"\x89MCAP0\r\n" + b"\xff" * 3)):
        d = tmp_path / name
        d.mkdir()
        (d / "bag.mcap").write_bytes(data)
        with pytest.raises(UserError, match="not an MCAP file|header") as ei:
            BagReader(d)
        assert "\n" not in str(ei.value)


_WRITER = """
import json, os, sys, time
from bringup.recording.bag import BagWriter
from msgs_json.envelope import Envelope
S = 10**9
with BagWriter(sys.argv[1], epoch_ns=946727968 * S) as bag:
    for k in range(10**6):
        t = k * 10 * S
        bag.write_clock(t)
        bag.write_envelope(Envelope(t, "sat_11", k, "/sat_11/observations", json.dumps({"k": k})))
        if k == 600:  # 100 min of sim time: 50 chunks of 2 min closed and flushed
            print("ready", flush=True)
            time.sleep(600)
"""


def test_a_writer_killed_mid_run_leaves_its_closed_chunks(tmp_path):
    bag = tmp_path / "bag"
    p = subprocess.Popen([sys.executable, "-c", _WRITER, str(bag)], stdout=subprocess.PIPE, text=True)
    try:
        assert p.stdout.readline().strip() == "ready"
        os.kill(p.pid, signal.SIGKILL)
    finally:
        p.wait(timeout=30)
    assert not (bag / "metadata.yaml").exists()  # the writer never closed
    with BagReader(bag) as r:
        envs = list(r.envelopes(["/sat_11/observations"]))
        assert r.epoch_ns == 946727968 * S and not r.complete
        # chunks close at the /clock 2 min after their first message: steps 0..587 are in closed chunks
        assert len(envs) >= 588 and [e.seq for e in envs] == list(range(len(envs)))
        assert r.warnings == []
    assert main(["bag-info", str(bag)]) == 0


# -- metadata.yaml against the .mcap --------------------------------------------------------------
@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("run") / "r"
    assert main(["run", "--engine", "local", "--sats", "6", "--hours", "0.5", "--no-plots", "--no-progress",
                 "--out", str(out)]) == 0
    return out


def _copy_bag(run_dir: Path, dst: Path) -> Path:
    shutil.copytree(run_dir / "bag", dst)
    return dst


def _report(capsys, bag: Path) -> tuple[dict, str]:
    assert main(["report", str(bag)]) == 0
    got = capsys.readouterr()
    return json.loads(got.out), got.err


def test_renamed_topic_in_metadata_yaml(tmp_path, capsys, run_dir):
    clean, err = _report(capsys, run_dir / "bag")
    # (the short run sees only some regions: that warning is the run's, not the bag's)
    assert not [ln for ln in err.splitlines() if "no satellite has region" not in ln]
    assert clean["observations"]["count"] > 20 and clean["partial"] is False
    bag = _copy_bag(run_dir, tmp_path / "bag")
    with BagReader(bag) as r:
        topic = next(t.topic for t in r.topics() if t.topic.endswith("/observations") and t.count)
    y = bag / "metadata.yaml"
    y.write_text(y.read_text().replace(topic, "/sat_99/renamed"))
    rep, err = _report(capsys, bag)
    assert rep["observations"] == clean["observations"] and rep["value"] == clean["value"]  # was 233 -> 185
    assert "metadata.yaml disagrees with bag.mcap" in err and "/sat_99/renamed" in err and topic in err
    assert rep["recording"]["warnings"] and rep["partial"] is False


def test_foreign_metadata_yaml(tmp_path, capsys, run_dir):
    clean, _ = _report(capsys, run_dir / "bag")
    other = tmp_path / "other"
    _write(other, steps=30)
    bag = _copy_bag(run_dir, tmp_path / "bag")
    shutil.copy(other / "metadata.yaml", bag / "metadata.yaml")
    rep, err = _report(capsys, bag)
    assert {k: rep[k] for k in ("observations", "value", "dtn")} == {k: clean[k] for k in ("observations", "value", "dtn")}
    assert "message_count" in err and "/dtn/medium" in err


def test_counts_times_ten_in_bag_info(tmp_path, capsys, run_dir):
    bag = _copy_bag(run_dir, tmp_path / "bag")
    assert main(["bag-info", "--json", str(run_dir / "bag")]) == 0
    clean = json.loads(capsys.readouterr().out)
    y = bag / "metadata.yaml"
    text = y.read_text()
    import re

    y.write_text(re.sub(r"message_count: (\d+)", lambda m: f"message_count: {int(m.group(1)) * 10}", text))
    assert main(["bag-info", "--json", str(bag)]) == 0
    got = capsys.readouterr()
    info = json.loads(got.out)
    assert info["messages"] == clean["messages"] and info["topics"] == clean["topics"]
    assert f"message_count {clean['messages'] * 10}" in got.err and "warning" in got.err
    (bag / "metadata.yaml").unlink()
    assert main(["bag-info", "--json", str(bag)]) == 0
    got = capsys.readouterr()
    assert json.loads(got.out)["topics"] == clean["topics"] and "no metadata.yaml" in got.err


def test_report_of_a_cut_bag_is_partial(tmp_path, capsys, run_dir):
    clean, _ = _report(capsys, run_dir / "bag")
    size = (run_dir / "bag" / "bag.mcap").stat().st_size
    bag = _cut(run_dir / "bag", tmp_path / "cut", size // 2)
    rep, err = _report(capsys, bag)
    assert rep["partial"] is True and 0 < rep["horizon_reached_s"] < rep["horizon_s"]
    assert rep["observations"]["count"] < clean["observations"]["count"]
    assert rep["recording"]["complete"] is False and "lost" in rep["recording"]["recovery"]
    assert "partial report" in err and "was not closed by its writer" in err
    assert main(["bag-info", str(bag)]) == 0
    assert "complete:  no" in capsys.readouterr().out
