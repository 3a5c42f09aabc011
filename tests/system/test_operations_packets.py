"""Housekeeping channels and their CCSDS space packets (sat_node/operations/packets.py,
`constellation ops packets`), decoded by an independent implementation of CCSDS 133.0-B-2 (ccsdspy).

A local run of the paper's scenario (12 satellites, 0.25 h) with ``operations.hk_period_s = 60`` and
one command (sat_33 to SAFE at 50 s, so a channel changes); its bag's Housekeeping messages are the
reference: the packets written beside the bag, decoded by ccsdspy from the dictionary's channel list
alone, give the same values per APID, with sequence counts 0, 1, 2... and the APIDs the rule names.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import msgspec
import numpy as np
import pytest

pytestmark = [pytest.mark.system]
STATIONS = [{"name": "svalbard", "lat_deg": 78.2298, "lon_deg": 15.4078, "alt_m": 500.0},
            {"name": "troll", "lat_deg": -72.0117, "lon_deg": 2.535, "alt_m": 1270.0}]


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> Path:
    from bringup.scenario.config import load_scenario
    from bringup.scenario.toml_text import to_toml

    base = tmp_path_factory.mktemp("hk")
    raw = msgspec.to_builtins(load_scenario("paper"))
    raw.pop("source_path", None)
    raw["operations"]["hk_period_s"] = 60.0
    raw["commands"] = [{"sat": "sat_33", "kind": "mode", "mode": "safe", "at_s": 50.0}]
    raw["ground"]["stations"] = STATIONS  # the commands' uplinks are timed for these stations
    (base / "hk.toml").write_text(to_toml(raw))
    out = base / "run"
    for cmd in (["run", "--engine", "local", "--scenario", str(base / "hk.toml"), "--sats", "12", "--hours", "0.25",
                 "--out", str(out), "--no-plots", "--no-progress"], ["ops", "packets", str(out / "bag")]):
        r = subprocess.run([sys.executable, "-m", "bringup.cli", *cmd], capture_output=True, text=True, timeout=600,
                           check=False)
        assert r.returncode == 0, r.stderr[-3000:]
    return out


def _hk(run: Path):
    from bringup.recording.bag import BagReader
    from msgs_json import codec

    with BagReader(run / "bag") as b:
        topics = [t.topic for t in b.topics() if t.topic.endswith("/ops/hk")]
        return [codec.decode(env.topic, env.data) for env in b.envelopes(topics)]


def test_packets_decode_with_ccsdspy_to_the_bag_values(run):
    import ccsdspy
    from ccsdspy.utils import split_by_apid

    from sat_node.operations.catalogue import dictionary

    chans = dictionary()["packets"]["housekeeping"]["channels"]  # the dictionary's list, nothing else
    pkt = ccsdspy.FixedLength([ccsdspy.PacketField(name=c["name"], data_type=c["type"], bit_length=c["bits"])
                               for c in chans])
    hk = _hk(run)
    sats = sorted({m.sat for m in hk})
    assert len(sats) == 12 and len(hk) == 12 * 16  # 0, 60, ..., 900 s
    streams = split_by_apid(str(run / "telemetry.ccsds"))
    assert sorted(streams) == [0x100 + i + 1 for i in range(12)]
    for i, sat in enumerate(sats):
        mine = sorted((m for m in hk if m.sat == sat), key=lambda m: m.t_ns)
        got = pkt.load(streams[0x100 + i + 1], include_primary_header=True)
        assert list(got["CCSDS_SEQUENCE_COUNT"]) == list(range(len(mine)))
        assert set(got["CCSDS_PACKET_TYPE"]) == {0} and set(got["CCSDS_SEQUENCE_FLAG"]) == {3}
        for c in chans:
            want = np.array([getattr(m, c["name"]) for m in mine])
            assert np.array_equal(got[c["name"]], want), (sat, c["name"])
    safe = [m for m in hk if m.sat == "sat_33" and m.t_ns >= 60 * 10**9]
    assert safe and {m.mode for m in safe} == {2} and safe[-1].commands_accepted == 1  # the channel moved

