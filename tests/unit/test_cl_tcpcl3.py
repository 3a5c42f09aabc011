"""TCPCLv3 (RFC 7242) conformance: sat_node/dtn/cl/tcpcl3.py.

Oracles: the RFC's figures and RFC 6256's SDNV examples written out byte by byte; pyd3tn's TCPCLv3
client (the uD3TN project's implementation, the `interop` extra) as an independent peer in both
directions; a raw socket playing a misbehaving peer. All on 127.0.0.1.
"""

from __future__ import annotations

import asyncio

import pytest
from pyd3tn.tcpcl import TCPCLConnection

from sat_node.dtn.cl import ClError, SessionTerminated, TransferRefused
from sat_node.dtn.cl import tcpcl3 as t3

HOST = "127.0.0.1"


def run(coro, timeout=20):
    return asyncio.run(asyncio.wait_for(coro, timeout))


def test_sdnv_rfc6256_examples():
    # RFC 6256 2.1: 0xABC -> 0x95 0x3C; 0x1234 -> 0xA4 0x34; 0x4234 -> 0x81 0x84 0x34; 0x7F -> 0x7F
    assert t3.sdnv(0xABC) == b"\x95\x3c" and t3.sdnv(0x1234) == b"\xa4\x34"
    assert t3.sdnv(0x4234) == b"\x81\x84\x34" and t3.sdnv(0x7F) == b"\x7f" and t3.sdnv(0) == b"\x00"


def test_message_bytes():
    # 4.1 figure 2: magic, version 3, flags, keepalive U16, EID length SDNV, EID
    assert t3.contact_header(0x01, 15, "ipn:5.0") == b"dtn!\x03\x01\x00\x0f\x07ipn:5.0"
    # 5.2 figure 5: DATA_SEGMENT 0x1 with S|E flags, length SDNV (200 -> 0x81 0x48), data
    assert t3.data_segment(0x03, b"a" * 200) == b"\x13\x81\x48" + b"a" * 200
    assert t3.ack_segment(300) == b"\x20\x82\x2c"  # 5.3
    assert t3.refuse_bundle(t3.RefuseReason.COMPLETED) == b"\x31"  # 5.4: reason in the low nibble
    assert t3.keepalive() == b"\x40"  # 5.5
    assert t3.shutdown() == b"\x50"  # 5.6: no reason, no delay
    assert t3.shutdown(t3.ShutdownReason.VERSION_MISMATCH, 0) == b"\x53\x01\x00"
    assert t3.length_msg(129) == b"\x60\x81\x01"  # 5.7


def test_both_roles_segmented_with_acks():
    bundles = [b"q" * 5, bytes(range(256)) * 30, b"w" * 999]

    async def main():
        got, got_back, sessions = [], [], []
        lst = await t3.serve(HOST, 0, t3.Config(eid="ipn:2.0", keepalive_s=10, tx_segment=500),
                             on_bundle=lambda b, s: got.append(b), on_session=sessions.append)
        s = await t3.connect(HOST, lst.port, t3.Config(eid="ipn:1.0", keepalive_s=4, tx_segment=1000,
                                                       want_lengths=True),
                             on_bundle=lambda b, s: got_back.append(b))
        assert (s.peer_eid, s.keepalive_s, s.acks, s.refusals) == ("ipn:2.0", 4, True, True)
        for b in bundles:
            await s.send(b)
        for b in bundles:
            await sessions[0].send(b)
        await s.close()
        await sessions[0].wait_closed()
        await lst.close()
        return got, got_back, s, sessions[0]

    got, got_back, s, back = run(main())
    assert got == bundles and got_back == bundles
    assert s.counters["segments_sent"] == 1 + 8 + 1 and back.counters["segments_sent"] == 1 + 16 + 2
    assert back.send_lengths and back.shutdown_received and s.error is None and back.error is None


def test_refusal_when_negotiated():
    async def main():
        got = []
        lst = await t3.serve(HOST, 0, t3.Config(accept=lambda total: t3.RefuseReason.NO_RESOURCES),
                             on_bundle=lambda b, s: got.append(b))
        s = await t3.connect(HOST, lst.port, t3.Config(tx_segment=10))
        with pytest.raises(TransferRefused) as exc:
            await s.send(b"r" * 100)
        await s.close()
        await lst.close()
        return got, exc.value.reason

    got, reason = run(main())
    assert got == [] and reason == t3.RefuseReason.NO_RESOURCES


def test_pyd3tn_client_sends_and_receives():
    """uD3TN's TCPCLv3 client (no acknowledgments, one segment per bundle) against the listener."""
    bundles = [b"\x9f" + bytes([i]) * (100 + i) for i in range(5)]

    def client(port):
        with TCPCLConnection("ipn:7.0", HOST, port, timeout=5) as conn:
            for b in bundles:
                conn.send_bundle(b)
            return [conn.recv_bundle() for _ in bundles]

    async def main():
        got, sessions = [], []

        def on_bundle(b, s):
            got.append(b)
            asyncio.get_running_loop().create_task(s.send(b))  # echo each one back

        lst = await t3.serve(HOST, 0, t3.Config(eid="ipn:2.0"), on_bundle=on_bundle, on_session=sessions.append)
        echoed = await asyncio.to_thread(client, lst.port)
        await asyncio.sleep(0.1)
        await lst.close()
        return got, echoed, sessions[0]

    got, echoed, s = run(main())
    assert got == bundles and echoed == bundles
    assert s.peer_eid == "ipn:7.0" and not s.acks and s.shutdown_received


def test_version_4_header_gets_shutdown_version_mismatch():
    async def main():
        lst = await t3.serve(HOST, 0, t3.Config(eid="ipn:2.0", keepalive_s=15))
        r, w = await asyncio.open_connection(HOST, lst.port)
        w.write(b"dtn!\x04\x00\x00\x00")
        reply = await r.read()
        await lst.close()
        return reply, lst

    reply, lst = run(main())
    assert reply == t3.contact_header(0x05, 15, "ipn:2.0") + b"\x52\x01"
    assert "version 4" in lst.sessions[0].error


def test_unknown_type_oversize_and_truncated():
    async def raw_peer(port, tail):
        r, w = await asyncio.open_connection(HOST, port)
        w.write(t3.contact_header(0x01, 0, "ipn:9.0"))
        await r.readexactly(len(t3.contact_header(0x05, 15, "ipn:2.0")))
        w.write(t3.data_segment(0x03, b"kept"))
        ack = await r.readexactly(2)
        w.write(tail)
        if tail.startswith(b"\x12"):  # a truncated segment: cut the connection
            w.close()
            await asyncio.sleep(0.2)
            return ack, b""
        return ack, await r.read()

    async def main():
        out = []
        for tail in (b"\x70", b"\x13" + t3.sdnv(1 << 40), b"\x12\x64" + b"only 10 b."):
            got = []
            lst = await t3.serve(HOST, 0, t3.Config(eid="ipn:2.0", max_bundle=4096),
                                 on_bundle=lambda b, s, got=got: got.append(b))
            ack, reply = await raw_peer(lst.port, tail)
            await lst.close()
            out.append((ack, reply, got, lst.sessions[0]))
        return out

    (a1, r1, g1, s1), (a2, r2, g2, s2), (a3, _, g3, s3) = run(main())
    assert a1 == a2 == a3 == b"\x20\x04"  # the first bundle was acknowledged in full ...
    assert g1 == g2 == g3 == [b"kept"]  # ... and kept whatever came after it
    assert r1 == b"\x50" and "unknown message type 0x7" in s1.error
    assert r2 == b"\x50" and s2.counters["oversize_segments"] == 1
    assert "truncated" in s3.error and s3.counters["partial_bundles_discarded"] == 1


def test_send_after_peer_shutdown_and_bad_magic():
    async def main():
        lst = await t3.serve(HOST, 0, t3.Config())
        s = await t3.connect(HOST, lst.port, t3.Config())
        await lst.sessions[0].close()
        await s.wait_closed()
        with pytest.raises(SessionTerminated):
            await s.send(b"late")
        r, w = await asyncio.open_connection(HOST, lst.port)
        w.write(b"HTTP/1.1")
        head = await r.read()
        await lst.close()
        return head, lst

    head, lst = run(main())
    assert head == t3.contact_header(0x05, 15, "ipn:0.0")  # sent before the peer's was read; then closed
    assert "magic" in lst.sessions[-1].error and lst.counters["handshakes_failed"] == 1


def test_connect_refused_is_one_line():
    async def main():
        srv = await asyncio.start_server(lambda r, w: None, HOST, 0)
        port = srv.sockets[0].getsockname()[1]
        srv.close()
        await srv.wait_closed()
        with pytest.raises(ClError, match="cannot connect"):
            await t3.connect(HOST, port, t3.Config())
    run(main())
