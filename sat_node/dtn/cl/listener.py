"""The passive side both TCP convergence layers share: accept connections, run each one's session
handshake, keep the sessions, count what failed (never raise it), and close them all.

A layer subclasses :class:`Listener` with its ``Session`` class and how a session is ended (TCPCLv4:
SESS_TERM, RFC 9174 section 6.1; TCPCLv3: SHUTDOWN, RFC 7242 section 6.1). Checked through each
layer's tests (tests/unit/test_cl_tcpcl4.py, tests/unit/test_cl_tcpcl3.py: both roles, a failed
contact header counted).
"""

from __future__ import annotations

import asyncio
from collections import Counter

from .errors import ClError

__all__ = ["Listener", "start"]


class Listener:
    """Accepts sessions of ``session_cls``; a session that fails its handshake is counted and closed."""

    session_cls: type = type(None)

    def __init__(self, config, on_bundle=None, on_session=None):
        self.config, self.on_bundle, self.on_session = config, on_bundle, on_session
        self.sessions: list = []
        self.counters: Counter[str] = Counter()
        self.server: asyncio.Server | None = None

    async def _accept(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        s = self.session_cls(reader, writer, self.config, active=False, on_bundle=self.on_bundle)
        self.sessions.append(s)
        self.counters["connections"] += 1
        try:
            await s.handshake()
        except ClError:
            self.counters["handshakes_failed"] += 1
            return
        self.counters["sessions"] += 1
        if self.on_session is not None:
            self.on_session(s)
        s.start()

    @property
    def port(self) -> int:
        return self.server.sockets[0].getsockname()[1]

    async def _end(self, session) -> None:
        """End one open session (the layer's own way)."""
        raise NotImplementedError

    async def close(self) -> None:
        if self.server is not None:
            self.server.close()
            await self.server.wait_closed()
        for s in self.sessions:
            if not s.closed:
                await self._end(s)


async def start(listener: Listener, host: str, port: int) -> Listener:
    """``listener`` listening on host:port (port 0: any free port, ``Listener.port`` says which)."""
    listener.server = await asyncio.start_server(listener._accept, host, port)
    return listener
