"""TCPCLv4 (RFC 9174) conformance: sat_node/dtn/cl/tcpcl4.py.

Oracle: the RFC's message figures, written out here byte by byte (section numbers beside each), and
a raw socket playing the peer, whose received bytes are compared with what the RFC says the entity
must answer. Both roles run against each other on loopback (127.0.0.1, a free port each).
"""

from __future__ import annotations

import asyncio
import ssl
import struct
import subprocess

import pytest

from sat_node.dtn.cl import ClError, SessionTerminated, TransferRefused
from sat_node.dtn.cl import tcpcl4 as t4

HOST = "127.0.0.1"


def run(coro, timeout=20):
    return asyncio.run(asyncio.wait_for(coro, timeout))


# --- encodings (RFC 9174 figures) ---------------------------------------------------------------

def test_contact_header_bytes():
    # 4.2 figure 3: magic 'dtn!' 0x64 0x74 0x6E 0x21, version 4, flags (CAN_TLS 0x01)
    assert t4.contact_header() == bytes([0x64, 0x74, 0x6E, 0x21, 0x04, 0x00])
    assert t4.contact_header(can_tls=True) == bytes([0x64, 0x74, 0x6E, 0x21, 0x04, 0x01])


def test_sess_init_bytes():
    # 4.6 figure 16: type 0x07, keepalive U16, segment MRU U64, transfer MRU U64, node ID length U16,
    # node ID, extension items length U32, items
    want = (bytes([0x07, 0x00, 0x1E]) + bytes(6) + bytes([0x03, 0xE8]) + bytes(6) + bytes([0x07, 0xD0])
            + bytes([0x00, 0x07]) + b"ipn:1.0" + bytes(4))
    assert t4.sess_init(30, 1000, 2000, "ipn:1.0") == want


def test_transfer_messages_bytes():
    # 5.2.2 figure 20 XFER_SEGMENT with START|END (0x03), transfer ID 5, the Transfer Length extension
    # (5.2.5 figure 24: flags 0, type 0x0001, length 8, U64 total) and 3 data bytes
    ext = bytes([0x00, 0x00, 0x01, 0x00, 0x08]) + bytes(7) + bytes([0x03])
    assert t4.transfer_length_ext(3) == ext
    want = bytes([0x01, 0x03]) + bytes(7) + bytes([0x05]) + bytes([0, 0, 0, 13]) + ext + bytes(7) + b"\x03abc"
    assert t4.xfer_segment(0x03, 5, b"abc", ext) == want
    # a continuation segment carries no extension list
    assert t4.xfer_segment(0x01, 5, b"z") == bytes([0x01, 0x01]) + bytes(7) + b"\x05" + bytes(7) + b"\x01z"
    # 5.2.3 figure 21 XFER_ACK: the segment's flags, transfer ID, cumulative length
    assert t4.xfer_ack(0x03, 5, 3) == bytes([0x02, 0x03]) + bytes(7) + b"\x05" + bytes(7) + b"\x03"
    # 5.2.4 figure 22 XFER_REFUSE: reason, transfer ID
    assert t4.xfer_refuse(t4.RefuseReason.NO_RESOURCES, 5) == bytes([0x03, 0x02]) + bytes(7) + b"\x05"


def test_session_messages_bytes():
    assert t4.keepalive() == b"\x04"  # 5.1.1 figure 18
    # 6.1 figure 25 SESS_TERM: flags (REPLY 0x01), reason ("Version mismatch" 0x02)
    assert t4.sess_term(t4.TermReason.VERSION_MISMATCH) == bytes([0x05, 0x00, 0x02])
    assert t4.sess_term(t4.TermReason.IDLE_TIMEOUT, reply=True) == bytes([0x05, 0x01, 0x01])
    # 5.1.2 figure 19 MSG_REJECT: reason ("Message Type Unknown" 0x01), the rejected message header
    assert t4.msg_reject(t4.RejectReason.TYPE_UNKNOWN, 0x0F) == bytes([0x06, 0x01, 0x0F])


def test_config_refuses_impossible_parameters():
    with pytest.raises(ValueError, match="keepalive"):
        t4.Config(keepalive_s=70000)
    with pytest.raises(ValueError, match="segment_mru"):
        t4.Config(segment_mru=0)


# --- both roles on loopback ------------------------------------------------------------------------

def test_both_roles_segmented_bundles_identical_and_keepalive_negotiated():
    bundles = [b"x" * 10, bytes(range(256)) * 40, b"\x9f" + b"y" * 2999]

    async def main():
        got_passive, got_active, sessions = [], [], []
        lst = await t4.serve(HOST, 0, t4.Config(node_id="ipn:2.0", keepalive_s=5, segment_mru=1000),
                             on_bundle=lambda b, s: got_passive.append(b), on_session=sessions.append)
        s = await t4.connect(HOST, lst.port, t4.Config(node_id="ipn:1.0", keepalive_s=30, segment_mru=700),
                             on_bundle=lambda b, s: got_active.append(b))
        assert (s.peer_node_id, s.peer_segment_mru, s.keepalive_s) == ("ipn:2.0", 1000, 5)
        for b in bundles:
            await s.send(b)
        # the passive side sends back on the same session (RFC 9174 is symmetric after SESS_INIT)
        back = sessions[0]
        assert (back.peer_node_id, back.keepalive_s) == ("ipn:1.0", 5)
        for b in bundles:
            await back.send(b)
        await s.terminate()
        await back.wait_closed()
        await lst.close()
        return got_passive, got_active, s, back

    got_passive, got_active, s, back = run(main())
    assert got_passive == bundles and got_active == bundles
    # 10240 bytes in segments of at most the peer's segment MRU 1000: 11 segments; 3000: 3
    assert s.counters["segments_sent"] == 1 + 11 + 3
    assert back.counters["segments_sent"] == 1 + 15 + 5  # segments of at most 700 bytes
    assert s.counters["bundles_sent"] == 3 and back.counters["bundles_received"] == 3
    assert s.term_sent == t4.TermReason.UNKNOWN and back.term_received == 0
    assert s.error is None and back.error is None


def test_refusal_by_policy_and_transfer_mru_up_front():
    async def main():
        verdict = {"reason": t4.RefuseReason.NOT_ACCEPTABLE}
        got = []
        lst = await t4.serve(HOST, 0, t4.Config(transfer_mru=5000, accept=lambda total: verdict["reason"]),
                             on_bundle=lambda b, s: got.append(b))
        s = await t4.connect(HOST, lst.port, t4.Config(segment_mru=100))
        with pytest.raises(TransferRefused) as exc:
            await s.send(b"a" * 100)
        assert exc.value.reason == t4.RefuseReason.NOT_ACCEPTABLE
        with pytest.raises(ClError, match="transfer MRU 5000"):
            await s.send(b"b" * 5001)  # refused here, before a byte leaves
        verdict["reason"] = None
        await s.send(b"c" * 4000)  # the session goes on after a refusal
        await s.terminate()
        await lst.close()
        return got, s, lst

    got, s, lst = run(main())
    assert got == [b"c" * 4000]
    assert lst.sessions[0].counters["refused_here.not_acceptable"] == 1
    assert s.counters["refused_by_peer"] == 1


def _selfsigned(tmp_path):
    key, crt = tmp_path / "k.pem", tmp_path / "c.pem"
    subprocess.run(["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", str(key), "-out", str(crt),
                    "-days", "1", "-subj", "/CN=localhost"], check=True, capture_output=True)
    return key, crt


def test_tls_when_both_offer_it(tmp_path):
    key, crt = _selfsigned(tmp_path)
    server_ctx = ssl.create_default_context(ssl.Purpose.CLIENT_AUTH)
    server_ctx.load_cert_chain(crt, key)
    client_ctx = ssl.create_default_context(cafile=str(crt))
    client_ctx.check_hostname = False

    async def main():
        got = []
        lst = await t4.serve(HOST, 0, t4.Config(ssl_context=server_ctx, require_tls=True),
                             on_bundle=lambda b, s: got.append(b))
        s = await t4.connect(HOST, lst.port, t4.Config(ssl_context=client_ctx))
        await s.send(b"secret" * 1000)
        assert s.tls and s._w.get_extra_info("ssl_object") is not None
        await s.terminate()
        # a peer that does not offer TLS is refused by a listener that requires it
        with pytest.raises(SessionTerminated) as exc:
            await t4.connect(HOST, lst.port, t4.Config())
        assert exc.value.reason == t4.TermReason.CONTACT_FAILURE
        await lst.close()
        return got

    assert run(main()) == [b"secret" * 1000]


# --- malformed input from a raw peer -------------------------------------------------------------

async def _raw(port):
    return await asyncio.open_connection(HOST, port)


async def _raw_session(port, keepalive_s=0, segment_mru=1 << 20):
    r, w = await _raw(port)
    w.write(t4.contact_header() + t4.sess_init(keepalive_s, segment_mru, 1 << 20, "ipn:9.0"))
    assert await r.readexactly(6) == t4.contact_header()
    assert (await r.readexactly(1))[0] == t4.MsgType.SESS_INIT
    _, _, _, nlen = struct.unpack(">HQQH", await r.readexactly(20))
    await r.readexactly(nlen)
    (elen,) = struct.unpack(">I", await r.readexactly(4))
    await r.readexactly(elen)
    return r, w


def _listen_and(check, **cfg):
    async def main():
        got = []
        lst = await t4.serve(HOST, 0, t4.Config(**cfg), on_bundle=lambda b, s: got.append(b))
        try:
            out = await check(lst)
        finally:
            await lst.close()
        return out, got, lst
    return run(main())


def test_bad_magic_closes_with_nothing_sent():
    async def check(lst):
        r, w = await _raw(lst.port)
        w.write(b"xtn!\x04\x00")
        return await r.read()
    reply, _, lst = _listen_and(check)
    assert reply == b""  # 4.3: connection closed, no SESS_TERM (there is no session)
    assert "magic" in lst.sessions[0].error and lst.counters["handshakes_failed"] == 1


def test_version_3_gets_contact_header_and_version_mismatch():
    async def check(lst):
        r, w = await _raw(lst.port)
        w.write(b"dtn!\x03\x00\x00\x0a\x07ipn:9.0")  # a TCPCLv3 contact header (RFC 7242 4.1)
        return await r.read()
    reply, _, lst = _listen_and(check)
    assert reply == b"dtn!\x04\x00" + bytes([0x05, 0x00, 0x02])  # 4.3: own header, SESS_TERM 0x02
    assert "version 3" in lst.sessions[0].error


def test_unknown_message_type_rejected_and_closed():
    async def check(lst):
        r, w = await _raw_session(lst.port)
        w.write(b"\x0f")
        return await r.read()
    reply, _, lst = _listen_and(check)
    assert reply == bytes([0x06, 0x01, 0x0F])  # 5.1.2: MSG_REJECT "Message Type Unknown"
    assert lst.sessions[0].counters["rejected_here.type_unknown"] == 1


def test_oversize_segment_length_ends_session_resource_exhaustion():
    async def check(lst):
        r, w = await _raw_session(lst.port)
        w.write(struct.pack(">BBQIQ", 0x01, 0x03, 0, 0, 1 << 40))
        return await r.read()
    reply, got, _ = _listen_and(check, segment_mru=4096)
    assert reply == bytes([0x05, 0x00, 0x05]) and got == []


def test_truncated_segment_loses_nothing_acknowledged():
    async def check(lst):
        r, w = await _raw_session(lst.port)
        w.write(t4.xfer_segment(0x03, 1, b"first", t4.transfer_length_ext(5)))
        ack = await r.readexactly(18)
        w.write(t4.xfer_segment(0x02, 2, b"sec", t4.transfer_length_ext(6)))
        ack2 = await r.readexactly(18)
        w.write(struct.pack(">BBQQ", 0x01, 0x01, 2, 100) + b"only ten b")  # cut inside the data
        w.close()
        await asyncio.sleep(0.2)
        return ack, ack2
    (ack, ack2), got, lst = _listen_and(check)
    assert ack == t4.xfer_ack(0x03, 1, 5) and ack2 == t4.xfer_ack(0x02, 2, 3)
    assert got == [b"first"]  # the acknowledged bundle kept, the cut one not delivered
    s = lst.sessions[0]
    assert "truncated" in s.error and s.counters["partial_transfers_discarded"] == 1


def test_unexpected_ack_rejected_and_session_goes_on():
    async def check(lst):
        r, w = await _raw_session(lst.port)
        w.write(t4.xfer_ack(0x03, 77, 10))
        rej = await r.readexactly(3)
        w.write(t4.xfer_segment(0x03, 0, b"ok", t4.transfer_length_ext(2)))
        ack = await r.readexactly(18)
        w.write(t4.sess_term(t4.TermReason.UNKNOWN))
        return rej, ack, await r.read()
    (rej, ack, tail), got, _ = _listen_and(check)
    assert rej == bytes([0x06, 0x03, 0x02])  # "Message Unexpected", header XFER_ACK
    assert ack == t4.xfer_ack(0x03, 0, 2) and got == [b"ok"]
    assert tail == bytes([0x05, 0x01, 0x00])  # 6.1: the reply carries REPLY and the same reason


def test_transfer_refusals_from_the_wire():
    async def check(lst):
        r, w = await _raw_session(lst.port)
        crit = t4.extension_item(0x7777, b"?", critical=True)
        w.write(t4.xfer_segment(0x02, 1, b"ab", crit))
        w.write(t4.xfer_segment(0x01, 1, b"cd"))  # the rest of a refused transfer: dropped
        w.write(t4.xfer_segment(0x03, 2, b"x", t4.transfer_length_ext(10_000)))
        return await r.readexactly(10), await r.readexactly(10)
    (ref1, ref2), got, _ = _listen_and(check, transfer_mru=1000)
    assert ref1 == t4.xfer_refuse(t4.RefuseReason.EXTENSION_FAILURE, 1)
    assert ref2 == t4.xfer_refuse(t4.RefuseReason.NO_RESOURCES, 2)
    assert got == []


def test_idle_peer_gets_idle_timeout():
    async def check(lst):
        r, _w = await _raw_session(lst.port, keepalive_s=1)
        return await r.read()  # say nothing; the listener keepalives, then gives up after 2 s
    reply, _, lst = _listen_and(check, keepalive_s=1)
    assert reply.endswith(bytes([0x05, 0x00, 0x01])) and set(reply[:-3]) <= {0x04}
    assert lst.sessions[0].counters["keepalives_sent"] >= 1


def test_sender_sees_a_peer_that_vanishes():
    async def main():
        async def mute(reader, writer):
            writer.write(t4.contact_header())
            await reader.readexactly(6)
            writer.write(t4.sess_init(0, 100, 1000, "ipn:5.0"))
            await asyncio.sleep(0.2)
            writer.close()
        srv = await asyncio.start_server(mute, HOST, 0)
        s = await t4.connect(HOST, srv.sockets[0].getsockname()[1], t4.Config())
        with pytest.raises(SessionTerminated):
            await s.send(b"z" * 500)
        srv.close()
        return s
    s = run(main())
    assert s.closed and s.counters["bundles_sent"] == 0
