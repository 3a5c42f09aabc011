"""UDP, one bundle per datagram as ION sends them: sat_node/dtn/cl/udp.py.

Oracle: plain sockets (the kernel's UDP) on 127.0.0.1 on the other side of each direction.
"""

from __future__ import annotations

import asyncio
import socket

import pytest

from sat_node.dtn.cl import ClError, udp

HOST = "127.0.0.1"


def test_send_to_plain_socket_and_plain_socket_to_listener():
    bundles = [bytes([i]) * (1 + 997 * i) for i in range(30)] + [b"m" * udp.MAX_DATAGRAM]

    async def main():
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4 << 20)
        sock.bind((HOST, 0))
        sock.settimeout(5)
        n = await udp.send(HOST, sock.getsockname()[1], bundles)
        plain = [sock.recv(65535) for _ in bundles]
        sock.close()
        got = []
        lst = await udp.serve(HOST, 0, lambda b, peer: got.append(b))
        out = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        for b in bundles + [b""]:
            out.sendto(b, (HOST, lst.port))
        out.close()
        for _ in range(100):
            if lst.counters["datagrams"] == len(bundles) + 1:
                break
            await asyncio.sleep(0.02)
        await lst.close()
        return n, plain, got, lst

    n, plain, got, lst = asyncio.run(main())
    assert n == len(bundles) and plain == bundles and got == bundles
    assert lst.counters["empty"] == 1 and lst.counters["bundles_received"] == len(bundles)


def test_bundle_over_one_datagram_refused_up_front():
    with pytest.raises(ClError, match="over one datagram"):
        asyncio.run(udp.send(HOST, 9, [b"ok", b"x" * (udp.MAX_DATAGRAM + 1)]))


def test_listener_survives_a_caller_that_fails():
    async def main():
        def take(b, peer):
            if b == b"bad":
                raise OSError("disk full")
        lst = await udp.serve(HOST, 0, take)
        await udp.send(HOST, lst.port, [b"bad", b"good"])
        for _ in range(100):
            if lst.counters["datagrams"] == 2:
                break
            await asyncio.sleep(0.02)
        await lst.close()
        return lst.counters
    c = asyncio.run(main())
    assert c["not_taken"] == 1 and c["bundles_received"] == 1
