"""TCPCLv4 (sat_node/dtn/cl/tcpcl4.py) against an independent implementation: the RFC 9174 author's
agent (github BrianSipos/dtn-demo-agent, package ``tcpcl``), driven by tests/interop/tcpcl4_peer.py,
in both roles, both directions on one session, with transfers larger than each side's segment MRU
(so both segment). Marker ``interop``; the peer comes from ``scripts/setup_tcpcl4_peer.sh``
(``$TCPCL4_PEER`` or ``~/.cache/constellation/tcpcl4-peer``: ``venv/bin/python`` and ``src/``).
"""

from __future__ import annotations

import asyncio
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from ion_node import free_port

from sat_node.dtn.bpv7 import Bundle, decode_bundle, encode_bundle, ipn
from sat_node.dtn.cl import tcpcl4 as t4

pytestmark = pytest.mark.interop
HERE = Path(__file__).resolve().parent
PEER = Path(os.environ.get("TCPCL4_PEER", Path.home() / ".cache" / "constellation" / "tcpcl4-peer"))
OUR_MRU, PEER_MRU = 5000, 3000  # segment MRUs: every bundle below is larger than both


def _bundles(tmp: Path, src: int, n: int) -> list[Path]:
    tmp.mkdir(parents=True, exist_ok=True)
    out = []
    for i in range(n):
        f = tmp / f"{src}_{i}.bpv7"
        f.write_bytes(encode_bundle(Bundle(dest=ipn(1 if src == 9 else 9, 1), src=ipn(src, 1), creation_ms=849_096_000_000,
                                           seq=i, lifetime_ms=3_600_000, payload=bytes([65 + i]) * (6000 + 15000 * i))))
        out.append(f)
    return out


@pytest.fixture(scope="module")
def bus():
    py, src = PEER / "venv" / "bin" / "python", PEER / "src" / "tcpcl"
    if not py.exists() or not src.is_dir():
        raise FileNotFoundError(f"the TCPCLv4 peer is not set up in {PEER}: scripts/setup_tcpcl4_peer.sh SRC {PEER}")
    p = subprocess.Popen(["dbus-daemon", "--session", "--nofork", "--print-address=1"], stdout=subprocess.PIPE,
                         text=True)
    addr = p.stdout.readline().strip()
    try:
        yield addr
    finally:
        p.terminate()
        p.wait(timeout=10)


def _peer(bus: str, role: list[str], send: list[Path], expect: int, out: Path) -> subprocess.Popen:
    return subprocess.Popen([str(PEER / "venv" / "bin" / "python"), str(HERE / "tcpcl4_peer.py"), "--bus", bus, *role,
                             "--segment-mru", str(PEER_MRU), "--tx-segment", "100000", "--send", *map(str, send),
                             "--expect", str(expect), "--out", str(out), "--timeout", "60"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=dict(os.environ, PYTHONPATH=str(PEER / "src")))


def _finish(p: subprocess.Popen) -> dict:
    out, err = p.communicate(timeout=90)
    assert p.returncode == 0, err[-2000:]
    return json.loads(out.strip().splitlines()[-1])


def test_we_connect_peer_listens(bus, tmp_path):
    ours, theirs = _bundles(tmp_path / "ours", 1, 4), _bundles(tmp_path / "theirs", 9, 3)
    port = free_port()
    peer = _peer(bus, ["--listen", "127.0.0.1", str(port)], theirs, len(ours), tmp_path / "peer_in")
    got: list[bytes] = []

    async def main():
        for _ in range(100):  # the peer's listener comes up
            try:
                s = await t4.connect("127.0.0.1", port, t4.Config(node_id="ipn:1.0", segment_mru=OUR_MRU),
                                     on_bundle=lambda b, s: got.append(b))
                break
            except t4.ClError:
                await asyncio.sleep(0.1)
        else:
            raise AssertionError("the peer never listened")
        assert s.peer_node_id == "ipn:9.0" and s.peer_segment_mru == PEER_MRU
        for f in ours:
            await s.send(f.read_bytes(), timeout_s=30)
        await asyncio.wait_for(s.wait_closed(), 60)  # the peer ends the session when it has all
        return s

    s = asyncio.run(main())
    report = _finish(peer)
    received = [f.read_bytes() for f in sorted((tmp_path / "peer_in").glob("*.bin"))]
    assert received == [f.read_bytes() for f in ours]  # byte-identical, segmented at <= 3000 bytes
    assert sorted(got) == sorted(f.read_bytes() for f in theirs) and report["sent"] == len(theirs)
    assert s.counters["segments_sent"] == sum(-(-f.stat().st_size // PEER_MRU) for f in ours)
    assert s.term_received == t4.TermReason.UNKNOWN and s.error is None
    assert all(decode_bundle(b).src == ipn(9, 1) for b in got)
    print(f"peer listening: {len(received)} bundles to it, {len(got)} from it, {report}", file=sys.stderr)


def test_peer_connects_we_listen(bus, tmp_path):
    ours, theirs = _bundles(tmp_path / "ours", 1, 2), _bundles(tmp_path / "theirs", 9, 3)
    got: list[bytes] = []

    async def main():
        sessions = []
        lst = await t4.serve("127.0.0.1", 0, t4.Config(node_id="ipn:1.0", segment_mru=OUR_MRU),
                             on_bundle=lambda b, s: got.append(b), on_session=sessions.append)
        peer = _peer(bus, ["--connect", "127.0.0.1", str(lst.port)], theirs, len(ours), tmp_path / "peer_in")
        for _ in range(300):
            if sessions:
                break
            await asyncio.sleep(0.1)
        s = sessions[0]
        for f in ours:
            await s.send(f.read_bytes(), timeout_s=30)
        await asyncio.wait_for(s.wait_closed(), 60)
        await lst.close()
        return s, peer

    s, peer = asyncio.run(main())
    report = _finish(peer)
    received = [f.read_bytes() for f in sorted((tmp_path / "peer_in").glob("*.bin"))]
    assert received == [f.read_bytes() for f in ours]
    assert got == [f.read_bytes() for f in theirs] and report["sent"] == len(theirs)
    assert s.peer_node_id == "ipn:9.0" and s.peer_segment_mru == PEER_MRU and s.error is None
    assert s.counters["segments_received"] >= sum(-(-f.stat().st_size // OUR_MRU) for f in theirs)
    print(f"peer connecting: {len(received)} bundles to it, {len(got)} from it, {report}", file=sys.stderr)
