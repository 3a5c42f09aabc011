"""TCPCLv3: the DTN TCP convergence layer, version 3 (RFC 7242), both roles - what ION 4.x's ``tcp``
convergence layer (tcpcli/tcpclo) and uD3TN speak.

The protocol, by RFC 7242 section:

* 4.1 contact header: ``dtn!``, version 3, flags (0x01 request segment acknowledgments, 0x02 reactive
  fragmentation, 0x04 bundle refusal, 0x08 LENGTH messages), keepalive interval U16 [s], the local
  EID length as an SDNV (RFC 6256) and the EID. Both sides send theirs at once (no active/passive
  order). 4.3 negotiation: keepalive the minimum of the two (0 if either is 0); acknowledgments when
  both ask; refusal when both offer it and acknowledgments are on; LENGTH messages sent to a peer
  that asks for them. Reactive fragmentation is never offered (not done here).
* 5.1 the message header: type in the high nibble, flags in the low one. 5.2 DATA_SEGMENT (0x1; S
  0x02 start, E 0x01 end; length SDNV, data); 5.3 ACK_SEGMENT (0x2; the cumulative length received
  of the bundle, SDNV), one per segment when acknowledgments are on; 5.4 REFUSE_BUNDLE (0x3; reason
  in the flags nibble: 0 unknown, 1 completely received, 2 resources exhausted, 3 retransmit); 5.5
  KEEPALIVE (0x4); 5.6 SHUTDOWN (0x5; R 0x02 a reason byte follows: 0 idle time-out, 1 version
  mismatch, 2 busy; D 0x01 a reconnection delay SDNV follows); 5.7 LENGTH (0x6; the bundle's total
  length, SDNV). A sender with acknowledgments on waits for the final ACK_SEGMENT covering the whole
  bundle (without them, a bundle is sent when written).
* 6.1 SHUTDOWN: answered once, then the connection closes; 4.2 a contact header of another version is
  answered with SHUTDOWN "version mismatch"; a header without the magic closes the connection.

What a receiver does with bad input: a message type RFC 7242 does not define, an SDNV over 64 bits
or a segment longer than ``Config.max_bundle`` ends the session (SHUTDOWN without a reason - version
3 has no MSG_REJECT) and is counted; a connection lost inside a segment loses only that bundle (a
bundle is handed to the caller before its final ACK_SEGMENT leaves).

How we know it is right: the encodings written out by hand from the RFC's figures, the SDNV
examples of RFC 6256 section 2.1, both roles against each other (segmentation, refusal, shutdown,
malformed input from a raw socket) in tests/unit/test_cl_tcpcl3.py, and pyd3tn's TCPCLv3 client
(the uD3TN project's, an independent implementation) sending to this listener there; ION 4.1.3's
tcpcli/tcpclo both ways in tests/interop/test_ion.py (marker ``interop``).
"""

from __future__ import annotations

import asyncio
import contextlib
import struct
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from enum import IntEnum

from .errors import ClError, SessionTerminated, TransferRefused, count_failure, send_failure
from .listener import Listener as _Listener
from .listener import start as _start

__all__ = ["MAGIC", "VERSION", "Config", "Listener", "MsgType", "RefuseReason", "Session", "ShutdownReason",
           "ack_segment", "connect", "contact_header", "data_segment", "keepalive", "length_msg",
           "refuse_bundle", "sdnv", "serve", "shutdown"]

MAGIC = b"dtn!"
VERSION = 3
ACKS, REACTIVE, REFUSALS, LENGTHS = 0x01, 0x02, 0x04, 0x08
SEG_END, SEG_START = 0x01, 0x02
SHUT_DELAY, SHUT_REASON = 0x01, 0x02


class MsgType(IntEnum):  # RFC 7242 5.1, table 2
    DATA_SEGMENT = 0x1
    ACK_SEGMENT = 0x2
    REFUSE_BUNDLE = 0x3
    KEEPALIVE = 0x4
    SHUTDOWN = 0x5
    LENGTH = 0x6


class RefuseReason(IntEnum):  # RFC 7242 5.4, table 3
    UNKNOWN = 0x0
    COMPLETED = 0x1
    NO_RESOURCES = 0x2
    RETRANSMIT = 0x3


class ShutdownReason(IntEnum):  # RFC 7242 5.6, table 4
    IDLE_TIMEOUT = 0x00
    VERSION_MISMATCH = 0x01
    BUSY = 0x02


def sdnv(n: int) -> bytes:
    """RFC 6256 SDNV: 7 bits a byte, most significant first, the high bit set on all but the last."""
    if n < 0:
        raise ValueError("SDNV of a negative number")
    out = [n & 0x7F]
    n >>= 7
    while n:
        out.append(0x80 | (n & 0x7F))
        n >>= 7
    return bytes(reversed(out))


async def read_sdnv(r: asyncio.StreamReader) -> int:
    n = 0
    for _ in range(10):  # 64 bits fit in 10 bytes
        b = (await r.readexactly(1))[0]
        n = (n << 7) | (b & 0x7F)
        if not b & 0x80:
            if n >= 1 << 64:
                break
            return n
    raise ClError("SDNV longer than 64 bits")


def contact_header(flags: int, keepalive_s: int, eid: str) -> bytes:
    e = eid.encode("utf-8")
    return MAGIC + struct.pack(">BBH", VERSION, flags, keepalive_s) + sdnv(len(e)) + e


def data_segment(flags: int, data: bytes) -> bytes:
    return bytes([MsgType.DATA_SEGMENT << 4 | flags]) + sdnv(len(data)) + data


def ack_segment(length: int) -> bytes:
    return bytes([MsgType.ACK_SEGMENT << 4]) + sdnv(length)


def refuse_bundle(reason: int) -> bytes:
    return bytes([MsgType.REFUSE_BUNDLE << 4 | reason])


def keepalive() -> bytes:
    return bytes([MsgType.KEEPALIVE << 4])


def length_msg(total: int) -> bytes:
    return bytes([MsgType.LENGTH << 4]) + sdnv(total)


def shutdown(reason: int | None = None, delay_s: int | None = None) -> bytes:
    flags = (SHUT_REASON if reason is not None else 0) | (SHUT_DELAY if delay_s is not None else 0)
    out = bytes([MsgType.SHUTDOWN << 4 | flags])
    if reason is not None:
        out += bytes([reason])
    if delay_s is not None:
        out += sdnv(delay_s)
    return out


@dataclass
class Config:
    """One side of a TCPCLv3 session. ``accept(total_or_None)`` is the receive policy at a bundle's
    first segment (None: accept; a :class:`RefuseReason`: refuse, when refusal was negotiated)."""
    eid: str = "ipn:0.0"
    keepalive_s: int = 15
    acks: bool = True
    refusals: bool = True
    want_lengths: bool = False
    tx_segment: int = 64 * 1024
    max_bundle: int = 1 << 26
    accept: Callable[[int | None], RefuseReason | None] | None = None
    handshake_timeout_s: float = 10.0

    def flags(self) -> int:
        return (ACKS if self.acks else 0) | (REFUSALS if self.refusals else 0) | (LENGTHS if self.want_lengths else 0)


class Session:
    """One TCPCLv3 session over a connected stream."""

    def __init__(self, reader, writer, config: Config, active: bool,
                 on_bundle: Callable[[bytes, Session], None] | None = None):
        self._r, self._w, self.config, self.active, self.on_bundle = reader, writer, config, active, on_bundle
        peer = writer.get_extra_info("peername")
        self.peer = f"{peer[0]}:{peer[1]}" if peer else "?"
        self.counters: Counter[str] = Counter()
        self.peer_eid: str | None = None
        self.acks = self.refusals = self.send_lengths = False
        self.keepalive_s = 0
        self.shutdown_sent = self.shutdown_received = False
        self.shutdown_reason: int | None = None
        self.error: str | None = None
        self._tx_lock = asyncio.Lock()
        self._tx: tuple[int, asyncio.Future] | None = None  # (total, done) of the bundle in flight
        self._rx = bytearray()
        self._rx_open = False
        self._rx_refused = False
        self._rx_total: int | None = None
        self._closed = asyncio.get_running_loop().create_future()
        self._tasks: list[asyncio.Task] = []
        self._last_rx = self._last_tx = asyncio.get_running_loop().time()

    async def handshake(self) -> None:
        try:
            await asyncio.wait_for(self._handshake(), self.config.handshake_timeout_s)
        except TimeoutError:
            self._fail("no contact header within the handshake time-out")
            self._finish()
            raise ClError(f"TCPCLv3 {self.peer}: {self.error}") from None
        except ClError:
            self._finish()
            raise
        except (ConnectionError, asyncio.IncompleteReadError, OSError) as exc:
            self._fail(f"connection lost during the contact header ({type(exc).__name__})")
            self._finish()
            raise SessionTerminated(f"TCPCLv3 {self.peer}: {self.error}") from None

    async def _handshake(self) -> None:
        c = self.config
        self._write(contact_header(c.flags(), c.keepalive_s, c.eid))  # 4.1: both send at once
        head = await self._r.readexactly(8)
        if head[:4] != MAGIC:
            self._fail(f"bad contact header magic {head[:4]!r} (want b'dtn!')")
            raise ClError(f"TCPCLv3 {self.peer}: {self.error}")
        if head[4] != VERSION:
            await self._shutdown(ShutdownReason.VERSION_MISMATCH)
            self._fail(f"peer speaks TCPCL version {head[4]}, not {VERSION}")
            raise ClError(f"TCPCLv3 {self.peer}: {self.error}")
        flags, ka = head[5], struct.unpack(">H", head[6:8])[0]
        n = await read_sdnv(self._r)
        if n > 4096:
            await self._shutdown()
            self._fail(f"contact header EID of {n} bytes")
            raise ClError(f"TCPCLv3 {self.peer}: {self.error}")
        raw = await self._r.readexactly(n)
        try:
            self.peer_eid = raw.decode("utf-8")
        except UnicodeDecodeError:
            await self._shutdown()
            self._fail("contact header EID is not UTF-8")
            raise ClError(f"TCPCLv3 {self.peer}: {self.error}") from None
        self.keepalive_s = 0 if 0 in (ka, c.keepalive_s) else min(ka, c.keepalive_s)
        self.acks = c.acks and bool(flags & ACKS)
        self.refusals = self.acks and c.refusals and bool(flags & REFUSALS)
        self.send_lengths = bool(flags & LENGTHS)
        await self._w.drain()

    def start(self) -> None:
        self._tasks.append(asyncio.ensure_future(self._read_loop()))
        if self.keepalive_s:
            self._tasks.append(asyncio.ensure_future(self._keepalive_loop()))

    @property
    def closed(self) -> bool:
        return self._closed.done()

    async def wait_closed(self) -> None:
        await asyncio.shield(self._closed)

    async def send(self, data: bytes, timeout_s: float | None = None) -> None:
        """Send one bundle; with acknowledgments on, return when the peer acknowledged all of it."""
        if self.shutdown_sent or self.shutdown_received or self.closed:
            raise SessionTerminated(f"TCPCLv3 {self.peer}: session shut down, no new bundle")
        if not data:
            raise ClError(f"TCPCLv3 {self.peer}: an empty bundle")
        async with self._tx_lock:
            fut = asyncio.get_running_loop().create_future()
            self._tx = (len(data), fut)
            try:
                if self.send_lengths:
                    self._write(length_msg(len(data)))
                seg = self.config.tx_segment
                for off in range(0, len(data), seg):
                    chunk = data[off:off + seg]
                    flags = (SEG_START if off == 0 else 0) | (SEG_END if off + len(chunk) >= len(data) else 0)
                    self._write(data_segment(flags, chunk))
                    self.counters["segments_sent"] += 1
                    await self._w.drain()
                    if fut.done():
                        break
                if not self.acks and not fut.done():
                    fut.set_result(None)
                await asyncio.wait_for(asyncio.shield(fut), timeout_s)
            except (ConnectionError, OSError) as exc:
                self._fail(send_failure(exc, timeout_s))
                raise SessionTerminated(f"TCPCLv3 {self.peer}: {self.error}") from None
            finally:
                self._tx = None
            self.counters["bundles_sent"] += 1
            self.counters["bytes_sent"] += len(data)

    async def close(self, timeout_s: float = 5.0) -> None:
        """SHUTDOWN (no reason) and wait for the peer's answer or the connection's end (6.1)."""
        if not self.closed and not self.shutdown_sent:
            await self._shutdown(close=self.shutdown_received)
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(self.wait_closed(), timeout_s)
        self._finish()

    def abort(self) -> None:
        """Drop the connection at once, without SHUTDOWN: for a peer that no longer reads (a
        :meth:`close` whose SHUTDOWN cannot be written would wait on it)."""
        self._fail("connection lost: aborted by this side")
        with contextlib.suppress(Exception):
            self._w.transport.abort()
        self._finish()

    # ----- internals
    def _write(self, data: bytes) -> None:
        self._w.write(data)
        self._last_tx = asyncio.get_running_loop().time()

    def _fail(self, why: str) -> None:
        if self.error is None:
            self.error = why
        count_failure(self.counters, why)

    async def _shutdown(self, reason: int | None = None, close: bool = True) -> None:
        if not self.shutdown_sent:
            self.shutdown_sent = True
            with contextlib.suppress(ConnectionError, OSError):
                self._write(shutdown(reason))
                await self._w.drain()
        if close:
            self._finish()

    def _finish(self) -> None:
        for t in self._tasks:
            if t is not asyncio.current_task():
                t.cancel()
        if self._tx is not None and not self._tx[1].done():
            self._tx[1].set_exception(SessionTerminated(
                f"TCPCLv3 {self.peer}: session ended before the bundle was acknowledged"
                + (f" ({self.error})" if self.error else ""), self.shutdown_reason))
            self._tx[1].exception()
        with contextlib.suppress(Exception):
            self._w.close()
        if not self._closed.done():
            self._closed.set_result(None)

    async def _keepalive_loop(self) -> None:
        loop = asyncio.get_running_loop()
        ka = self.keepalive_s
        while not self.closed:
            await asyncio.sleep(min(ka / 4, 1.0))
            now = loop.time()
            if now - self._last_rx > 2 * ka:
                self._fail(f"nothing received for {now - self._last_rx:.1f} s (keepalive {ka} s)")
                await self._shutdown(ShutdownReason.IDLE_TIMEOUT)
                return
            if now - self._last_tx >= ka and not self.shutdown_sent:
                with contextlib.suppress(ConnectionError, OSError):
                    self._write(keepalive())
                    self.counters["keepalives_sent"] += 1

    async def _read_loop(self) -> None:
        try:
            while True:
                try:
                    head = (await self._r.readexactly(1))[0]
                except asyncio.IncompleteReadError:
                    if not (self.shutdown_sent or self.shutdown_received):
                        self._fail("connection lost: closed without SHUTDOWN")
                    break
                self._last_rx = asyncio.get_running_loop().time()
                if not await self._dispatch(head >> 4, head & 0x0F):
                    break
        except asyncio.IncompleteReadError as exc:
            self._fail(f"connection lost: message truncated ({len(exc.partial)} of {exc.expected} bytes)")
        except ClError as exc:
            self._fail(str(exc))
            await self._shutdown()
        except (ConnectionError, OSError) as exc:
            self._fail(f"connection lost: {type(exc).__name__}: {exc}")
        finally:
            if self._rx_open:
                self.counters["partial_bundles_discarded"] += 1
            self._finish()

    async def _dispatch(self, t: int, flags: int) -> bool:
        r = self._r
        if t == MsgType.DATA_SEGMENT:
            n = await read_sdnv(r)
            if n > self.config.max_bundle or len(self._rx) + n > self.config.max_bundle:
                self._fail(f"segment of {n} bytes over the bundle limit {self.config.max_bundle}")
                self.counters["oversize_segments"] += 1
                await self._shutdown()
                return False
            try:
                data = await r.readexactly(n)
            except asyncio.IncompleteReadError:
                self._rx_open = True  # counted as a discarded partial bundle at the session's end
                raise
            self.counters["segments_received"] += 1
            if flags & SEG_START:
                if self._rx_open:
                    self.counters["partial_bundles_discarded"] += 1
                self._rx, self._rx_open, self._rx_refused = bytearray(), True, False
                total = self._rx_total
                self._rx_total = None
                verdict = self.config.accept(total) if self.config.accept is not None else None
                if verdict is not None and self.refusals:
                    self._rx_refused = True
                    self.counters[f"refused_here.{RefuseReason(verdict).name.lower()}"] += 1
                    self._write(refuse_bundle(verdict))
            elif not self._rx_open:
                self._fail("a DATA_SEGMENT continuing no bundle")
                await self._shutdown()
                return False
            if self._rx_refused:
                if flags & SEG_END:
                    self._rx_open = False
                return True
            self._rx += data
            if flags & SEG_END:
                bundle = bytes(self._rx)
                self._rx, self._rx_open = bytearray(), False
                if self.on_bundle is not None:
                    try:
                        self.on_bundle(bundle, self)  # handed over before the final ACK leaves
                    except Exception as exc:  # noqa: BLE001 - the caller's store failed
                        self._fail(f"the receiver could not take a bundle ({exc})")
                        if self.refusals:
                            self._write(refuse_bundle(RefuseReason.NO_RESOURCES))
                        return True
                self.counters["bundles_received"] += 1
                self.counters["bytes_received"] += len(bundle)
                if self.acks:
                    self._write(ack_segment(len(bundle)))
            elif self.acks:
                self._write(ack_segment(len(self._rx)))
            return True
        if t == MsgType.ACK_SEGMENT:
            n = await read_sdnv(r)
            if self._tx is not None and n >= self._tx[0] and not self._tx[1].done():
                self._tx[1].set_result(None)
            return True
        if t == MsgType.REFUSE_BUNDLE:
            self.counters["refused_by_peer"] += 1
            if self._tx is not None and not self._tx[1].done():
                name = RefuseReason(flags).name if flags in RefuseReason.__members__.values() else str(flags)
                self._tx[1].set_exception(TransferRefused(f"TCPCLv3 {self.peer}: bundle refused ({name})", flags))
            return True
        if t == MsgType.KEEPALIVE:
            self.counters["keepalives_received"] += 1
            return True
        if t == MsgType.SHUTDOWN:
            if flags & SHUT_REASON:
                self.shutdown_reason = (await r.readexactly(1))[0]
            if flags & SHUT_DELAY:
                await read_sdnv(r)
            self.shutdown_received = True
            await self._shutdown()  # answer once, then close (6.1)
            return False
        if t == MsgType.LENGTH:
            self._rx_total = await read_sdnv(r)
            return True
        self._fail(f"unknown message type {t:#x}")
        self.counters["unknown_messages"] += 1
        await self._shutdown()
        return False


async def connect(host: str, port: int, config: Config,
                  on_bundle: Callable[[bytes, Session], None] | None = None) -> Session:
    try:
        reader, writer = await asyncio.wait_for(asyncio.open_connection(host, port), config.handshake_timeout_s)
    except (TimeoutError, OSError) as exc:
        raise ClError(f"TCPCLv3 {host}:{port}: cannot connect ({exc or 'time-out'})") from None
    s = Session(reader, writer, config, active=True, on_bundle=on_bundle)
    await s.handshake()
    s.start()
    return s


class Listener(_Listener):
    """Accepts TCPCLv3 sessions; a failed contact header is counted and closed, never raised."""

    session_cls = Session

    async def _end(self, session: Session) -> None:
        await session.close(timeout_s=1.0)


async def serve(host: str, port: int, config: Config, on_bundle=None, on_session=None) -> Listener:
    return await _start(Listener(config, on_bundle, on_session), host, port)
