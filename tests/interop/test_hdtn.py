"""Bundles exchanged with HDTN (NASA's High-rate DTN, built from its source by scripts/build_hdtn.sh)
over TCPCLv4 (RFC 9174), in both roles, through ``constellation bundles send|listen --cl tcpcl4``
(bringup/cli/bundles.py, sat_node/dtn/cl/tcpcl4.py).

HDTN is configured only through its own files (tests/interop/hdtn_node.py writes them in HDTN's
documented format): ``hdtn-one-process`` with an HDTN config (a ``tcpcl_v4`` induct and outduct) and a
contact plan, and HDTN's ``bpgen-async`` / ``bpsink-async`` apps with an outducts / inducts config.
The oracles are HDTN's: its router forwards a bundle only if it decoded it, its egress hands it on
only once it was re-encoded, its bpsink counts the BPv7 bundles and payload bytes it accepted, its
bpgen counts the bundles it generated (their payloads begin with its 64-bit sequence number).

Every transfer is larger than the receiving side's segment MRU: HDTN's induct offers 3000 bytes, our
listener 5000, and our TCPCLv4 ends a session on a segment over its MRU (RFC 9174 5.4.1), so a bundle
received whole proves the sender segmented. Everything runs in a network namespace with loopback
only (hdtn_node.NetNs). Marker ``interop`` (deselected by default): ``pytest -m interop tests/interop``.
"""

from __future__ import annotations

import os
import re
import struct
import subprocess
import sys
import time
from pathlib import Path

import hdtn_node as hn
import pytest

from sat_node.dtn.bpv7 import Bundle, decode_bundle, encode_bundle, ipn

pytestmark = pytest.mark.interop
REPO = Path(__file__).resolve().parents[2]
N = 8
HDTN_MRU, OUR_MRU = 3000, 5000  # segment MRUs; every bundle below is larger than both
US_SRC, HDTN_NODE, US_DST = 1, 10, 2  # node numbers: our sender, HDTN, our listener
IN_PORT, OUT_PORT = 4556, 4558  # HDTN's usual ports: free in the test's own namespace


def _now_dtn_ms() -> int:
    return int((time.time() - 946_684_800) * 1000)  # RFC 9171 4.2.6: ms since 2000-01-01T00:00:00Z


def _our_bundles(tmp: Path, n: int = N) -> list[tuple[Path, Bundle]]:
    """n bundles ipn:1.1 -> ipn:2.1, unexpired, 6-58 kB random payloads that begin with a 64-bit
    little-endian sequence number 1..n (the header HDTN's bpsink reads), a hop-count block (0 of 16)."""
    out, t = [], _now_dtn_ms()
    tmp.mkdir(parents=True, exist_ok=True)
    for i in range(n):
        payload = struct.pack("<Q", i + 1) + os.urandom(6000 + 7400 * i)
        b = Bundle(dest=ipn(US_DST, 1), src=ipn(US_SRC, 1), creation_ms=t, seq=i, lifetime_ms=3_600_000,
                   payload=payload)
        b.hop_count = (16, 0)
        f = tmp / f"ours{i}.bpv7"
        f.write_bytes(encode_bundle(b))
        out.append((f, decode_bundle(f.read_bytes())))
    return out


def _cli(ns: hn.NetNs, *args: str) -> list[str]:
    return ns.argv(sys.executable, "-m", "bringup.cli", "bundles", *args)


def _env() -> dict:
    return dict(os.environ, PYTHONPATH=str(REPO))


def _listen(ns: hn.NetNs, out: Path, count: int, duration: float = 120) -> subprocess.Popen:
    p = subprocess.Popen(_cli(ns, "listen", "--cl", "tcpcl4", "--at", f"127.0.0.1:{OUT_PORT}", "--out", str(out),
                              "--count", str(count), "--duration", str(duration), "--node-id", f"ipn:{US_DST}.0",
                              "--segment", str(OUR_MRU)),
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=_env(), cwd=REPO)
    line = p.stdout.readline()
    assert line.startswith("listening on"), line + p.stderr.read()
    return p


def _send(ns: hn.NetNs, files: list[Path]) -> subprocess.CompletedProcess:
    return subprocess.run(_cli(ns, "send", "--cl", "tcpcl4", "--to", f"127.0.0.1:{IN_PORT}", "--node-id",
                               f"ipn:{US_SRC}.0", "--segment", str(OUR_MRU), *map(str, files)),
                          check=False, capture_output=True, text=True, env=_env(), cwd=REPO, timeout=120)


def _finish(p: subprocess.Popen) -> str:
    out, err = p.communicate(timeout=150)
    assert p.returncode == 0, out + err
    return out


@pytest.fixture
def ns():
    n = hn.NetNs()
    try:
        yield n
    finally:
        n.close()


def test_hdtn_forwards_our_bundles_to_us(ns, tmp_path):
    """Our active side -> HDTN's induct; HDTN's router and egress -> its outduct (active) -> our
    passive side: every bundle arrives once, payload byte-identical, primary block unchanged, hop
    count one more, HDTN named as previous node."""
    home = tmp_path / "hdtn"
    hn.hdtn_prefix("hdtn-one-process")  # a clear error first when it is not built
    cfg = hn.write_json(home / "hdtn.json", hn.hdtn_config(
        HDTN_NODE, [hn.tcpcl4_induct("from_us", IN_PORT, HDTN_MRU)],
        [hn.tcpcl4_outduct("to_us", US_DST, OUT_PORT)], home))
    plan = hn.write_json(home / "plan.json", hn.contact_plan([(HDTN_NODE, US_DST)]))
    ours = _our_bundles(tmp_path / "ours")
    lst = _listen(ns, tmp_path / "from_hdtn", N)
    hdtn = hn.HdtnProc(ns, home, "hdtn-one-process", f"--hdtn-config-file={cfg}", f"--contact-plan-file={plan}")
    try:
        ns.wait_listening(IN_PORT, hdtn.proc, hdtn.log_path)
        sent = _send(ns, [f for f, _ in ours])
        assert sent.returncode == 0, sent.stdout + sent.stderr
        assert f"{N} bundles sent and acknowledged" in sent.stdout
        out = _finish(lst)
    finally:
        hdtn.stop()
    got = [decode_bundle(p.read_bytes()) for p in sorted((tmp_path / "from_hdtn").glob("*.bpv7"))]
    assert len(got) == N, out + hdtn.log()[-3000:]
    got.sort(key=lambda b: b.seq)
    for (_, want), b in zip(ours, got, strict=True):
        assert b.payload == want.payload
        assert (b.src, b.dest, b.creation_ms, b.seq, b.lifetime_ms) == \
            (want.src, want.dest, want.creation_ms, want.seq, want.lifetime_ms)
    # RFC 9171 4.4.3 and 4.4.1: a forwarder adds one to the hop count and names itself as previous node
    hops = {b.hop_count for b in got}
    prev = {b.previous_node for b in got}
    assert hops == {(16, 1)} and prev == {ipn(HDTN_NODE, 0)}
    print(f"HDTN {hn.hdtn_version(hdtn.prefix)}: {N} bundles ({sum(len(b.payload) for _, b in ours)} B of payload) "
          f"forwarded ipn:1.1 -> ipn:10 -> ipn:2.1, payloads byte-identical; hop count {hops}, "
          f"previous node {prev}", file=sys.stderr)


def test_hdtn_bpgen_sends_to_our_listener(ns, tmp_path):
    """HDTN's bpgen-async (active side, its outduct) -> our passive side: every bundle it generated
    arrives, BPv7, its payload the size bpgen was told and its sequence numbers 0, 1, 2... in order."""
    home = tmp_path / "bpgen"
    hn.hdtn_prefix("bpgen-async")
    outducts = hn.write_json(home / "outducts.json", {"outductConfigName": "ours", "outductVector": [
        hn.tcpcl4_outduct("bpgen", US_DST, OUT_PORT, segment_mru=200000)]})
    size = 20000  # > our segment MRU
    lst = _listen(ns, tmp_path / "from_bpgen", 10_000, duration=40)
    gen = hn.HdtnProc(ns, home, "bpgen-async", "--use-bp-version-7", f"--bundle-size={size}", "--bundle-rate=5",
                   "--duration=4", f"--my-uri-eid=ipn:{HDTN_NODE}.1", f"--dest-uri-eid=ipn:{US_DST}.1",
                   f"--outducts-config-file={outducts}")
    try:
        gen.proc.wait(timeout=90)
    finally:
        gen.stop()
    lst.send_signal(2)
    out = _finish(lst)
    log = gen.log()
    m = re.search(r"bundle_count: (\d+)", log)
    assert m, log[-3000:]
    generated = int(m.group(1))
    got = [decode_bundle(p.read_bytes()) for p in sorted((tmp_path / "from_bpgen").glob("*.bpv7"))]
    assert generated >= 5 and len(got) == generated, out + log[-3000:]
    assert all(b.src == ipn(HDTN_NODE, 1) and b.dest == ipn(US_DST, 1) and len(b.payload) == size for b in got)
    assert [struct.unpack_from("<Q", b.payload)[0] for b in got] == list(range(generated))
    print(f"HDTN bpgen-async: {generated} bundles of {size} B payload generated, {len(got)} received by "
          "`bundles listen`, sequence numbers in order", file=sys.stderr)


def test_our_bundles_to_hdtn_bpsink(ns, tmp_path):
    """Our active side -> HDTN's bpsink-async (passive side, its induct with a 3000-byte segment MRU):
    bpsink counts every bundle as BPv7 and every payload byte."""
    home = tmp_path / "bpsink"
    inducts = hn.write_json(home / "inducts.json", {"inductConfigName": "ours", "inductVector": [
        hn.tcpcl4_induct("bpsink", IN_PORT, HDTN_MRU)]})
    ours = _our_bundles(tmp_path / "ours")
    sink = hn.HdtnProc(ns, home, "bpsink-async", f"--my-uri-eid=ipn:{US_DST}.1", f"--inducts-config-file={inducts}")
    try:
        ns.wait_listening(IN_PORT, sink.proc, sink.log_path)
        sent = _send(ns, [f for f, _ in ours])
        assert sent.returncode == 0, sent.stdout + sent.stderr + sink.log()[-3000:]
        assert f"{N} bundles sent and acknowledged" in sent.stdout
    finally:
        sink.stop()
    log = sink.log()
    totals = {k: int(v) for k, v in re.findall(r"(totalPayloadBytesRx|totalBundleBytesRx|m_totalBundlesVersion7Rx)"
                                                r": (\d+)", log)}
    assert totals == {"totalPayloadBytesRx": sum(len(b.payload) for _, b in ours),
                      "totalBundleBytesRx": sum(f.stat().st_size for f, _ in ours),
                      "m_totalBundlesVersion7Rx": N}, log[-3000:]
    print(f"HDTN bpsink-async: {totals}", file=sys.stderr)
