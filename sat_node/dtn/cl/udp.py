"""UDP as ION's ``udp`` convergence layer speaks it: one bundle per datagram, nothing added.

ION 4.x (bpv7/udp: udpclo sends, udpcli receives) writes each bundle's bytes as one UDP datagram and
reads each datagram as one bundle; a bundle longer than its buffer (65535 bytes) is not sent. IPv4
caps a datagram's payload at 65507 bytes (RFC 791 total length 65535 minus the 20-byte IP and
8-byte UDP headers), so :func:`send` refuses a longer bundle up front with a one-line error. UDP
does not acknowledge: a datagram the receiver's socket buffer cannot hold is lost silently, as with
ION; ``gap_s`` spaces datagrams for a receiver that reads slowly. The receiver counts what it
drops: an empty datagram (``empty``) - a datagram is otherwise handed over as it came; deciding
whether it is a bundle is the bundle agent's business.

How we know it is right: datagrams sent by :func:`send` arrive byte-identical at :func:`serve` and
at a plain socket, and plain-socket datagrams arrive at :func:`serve` (tests/unit/test_cl_udp.py);
ION 4.1.3's udpcli delivers what :func:`send` sent and its udpclo's datagrams arrive here
(tests/interop/test_ion.py, marker ``interop``).
"""

from __future__ import annotations

import asyncio
import socket
from collections import Counter
from collections.abc import Callable, Iterable

from .errors import ClError

__all__ = ["MAX_DATAGRAM", "Listener", "send", "serve"]

MAX_DATAGRAM = 65507


async def send(host: str, port: int, bundles: Iterable[bytes], gap_s: float = 0.0) -> int:
    """Send each bundle as one datagram; return how many were sent."""
    items = list(bundles)
    for i, b in enumerate(items):
        if len(b) > MAX_DATAGRAM:
            raise ClError(f"UDP {host}:{port}: bundle {i} is {len(b)} bytes, over one datagram ({MAX_DATAGRAM})")
    loop = asyncio.get_running_loop()
    try:
        transport, _ = await loop.create_datagram_endpoint(asyncio.DatagramProtocol, remote_addr=(host, port),
                                                           family=socket.AF_INET)
    except OSError as exc:
        raise ClError(f"UDP {host}:{port}: {exc}") from None
    try:
        for b in items:
            transport.sendto(b)
            await asyncio.sleep(gap_s)
    finally:
        transport.close()
    return len(items)


class Listener(asyncio.DatagramProtocol):
    """Hands each datagram to ``on_bundle(data, peer)``; counts datagrams and drops."""

    def __init__(self, on_bundle: Callable[[bytes, str], None]):
        self.on_bundle = on_bundle
        self.counters: Counter[str] = Counter()
        self.transport: asyncio.DatagramTransport | None = None

    def connection_made(self, transport) -> None:
        self.transport = transport

    def datagram_received(self, data: bytes, addr) -> None:
        self.counters["datagrams"] += 1
        if not data:
            self.counters["empty"] += 1
            return
        try:
            self.on_bundle(data, f"{addr[0]}:{addr[1]}")
        except Exception:  # noqa: BLE001 - the caller failed to take it: counted, the listener lives on
            self.counters["not_taken"] += 1
            return
        self.counters["bundles_received"] += 1

    @property
    def port(self) -> int:
        return self.transport.get_extra_info("sockname")[1]

    async def close(self) -> None:
        if self.transport is not None:
            self.transport.close()


async def serve(host: str, port: int, on_bundle: Callable[[bytes, str], None],
                rcvbuf: int = 4 << 20) -> Listener:
    """Listen for datagrams (port 0: any free port, ``Listener.port`` says which)."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
        sock.bind((host, port))
    except OSError as exc:
        sock.close()
        raise ClError(f"UDP {host}:{port}: cannot listen ({exc})") from None
    _, proto = await asyncio.get_running_loop().create_datagram_endpoint(lambda: Listener(on_bundle), sock=sock)
    return proto
