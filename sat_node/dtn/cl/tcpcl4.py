"""TCPCLv4: the DTN TCP convergence layer, version 4 (RFC 9174), both roles, TLS optional.

The protocol, by RFC 9174 section:

* 4.2 contact header: ``dtn!``, version 4, flags (CAN_TLS 0x01). 4.3: a header without the magic
  closes the connection with nothing sent; a passive entity that receives another version sends its
  own header and SESS_TERM "Version mismatch"; an active entity that receives another version closes
  the connection. 4.4: TLS when both headers say CAN_TLS and a context is configured (the active
  entity is the TLS client); ``require_tls`` refuses a session without it (SESS_TERM "Contact
  Failure").
* 4.6 SESS_INIT (keepalive U16, segment MRU U64, transfer MRU U64, node ID, extension items); the
  active entity sends first. 4.7 negotiation: the session keepalive is the minimum of the two (0 if
  either is 0); a sender's segments are at most the peer's segment MRU, its transfers at most the
  peer's transfer MRU (a larger bundle is refused up front, before a byte is sent). 4.8: an unknown
  session extension marked CRITICAL ends the session ("Contact Failure").
* 5.1.1 KEEPALIVE, sent when nothing else was sent for a keepalive interval; a session that received
  nothing for twice the interval ends with SESS_TERM "Idle timeout".
* 5.1.2 MSG_REJECT (reason, rejected header): an unknown message type is answered with "Message Type
  Unknown" and the connection closed (the framing is lost); a message out of place (an XFER_ACK for
  no transfer, a second SESS_INIT, a continuation segment of no transfer) with "Message Unexpected",
  and the session goes on.
* 5.2.2 XFER_SEGMENT (flags END 0x01 / START 0x02, transfer ID U64, extension items on START only,
  data length U64, data); 5.2.5 the Transfer Length extension (type 0x0001) on every START.
  5.2.3 XFER_ACK (the segment's flags, transfer ID, cumulative acknowledged length), one per segment.
  5.2.4 XFER_REFUSE (reason, transfer ID): the receiver refuses a transfer larger than its transfer
  MRU ("No Resources"), one with an unknown CRITICAL transfer extension ("Extension Failure"), one
  its policy rejects (``Config.accept``), one started after SESS_TERM ("Session Terminating"); the
  sender stops its segments and :meth:`Session.send` raises :class:`TransferRefused`.
* 6.1 SESS_TERM (flags REPLY 0x01, reason): answered once with the REPLY flag and the same reason;
  transfers in progress may finish, no new one starts; the connection closes when both sides sent
  SESS_TERM and nothing is in flight.

What a receiver does with bad input (the session never takes the process down): a data length above
its segment MRU, or extension items over 64 KiB, ends the session with SESS_TERM "Resource
Exhaustion" (it cannot buffer them); a connection lost inside a segment loses only that transfer: a
bundle is handed to the caller before its last XFER_ACK leaves, so every bundle the peer saw fully
acknowledged was delivered here. Each session counts what it did (``Session.counters``).

Not done: reactive fragmentation of a transfer cut by the session's end (RFC 9174 5.2.6, optional:
the partial bundle is discarded), TLS certificate checks of the node ID (the ssl context does what it
is configured to do; RFC 9174 4.4.3's Node ID authentication is not implemented), session
extensions (none are defined).

Why one module: the message encoders, the session's state machine and the two roles are one
protocol: the session reads what the encoders write and the tests drive both through the same
names; split, each half would import the other's constants and private state.

How we know it is right: the byte encodings of each message written out by hand from the RFC's
figures, both roles against each other on loopback (segmentation under a small segment MRU,
refusal, termination, keepalive, TLS with a throw-away certificate), every malformed input of the
list above sent by a raw socket with the reply bytes checked (tests/unit/test_cl_tcpcl4.py); the
RFC author's own implementation (github BrianSipos/dtn-demo-agent) as the peer in both roles, bundles
both ways on one session, each larger than the other side's segment MRU
(tests/interop/test_tcpcl4_interop.py, marker ``interop``).
"""

from __future__ import annotations

import asyncio
import contextlib
import ssl
import struct
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from enum import IntEnum

from .errors import ClError, SessionTerminated, TransferRefused, count_failure, send_failure
from .listener import Listener as _Listener
from .listener import start as _start

__all__ = [
    "MAGIC",
    "VERSION",
    "Config",
    "Listener",
    "MsgType",
    "RefuseReason",
    "RejectReason",
    "Session",
    "TermReason",
    "connect",
    "contact_header",
    "extension_item",
    "keepalive",
    "msg_reject",
    "serve",
    "sess_init",
    "sess_term",
    "transfer_length_ext",
    "xfer_ack",
    "xfer_refuse",
    "xfer_segment",
]

MAGIC = b"dtn!"
VERSION = 4
CAN_TLS = 0x01
FLAG_END, FLAG_START = 0x01, 0x02
TERM_REPLY = 0x01
EXT_CRITICAL = 0x01
EXT_TRANSFER_LENGTH = 0x0001
MAX_EXTENSIONS = 64 * 1024  # bytes of extension items a receiver buffers


class MsgType(IntEnum):  # RFC 9174 table 5 (section 9.5)
    XFER_SEGMENT = 0x01
    XFER_ACK = 0x02
    XFER_REFUSE = 0x03
    KEEPALIVE = 0x04
    SESS_TERM = 0x05
    MSG_REJECT = 0x06
    SESS_INIT = 0x07


class TermReason(IntEnum):  # RFC 9174 6.1, table 9
    UNKNOWN = 0x00
    IDLE_TIMEOUT = 0x01
    VERSION_MISMATCH = 0x02
    BUSY = 0x03
    CONTACT_FAILURE = 0x04
    RESOURCE_EXHAUSTION = 0x05


class RefuseReason(IntEnum):  # RFC 9174 5.2.4, table 8
    UNKNOWN = 0x00
    COMPLETED = 0x01
    NO_RESOURCES = 0x02
    RETRANSMIT = 0x03
    NOT_ACCEPTABLE = 0x04
    EXTENSION_FAILURE = 0x05
    SESSION_TERMINATING = 0x06


class RejectReason(IntEnum):  # RFC 9174 5.1.2, table 6
    TYPE_UNKNOWN = 0x01
    UNSUPPORTED = 0x02
    UNEXPECTED = 0x03


# --- encoders (RFC 9174 figures 3, 16, 17, 18, 19, 20, 21, 22, 23, 24) ---------------------------

def contact_header(can_tls: bool = False) -> bytes:
    return MAGIC + bytes([VERSION, CAN_TLS if can_tls else 0])


def extension_item(item_type: int, data: bytes, critical: bool = False) -> bytes:
    return struct.pack(">BHH", EXT_CRITICAL if critical else 0, item_type, len(data)) + data


def transfer_length_ext(total: int) -> bytes:
    return extension_item(EXT_TRANSFER_LENGTH, struct.pack(">Q", total))


def sess_init(keepalive_s: int, segment_mru: int, transfer_mru: int, node_id: str,
              extensions: bytes = b"") -> bytes:
    nid = node_id.encode("utf-8")
    return (struct.pack(">BHQQH", MsgType.SESS_INIT, keepalive_s, segment_mru, transfer_mru, len(nid)) + nid
            + struct.pack(">I", len(extensions)) + extensions)


def xfer_segment(flags: int, transfer_id: int, data: bytes, extensions: bytes = b"") -> bytes:
    head = struct.pack(">BBQ", MsgType.XFER_SEGMENT, flags, transfer_id)
    if flags & FLAG_START:
        head += struct.pack(">I", len(extensions)) + extensions
    return head + struct.pack(">Q", len(data)) + data


def xfer_ack(flags: int, transfer_id: int, length: int) -> bytes:
    return struct.pack(">BBQQ", MsgType.XFER_ACK, flags, transfer_id, length)


def xfer_refuse(reason: int, transfer_id: int) -> bytes:
    return struct.pack(">BBQ", MsgType.XFER_REFUSE, reason, transfer_id)


def keepalive() -> bytes:
    return bytes([MsgType.KEEPALIVE])


def sess_term(reason: int, reply: bool = False) -> bytes:
    return bytes([MsgType.SESS_TERM, TERM_REPLY if reply else 0, reason])


def msg_reject(reason: int, rejected_header: int) -> bytes:
    return bytes([MsgType.MSG_REJECT, reason, rejected_header])


def _parse_extensions(raw: bytes) -> list[tuple[int, int, bytes]]:
    """(flags, type, data) of each item of an extension list (RFC 9174 4.8 / 5.2.5)."""
    out, i = [], 0
    while i < len(raw):
        if len(raw) - i < 5:
            raise ClError(f"extension item truncated at byte {i} of {len(raw)}")
        flags, typ, n = struct.unpack_from(">BHH", raw, i)
        i += 5
        if len(raw) - i < n:
            raise ClError(f"extension item type {typ:#06x} claims {n} bytes, {len(raw) - i} left")
        out.append((flags, typ, raw[i:i + n]))
        i += n
    return out


# --- configuration and the session -----------------------------------------------------------------

@dataclass
class Config:
    """One entity's side of a session. ``accept(total_length)`` is the receive policy called at the
    start of each transfer (total from the Transfer Length extension, None without one): it returns
    None to accept or a :class:`RefuseReason`."""
    node_id: str = "ipn:0.0"
    keepalive_s: int = 30
    segment_mru: int = 1 << 20
    transfer_mru: int = 1 << 26
    tx_segment_max: int | None = None
    ssl_context: ssl.SSLContext | None = None
    require_tls: bool = False
    accept: Callable[[int | None], RefuseReason | None] | None = None
    handshake_timeout_s: float = 10.0

    def __post_init__(self):
        if not 0 <= self.keepalive_s <= 0xFFFF:
            raise ValueError(f"keepalive {self.keepalive_s} s: must be 0..65535")
        for name in ("segment_mru", "transfer_mru"):
            if not 1 <= getattr(self, name) < 1 << 64:
                raise ValueError(f"{name} {getattr(self, name)}: must be 1..2^64-1")
        if len(self.node_id.encode("utf-8")) > 0xFFFF:
            raise ValueError("node ID longer than 65535 bytes")


@dataclass
class _OutTransfer:
    total: int
    done: asyncio.Future
    acked: int = 0


class Session:
    """One TCPCLv4 session over a connected stream (``active``: this side opened it)."""

    def __init__(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter, config: Config,
                 active: bool, on_bundle: Callable[[bytes, Session], None] | None = None):
        self._r, self._w, self.config, self.active = reader, writer, config, active
        self.on_bundle = on_bundle
        peer = writer.get_extra_info("peername")
        self.peer = f"{peer[0]}:{peer[1]}" if peer else "?"
        self.counters: Counter[str] = Counter()
        self.peer_node_id: str | None = None
        self.peer_segment_mru = self.peer_transfer_mru = 0
        self.keepalive_s = 0
        self.tls = False
        self.term_sent: TermReason | None = None
        self.term_received: int | None = None
        self.error: str | None = None  # the first protocol error seen, one line
        self._next_tid = 0
        self._out: dict[int, _OutTransfer] = {}
        self._tx_lock = asyncio.Lock()
        self._rx_tid: int | None = None
        self._rx_buf = bytearray()
        self._rx_refused: set[int] = set()
        self._closed = asyncio.get_running_loop().create_future()
        self._tasks: list[asyncio.Task] = []
        loop = asyncio.get_running_loop()
        self._last_rx = self._last_tx = loop.time()

    # ----- setup (RFC 9174 4.2 - 4.7)
    async def handshake(self) -> None:
        try:
            await asyncio.wait_for(self._handshake(), self.config.handshake_timeout_s)
        except TimeoutError:
            self._fail("no contact header / SESS_INIT within the handshake time-out")
            raise ClError(f"TCPCLv4 {self.peer}: {self.error}") from None
        except ClError:
            self._finish()
            raise
        except (ConnectionError, asyncio.IncompleteReadError, ssl.SSLError, OSError) as exc:
            self._fail(f"connection lost during the handshake ({type(exc).__name__}: {exc})")
            raise SessionTerminated(f"TCPCLv4 {self.peer}: {self.error}") from None

    async def _handshake(self) -> None:
        c = self.config
        can_tls = c.ssl_context is not None
        if self.active:
            self._write(contact_header(can_tls))
        head = await self._r.readexactly(6)
        if head[:4] != MAGIC:
            self._fail(f"bad contact header magic {head[:4]!r} (want b'dtn!')")
            raise ClError(f"TCPCLv4 {self.peer}: {self.error}")
        if head[4] != VERSION:
            if not self.active:  # 4.3: the passive entity answers with its header and SESS_TERM
                self._write(contact_header(can_tls) + sess_term(TermReason.VERSION_MISMATCH))
                self.term_sent = TermReason.VERSION_MISMATCH
                await self._drain()
            self._fail(f"peer speaks TCPCL version {head[4]}, not {VERSION}")
            raise ClError(f"TCPCLv4 {self.peer}: {self.error}")
        if not self.active:
            self._write(contact_header(can_tls))
        self.tls = can_tls and bool(head[5] & CAN_TLS)
        if self.tls:
            await self._drain()
            await self._w.start_tls(c.ssl_context, server_hostname=None if not self.active else
                                    (None if not c.ssl_context.check_hostname else self._host()))
        elif c.require_tls:
            await self._term(TermReason.CONTACT_FAILURE)
            self._fail("TLS required by configuration, not offered by the peer")
            raise ClError(f"TCPCLv4 {self.peer}: {self.error}")
        mine = sess_init(c.keepalive_s, c.segment_mru, c.transfer_mru, c.node_id)
        if self.active:
            self._write(mine)
        t = (await self._r.readexactly(1))[0]
        if t == MsgType.SESS_TERM:
            _flags, reason = await self._r.readexactly(2)
            self.term_received = reason
            self._fail(f"peer ended the session before SESS_INIT (reason {reason})")
            raise SessionTerminated(f"TCPCLv4 {self.peer}: {self.error}", reason)
        if t != MsgType.SESS_INIT:
            if t not in MsgType.__members__.values():
                self._write(msg_reject(RejectReason.TYPE_UNKNOWN, t))
            await self._term(TermReason.CONTACT_FAILURE)
            self._fail(f"message type {t:#04x} where SESS_INIT was due")
            raise ClError(f"TCPCLv4 {self.peer}: {self.error}")
        ka, smru, tmru, nid = await self._read_sess_init()
        if smru == 0 or tmru == 0:
            await self._term(TermReason.CONTACT_FAILURE)
            self._fail(f"SESS_INIT with segment MRU {smru}, transfer MRU {tmru} (must be > 0)")
            raise ClError(f"TCPCLv4 {self.peer}: {self.error}")
        if not self.active:
            self._write(mine)
        await self._drain()
        self.peer_node_id, self.peer_segment_mru, self.peer_transfer_mru = nid, smru, tmru
        self.keepalive_s = 0 if 0 in (ka, c.keepalive_s) else min(ka, c.keepalive_s)

    def _host(self) -> str | None:
        peer = self._w.get_extra_info("peername")
        return peer[0] if peer else None

    async def _read_sess_init(self) -> tuple[int, int, int, str]:
        ka, smru, tmru, nlen = struct.unpack(">HQQH", await self._r.readexactly(20))
        raw_nid = await self._r.readexactly(nlen)
        (elen,) = struct.unpack(">I", await self._r.readexactly(4))
        if elen > MAX_EXTENSIONS:
            await self._term(TermReason.RESOURCE_EXHAUSTION)
            self._fail(f"SESS_INIT extension items of {elen} bytes (over {MAX_EXTENSIONS})")
            raise ClError(f"TCPCLv4 {self.peer}: {self.error}")
        raw_ext = await self._r.readexactly(elen)
        try:
            nid = raw_nid.decode("utf-8")
            exts = _parse_extensions(raw_ext)
        except (UnicodeDecodeError, ClError) as exc:
            await self._term(TermReason.CONTACT_FAILURE)
            self._fail(f"malformed SESS_INIT: {exc}")
            raise ClError(f"TCPCLv4 {self.peer}: {self.error}") from None
        for flags, typ, _ in exts:
            if flags & EXT_CRITICAL:  # 4.8: no session extension is known here
                await self._term(TermReason.CONTACT_FAILURE)
                self._fail(f"unknown critical session extension {typ:#06x}")
                raise ClError(f"TCPCLv4 {self.peer}: {self.error}")
        return ka, smru, tmru, nid

    # ----- running
    def start(self) -> None:
        """Start reading messages (and keepalives) after :meth:`handshake`."""
        self._tasks.append(asyncio.ensure_future(self._read_loop()))
        if self.keepalive_s:
            self._tasks.append(asyncio.ensure_future(self._keepalive_loop()))

    async def wait_closed(self) -> None:
        await asyncio.shield(self._closed)

    @property
    def closed(self) -> bool:
        return self._closed.done()

    async def send(self, data: bytes, timeout_s: float | None = None) -> None:
        """Send one bundle; return when the peer acknowledged all of it (5.2.3)."""
        if self.term_sent is not None or self.term_received is not None or self.closed:
            raise SessionTerminated(f"TCPCLv4 {self.peer}: session ending, no new transfer")
        if len(data) > self.peer_transfer_mru:
            raise ClError(f"TCPCLv4 {self.peer}: bundle of {len(data)} bytes over the peer's transfer MRU "
                          f"{self.peer_transfer_mru}")
        async with self._tx_lock:
            tid = self._next_tid
            self._next_tid += 1
            fut = asyncio.get_running_loop().create_future()
            self._out[tid] = _OutTransfer(len(data), fut)
            seg = min(self.peer_segment_mru, self.config.tx_segment_max or self.peer_segment_mru)
            try:
                off = 0
                while True:
                    chunk = data[off:off + seg]
                    flags = (FLAG_START if off == 0 else 0) | (FLAG_END if off + len(chunk) >= len(data) else 0)
                    ext = transfer_length_ext(len(data)) if off == 0 else b""
                    self._write(xfer_segment(flags, tid, chunk, ext))
                    self.counters["segments_sent"] += 1
                    off += len(chunk)
                    await self._drain()
                    if fut.done() or flags & FLAG_END:
                        break
                await asyncio.wait_for(asyncio.shield(fut), timeout_s)
            except (ConnectionError, OSError) as exc:
                self._fail(send_failure(exc, timeout_s))
                raise SessionTerminated(f"TCPCLv4 {self.peer}: {self.error}") from None
            finally:
                self._out.pop(tid, None)
                self._maybe_close()
            self.counters["bundles_sent"] += 1
            self.counters["bytes_sent"] += len(data)

    async def terminate(self, reason: TermReason = TermReason.UNKNOWN, timeout_s: float = 5.0) -> None:
        """End the session (6.1): SESS_TERM, wait for the peer's reply and the connection's end."""
        if not self.closed and self.term_sent is None:
            await self._term(reason, close=False)
            self._maybe_close()
        with contextlib.suppress(asyncio.TimeoutError):
            await asyncio.wait_for(self.wait_closed(), timeout_s)
        self._finish()

    def abort(self) -> None:
        """Drop the connection at once, without SESS_TERM: for a peer that no longer reads (a
        :meth:`terminate` whose SESS_TERM cannot be written would wait on it)."""
        self._fail("connection lost: aborted by this side")
        with contextlib.suppress(Exception):
            self._w.transport.abort()
        self._finish()

    # ----- internals
    def _write(self, data: bytes) -> None:
        self._w.write(data)
        self._last_tx = asyncio.get_running_loop().time()

    async def _drain(self) -> None:
        await self._w.drain()

    def _fail(self, why: str) -> None:
        if self.error is None:
            self.error = why
        count_failure(self.counters, why)

    async def _term(self, reason: TermReason, reply: bool = False, close: bool = True) -> None:
        if self.term_sent is None:
            self.term_sent = TermReason(reason) if reason in TermReason.__members__.values() else reason
            with contextlib.suppress(ConnectionError, OSError):
                self._write(sess_term(reason, reply))
                await self._drain()
        if close:
            self._finish()

    def _finish(self) -> None:
        for t in self._tasks:
            if t is not asyncio.current_task():
                t.cancel()
        for o in self._out.values():
            if not o.done.done():
                o.done.set_exception(SessionTerminated(
                    f"TCPCLv4 {self.peer}: session ended before the transfer was acknowledged"
                    + (f" ({self.error})" if self.error else ""), self.term_received))
                o.done.exception()  # retrieved: no "never retrieved" warning when nobody waits
        with contextlib.suppress(Exception):
            self._w.close()
        if not self._closed.done():
            self._closed.set_result(None)

    def _maybe_close(self) -> None:
        if self.term_sent is not None and self.term_received is not None and not self._out:
            self._finish()

    async def _keepalive_loop(self) -> None:
        loop = asyncio.get_running_loop()
        ka = self.keepalive_s
        while not self.closed:
            await asyncio.sleep(min(ka / 4, 1.0))
            now = loop.time()
            if now - self._last_rx > 2 * ka:  # 5.1.1: idle
                self._fail(f"nothing received for {now - self._last_rx:.1f} s (keepalive {ka} s)")
                await self._term(TermReason.IDLE_TIMEOUT)
                return
            if now - self._last_tx >= ka and self.term_sent is None:
                with contextlib.suppress(ConnectionError, OSError):
                    self._write(keepalive())
                    self.counters["keepalives_sent"] += 1

    async def _read_loop(self) -> None:
        try:
            while True:
                try:
                    t = (await self._r.readexactly(1))[0]
                except asyncio.IncompleteReadError:
                    if self.term_sent is None or self.term_received is None:
                        self._fail("connection lost: closed without SESS_TERM")
                    break
                self._last_rx = asyncio.get_running_loop().time()
                if not await self._dispatch(t):
                    break
        except asyncio.IncompleteReadError as exc:
            self._drop_partial()
            self._fail(f"connection lost: message truncated ({len(exc.partial)} of {exc.expected} bytes)")
        except (ConnectionError, OSError, ssl.SSLError) as exc:
            self._drop_partial()
            self._fail(f"connection lost: {type(exc).__name__}: {exc}")
        except asyncio.CancelledError:
            raise
        finally:
            self._drop_partial()
            self._finish()

    def _drop_partial(self) -> None:
        if self._rx_tid is not None:
            self.counters["partial_transfers_discarded"] += 1
            self._rx_tid = None
            self._rx_buf = bytearray()

    async def _dispatch(self, t: int) -> bool:
        """Handle one message whose type byte is ``t``; False ends the session."""
        r = self._r
        if t == MsgType.XFER_SEGMENT:
            return await self._on_segment()
        if t == MsgType.XFER_ACK:
            flags, tid, n = struct.unpack(">BQQ", await r.readexactly(17))
            o = self._out.get(tid)
            if o is None or n > o.total:
                self._write(msg_reject(RejectReason.UNEXPECTED, t))
                self.counters["rejected_here.unexpected"] += 1
                return True
            o.acked = n
            if flags & FLAG_END and n == o.total and not o.done.done():
                o.done.set_result(None)
            return True
        if t == MsgType.XFER_REFUSE:
            reason, tid = struct.unpack(">BQ", await r.readexactly(9))
            o = self._out.get(tid)
            self.counters["refused_by_peer"] += 1
            if o is not None and not o.done.done():
                name = RefuseReason(reason).name if reason in RefuseReason.__members__.values() else str(reason)
                o.done.set_exception(TransferRefused(f"TCPCLv4 {self.peer}: transfer {tid} refused ({name})",
                                                     reason))
            return True
        if t == MsgType.KEEPALIVE:
            self.counters["keepalives_received"] += 1
            return True
        if t == MsgType.SESS_TERM:
            flags, reason = await r.readexactly(2)
            self.term_received = reason
            if self.term_sent is None:  # 6.1: reply once, same reason
                self.term_sent = reason
                self._write(sess_term(reason, reply=True))
                await self._drain()
            self._maybe_close()
            return not self.closed
        if t == MsgType.MSG_REJECT:
            reason, head = await r.readexactly(2)
            self.counters["rejected_by_peer"] += 1
            self._fail(f"peer rejected message type {head:#04x} (reason {reason})")
            return True
        if t == MsgType.SESS_INIT:
            await self._read_sess_init()
            self._write(msg_reject(RejectReason.UNEXPECTED, t))
            self.counters["rejected_here.unexpected"] += 1
            return True
        # 5.1.2: unknown type - the rest of the stream cannot be framed
        self._fail(f"unknown message type {t:#04x}")
        self.counters["rejected_here.type_unknown"] += 1
        self._write(msg_reject(RejectReason.TYPE_UNKNOWN, t))
        with contextlib.suppress(ConnectionError, OSError):
            await self._drain()
        return False

    async def _on_segment(self) -> bool:
        r = self._r
        flags, tid = struct.unpack(">BQ", await r.readexactly(9))
        exts: list[tuple[int, int, bytes]] = []
        refuse: RefuseReason | None = None
        if flags & FLAG_START:
            (elen,) = struct.unpack(">I", await r.readexactly(4))
            if elen > MAX_EXTENSIONS:
                self._fail(f"transfer {tid}: extension items of {elen} bytes (over {MAX_EXTENSIONS})")
                await self._term(TermReason.RESOURCE_EXHAUSTION)
                return False
            try:
                exts = _parse_extensions(await r.readexactly(elen))
            except ClError:
                refuse = RefuseReason.EXTENSION_FAILURE
        (n,) = struct.unpack(">Q", await r.readexactly(8))
        if n > self.config.segment_mru:
            self._fail(f"transfer {tid}: segment of {n} bytes over the segment MRU {self.config.segment_mru}")
            await self._term(TermReason.RESOURCE_EXHAUSTION)
            return False
        data = await r.readexactly(n)
        self.counters["segments_received"] += 1
        if flags & FLAG_START:
            if self._rx_tid is not None:  # a new transfer before the last one ended
                self._drop_partial()
            total = None
            for eflags, typ, edata in exts:
                if typ == EXT_TRANSFER_LENGTH and len(edata) == 8:
                    (total,) = struct.unpack(">Q", edata)
                elif eflags & EXT_CRITICAL:
                    refuse = RefuseReason.EXTENSION_FAILURE
            if refuse is None and self.term_sent is not None:
                refuse = RefuseReason.SESSION_TERMINATING
            if refuse is None and total is not None and total > self.config.transfer_mru:
                refuse = RefuseReason.NO_RESOURCES
            if refuse is None and self.config.accept is not None:
                refuse = self.config.accept(total)
            if refuse is not None:
                return self._refuse(refuse, tid)
            self._rx_tid, self._rx_buf = tid, bytearray()
        elif tid in self._rx_refused:
            return True  # the rest of a refused transfer: dropped (5.2.4)
        elif tid != self._rx_tid:
            self._write(msg_reject(RejectReason.UNEXPECTED, MsgType.XFER_SEGMENT))
            self.counters["rejected_here.unexpected"] += 1
            return True
        self._rx_buf += data
        if len(self._rx_buf) > self.config.transfer_mru:
            self._rx_tid = None
            self._rx_buf = bytearray()
            return self._refuse(RefuseReason.NO_RESOURCES, tid)
        if flags & FLAG_END:
            bundle = bytes(self._rx_buf)
            self._rx_tid, self._rx_buf = None, bytearray()
            if self.on_bundle is not None:
                try:
                    self.on_bundle(bundle, self)  # handed over before the last ACK leaves
                except Exception as exc:  # noqa: BLE001 - the caller's store failed: refuse, keep going
                    self._fail(f"transfer {tid}: the receiver could not take the bundle ({exc})")
                    return self._refuse(RefuseReason.NO_RESOURCES, tid)
            self.counters["bundles_received"] += 1
            self.counters["bytes_received"] += len(bundle)
            self._write(xfer_ack(flags, tid, len(bundle)))
        else:
            self._write(xfer_ack(flags, tid, len(self._rx_buf)))
        return True

    def _refuse(self, reason: RefuseReason, tid: int) -> bool:
        self._rx_refused.add(tid)
        self.counters[f"refused_here.{RefuseReason(reason).name.lower()}"] += 1
        self._write(xfer_refuse(reason, tid))
        return True


# --- the two roles ---------------------------------------------------------------------------------

async def connect(host: str, port: int, config: Config,
                  on_bundle: Callable[[bytes, Session], None] | None = None) -> Session:
    """Open a session as the active entity; it is established (SESS_INIT exchanged) on return."""
    try:
        reader, writer = await asyncio.wait_for(asyncio.open_connection(host, port), config.handshake_timeout_s)
    except (TimeoutError, OSError) as exc:
        raise ClError(f"TCPCLv4 {host}:{port}: cannot connect ({exc or 'time-out'})") from None
    s = Session(reader, writer, config, active=True, on_bundle=on_bundle)
    await s.handshake()
    s.start()
    return s


class Listener(_Listener):
    """A passive entity: every accepted connection becomes a :class:`Session` (kept in
    ``sessions``); a session that fails its handshake is counted and closed, never raised."""

    session_cls = Session

    async def _end(self, session: Session) -> None:
        await session.terminate(timeout_s=1.0)


async def serve(host: str, port: int, config: Config,
                on_bundle: Callable[[bytes, Session], None] | None = None,
                on_session: Callable[[Session], None] | None = None) -> Listener:
    """Listen as the passive entity (port 0: any free port, ``Listener.port`` says which)."""
    return await _start(Listener(config, on_bundle, on_session), host, port)
