"""The ground gateway: the ground segment's bundle agent (ground_station/ground_agent.py) exchanges
bundles with one terrestrial DTN node over a real convergence layer (sat_node/dtn/cl).

``constellation run ... --ground-gateway URL``, with URL one of::

    tcpcl4://HOST:PORT?node=N[&listen=HOST:PORT][&foreign=accept|refuse]   TCPCLv4, RFC 9174
    tcpcl3://HOST:PORT?node=N[&listen=HOST:PORT][&foreign=accept|refuse]   TCPCLv3, RFC 7242 (ION's tcp)
    udp://HOST:PORT?node=N[&listen=HOST:PORT][&foreign=accept|refuse]      one bundle per datagram (ION's udp)

* ``HOST:PORT``: the peer's induct. The ground is the active side: it opens one session (node ID
  ``ipn:100.0``) when the run starts - a peer it cannot reach stops the run before it starts, one
  line - and opens it again when it is lost (see "Delivery to the peer").
* ``node=N``: the peer's ipn node number. It is routed through the ground (the ground agent's graph
  has a contact to it for the whole run), and the satellites address their downlinked observations
  to ``ipn:N.1`` (sat_node/dtn/downlink.py): the ground forwards every downlink to the peer.
* ``listen=HOST:PORT``: the ground also accepts sessions (TCPCL) or datagrams (UDP) there, for a
  peer that sends on its own outduct (ION does: its plan for node 100 names an outduct). Over TCPCL
  the peer may also send on the ground's session.
* ``foreign``: the policy for bundles from the peer that lack the constellation's BIB and
  recipients block (sat_node/dtn/rx_policy.py): ``accept`` (the default: ordinary unicast bundles
  to their ``ipn`` destination) or ``refuse``. A BIB is checked whenever present: one that fails
  drops the bundle. Every decision is counted per reason in the run's gateway.json.

Delivery to the peer: a bundle stays in the ground's store until the peer acknowledged all of it
(TCPCLv4 XFER_ACK, TCPCLv3 ACK_SEGMENT), and the bundles go one at a time, in submit order. A send that
fails - the session ended or lost, the connection refused, or the bundle not sent and acknowledged
within :data:`ACK_S` s (a peer that stopped reading keeps the TCP connection open: only this bound
notices it) - counts ``send_failed``; the session is ended (SESS_TERM / SHUTDOWN, bounded by
:data:`END_S` s, then dropped), and after a backoff (:data:`RECONNECT_S` s, doubled at each failure in a
row up to :data:`RECONNECT_MAX_S` s, back to the start after a bundle is acknowledged) a new session is
opened (``reconnects``) and every bundle not yet acknowledged is sent again, from the oldest. No bundle
is lost; a bundle whose acknowledgment was lost (the peer had all of it when the session ended) is sent
again, so the peer gets it twice (no custody transfer: it delivers both). A refusal is a failed send
when its reason asks for the bundle again (TCPCLv4 "retransmit" or "session terminating", which a peer
ending its session sends for the transfer in flight; TCPCLv3 "retransmit"), a delivery when it is
"completed", and otherwise final: the bundle is dropped from the queue (``refused``) and stays in the
ground's store. A session lost while there is nothing to send is opened again with the next bundle. UDP
acknowledges nothing: a datagram is counted sent when it left (``unacknowledged``), and one the peer did
not take is lost. At the run's end the ground waits up to :data:`FLUSH_S` s for the last
acknowledgments; what is still unacknowledged stays in the store and is counted.

The sessions run in an asyncio loop on a thread of their own; the ground's lockstep steps hand it
bundles (:meth:`Gateway.submit`) and take what it received and what the peer acknowledged
(:meth:`Gateway.take_received`, :meth:`Gateway.take_acks`), so the lockstep contract is kept: the
peer's bundles enter the run at the ground step after they arrived.

How we know it is right: tests/unit/test_gateway.py (URL forms and their one-line errors; a
session to the project's own listener: every bundle arrives byte-identical, acknowledged bundles
only leave the store, a lost session is opened again and the unacknowledged bundles sent again;
a peer lost mid-stream and a session that stops acknowledging (small bundles, and one that fills the
socket buffers): every bundle arrives, duplicates only across the loss, within the flush;
bundles from the peer taken in); tests/system/test_ground_gateway.py (a centralized run whose
downlinks reach ``bundles listen`` and whose peer bundles reach the named satellite);
tests/interop/test_ground_gateway_ion.py (ION 4.1.3 over TCPCLv3 and UDP) and
tests/interop/test_ground_gateway_tcpcl4.py (the RFC 9174 author's agent over TCPCLv4).
"""

from __future__ import annotations

import asyncio
import contextlib
import hashlib
import queue
import threading
import time
from collections import Counter, deque
from dataclasses import dataclass
from urllib.parse import parse_qs, urlsplit

from sat_node.dtn.cl import ClError, TransferRefused, tcpcl3, tcpcl4, udp
from sat_node.dtn.downlink import GROUND_NODE
from sat_node.dtn.rx_policy import FOREIGN_POLICIES

__all__ = ["ACK_S", "FLUSH_S", "LAYERS", "RECONNECT_S", "Gateway", "GatewaySpec", "parse_gateway"]

LAYERS = ("tcpcl4", "tcpcl3", "udp")
RECONNECT_S = 1.0  # the first wait after a failed send
RECONNECT_MAX_S = 8.0  # the backoff doubles up to this
ACK_S = 10.0  # a bundle not acknowledged within this: the session is taken as lost
END_S = 3.0  # ending a failed session: past this it is dropped without its SESS_TERM / SHUTDOWN
FLUSH_S = 30.0  # > ACK_S + RECONNECT_MAX_S + CONNECT_S: a stalled session is replaced within the flush
CONNECT_S = 10.0
# XFER_REFUSE / REFUSE_BUNDLE reasons (RFC 9174 5.2.4 table 8, RFC 7242 5.4 table 3): "completed" is
# a delivery; "retransmit" and "session terminating" ask for the bundle again (a failed send: kept,
# sent again on the next session); any other drops the bundle from the gateway's queue
_COMPLETED = 1
_RETRY = {"tcpcl4": frozenset({tcpcl4.RefuseReason.RETRANSMIT, tcpcl4.RefuseReason.SESSION_TERMINATING}),
          "tcpcl3": frozenset({tcpcl3.RefuseReason.RETRANSMIT}), "udp": frozenset()}
POLL_S = 10.0  # scenario seconds between the ground's looks at the gateway
_NS = 1_000_000_000


@dataclass(frozen=True)
class GatewaySpec:
    cl: str
    host: str
    port: int
    node: int
    listen: tuple[str, int] | None = None
    foreign: str = "accept"

    @property
    def url(self) -> str:
        q = f"?node={self.node}" + (f"&listen={self.listen[0]}:{self.listen[1]}" if self.listen else "")
        return f"{self.cl}://{self.host}:{self.port}{q}&foreign={self.foreign}"


def _host_port(text: str, what: str) -> tuple[str, int]:
    host, sep, port = text.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 < int(port) <= 65535:
        raise ValueError(f"{what} {text!r}: expected HOST:PORT (port 1-65535)")
    return host.strip("[]"), int(port)


def parse_gateway(url: str) -> GatewaySpec:
    """The gateway a URL names; ValueError (one line, naming the part) when it is not one."""
    u = urlsplit(url)
    if u.scheme not in LAYERS:
        raise ValueError(f"ground gateway {url!r}: the scheme must be one of {', '.join(LAYERS)} "
                         "(e.g. tcpcl4://127.0.0.1:4556?node=2)")
    if u.path not in ("", "/") or u.fragment:
        raise ValueError(f"ground gateway {url!r}: nothing may follow HOST:PORT but ?node=N&...")
    host, port = _host_port(u.netloc, f"ground gateway {url!r}: address")
    try:
        q = parse_qs(u.query, keep_blank_values=True, strict_parsing=bool(u.query))
    except ValueError:
        raise ValueError(f"ground gateway {url!r}: the query must be name=value pairs joined by &") from None
    unknown = sorted(set(q) - {"node", "listen", "foreign"})
    if unknown:
        raise ValueError(f"ground gateway {url!r}: unknown parameter {unknown[0]!r} (node, listen, foreign)")
    for k, v in q.items():
        if len(v) > 1:
            raise ValueError(f"ground gateway {url!r}: {k} given {len(v)} times")
    node_s = q.get("node", [""])[0]
    if not node_s.isdigit() or not 0 < int(node_s) < 1 << 63:
        raise ValueError(f"ground gateway {url!r}: node=N, the peer's ipn node number (1..2^63-1), "
                         "is required")
    node = int(node_s)
    if node == GROUND_NODE:
        raise ValueError(f"ground gateway {url!r}: node {node} is the ground segment's own node")
    listen = _host_port(q["listen"][0], f"ground gateway {url!r}: listen") if "listen" in q else None
    foreign = q.get("foreign", ["accept"])[0]
    if foreign not in FOREIGN_POLICIES:
        raise ValueError(f"ground gateway {url!r}: foreign={foreign!r}: one of {', '.join(FOREIGN_POLICIES)}")
    return GatewaySpec(u.scheme, host, port, node, listen, foreign)


class Gateway:
    """The convergence-layer side of the gateway (see the module docstring): :meth:`start` it (one
    line ``ClError`` when the peer cannot be reached), :meth:`submit` bundles, take what arrived,
    :meth:`close` it."""

    def __init__(self, spec: GatewaySpec, *, poll_s: float = POLL_S, flush_s: float = FLUSH_S,
                 reconnect_s: float = RECONNECT_S, reconnect_max_s: float = RECONNECT_MAX_S,
                 ack_s: float = ACK_S):
        self.spec = spec
        self.poll_ns = int(poll_s * _NS)
        self.flush_s, self.ack_s = flush_s, ack_s
        self.reconnect_s, self.reconnect_max_s = reconnect_s, max(reconnect_s, reconnect_max_s)
        self.last_error: str | None = None
        self.node_id = f"ipn:{GROUND_NODE}.0"
        self.counters: Counter[str] = Counter()
        self.sent: list[tuple[str, int, str]] = []  # (bundle id, bytes, SHA-256) in the order taken
        self._received: queue.SimpleQueue = queue.SimpleQueue()
        self._acks: queue.SimpleQueue = queue.SimpleQueue()
        self._pending: deque = deque()  # (bundle id, bytes) not yet acknowledged, in submit order
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._session = None
        self._listener = None
        self._wake: asyncio.Event | None = None
        self._stop = False
        self._sender: asyncio.Task | None = None
        self.t_first_send: float | None = None
        self.t_last_ack: float | None = None

    # ------------------------------------------------------------------ the ground's side (its thread)
    def start(self) -> Gateway:
        ready: queue.SimpleQueue = queue.SimpleQueue()
        self._thread = threading.Thread(target=self._run, args=(ready,), name="ground-gateway", daemon=True)
        self._thread.start()
        err = ready.get()
        if err is not None:
            self._thread.join(timeout=5)
            raise err
        return self

    def submit(self, bundle_id: str, data: bytes) -> None:
        self._loop.call_soon_threadsafe(self._add, bundle_id, data)

    def take_received(self) -> list[bytes]:
        return _drain(self._received)

    def take_acks(self) -> list[str]:
        return _drain(self._acks)

    def flush(self) -> None:
        """Wait (up to the flush time) until every submitted bundle was acknowledged or sent."""
        fut = asyncio.run_coroutine_threadsafe(self._flush(), self._loop)
        fut.result(timeout=self.flush_s + 5)

    def close(self) -> None:
        if self._loop is None or self._thread is None:
            return
        if self._thread.is_alive():
            with contextlib.suppress(Exception):
                asyncio.run_coroutine_threadsafe(self._close(), self._loop).result(timeout=15)
            self._loop.call_soon_threadsafe(self._loop.stop)
            self._thread.join(timeout=10)

    def report(self) -> dict:
        out = {"url": self.spec.url, "cl": self.spec.cl, "peer_node": f"ipn:{self.spec.node}",
               "acknowledged": self.spec.cl != "udp", "counters": dict(sorted(self.counters.items())),
               "pending": len(self._pending), "last_error": self.last_error,
               "sent": [{"bundle": b, "bytes": n, "sha256": h} for b, n, h in self.sent]}
        if self.t_first_send is not None and self.t_last_ack is not None:
            out["send_wall_s"] = round(self.t_last_ack - self.t_first_send, 3)
        return out

    # ------------------------------------------------------------------ the loop's side
    def _run(self, ready: queue.SimpleQueue) -> None:
        loop = self._loop = asyncio.new_event_loop()
        asyncio.set_event_loop(loop)
        try:
            loop.run_until_complete(self._open())
        except ClError as exc:
            ready.put(exc)
            loop.close()
            return
        ready.put(None)
        self._sender = loop.create_task(self._send_loop())
        try:
            loop.run_forever()
        finally:
            loop.close()

    async def _open(self) -> None:
        self._wake = asyncio.Event()
        s = self.spec
        if s.listen is not None:
            lh, lp = s.listen
            if s.cl == "udp":
                self._listener = await udp.serve(lh, lp, self._on_datagram)
            else:
                mod = tcpcl4 if s.cl == "tcpcl4" else tcpcl3
                self._listener = await mod.serve(lh, lp, self._config(), on_bundle=self._on_bundle)
        if s.cl == "udp":
            await self._udp_check()
        else:
            self._session = await self._connect()

    def _config(self):
        if self.spec.cl == "tcpcl4":
            return tcpcl4.Config(node_id=self.node_id, handshake_timeout_s=CONNECT_S)
        return tcpcl3.Config(eid=self.node_id, handshake_timeout_s=CONNECT_S)

    async def _connect(self):
        mod = tcpcl4 if self.spec.cl == "tcpcl4" else tcpcl3
        s = await mod.connect(self.spec.host, self.spec.port, self._config(), on_bundle=self._on_bundle)
        self.counters["sessions_opened"] += 1
        return s

    async def _udp_check(self) -> None:
        """UDP has no session: the peer's address is checked to be one this host can send to."""
        try:
            await udp.send(self.spec.host, self.spec.port, [])
        except ClError as exc:
            raise ClError(f"UDP {self.spec.host}:{self.spec.port}: {exc}") from None

    def _on_bundle(self, data: bytes, _session) -> None:
        self.counters["received"] += 1
        self.counters["bytes_received"] += len(data)
        self._received.put(bytes(data))

    def _on_datagram(self, data: bytes, _peer: str) -> None:
        self._on_bundle(data, None)

    def _add(self, bundle_id: str, data: bytes) -> None:
        self._pending.append((bundle_id, data))
        self._wake.set()

    async def _send_loop(self) -> None:
        backoff = self.reconnect_s
        while not self._stop:
            if not self._pending:
                self._wake.clear()
                await self._wake.wait()
                continue
            bid, data = self._pending[0]
            failed = None
            if self.t_first_send is None:
                self.t_first_send = time.monotonic()
            try:
                if self.spec.cl == "udp":
                    await udp.send(self.spec.host, self.spec.port, [data])
                    self.counters["unacknowledged"] += 1
                else:
                    if self._session is None or self._session.closed:
                        await self._drop_session()
                        self._session = await self._connect()
                        self.counters["reconnects"] += 1
                    # the whole transfer is bounded: a peer that stops reading blocks its writes too
                    await asyncio.wait_for(self._session.send(data, timeout_s=self.ack_s), self.ack_s)
                    self.counters["acknowledged"] += 1
            except TransferRefused as exc:
                self.counters[f"refused.reason_{exc.reason}"] += 1
                if exc.reason == _COMPLETED:  # the peer already has all of it: delivered
                    self.counters["acknowledged"] += 1
                elif exc.reason in _RETRY[self.spec.cl]:
                    failed = exc
                else:
                    self.counters["refused"] += 1
                    self._pending.popleft()  # the peer will not take it: it stays in the ground's store
                    continue
            except Exception as exc:  # noqa: BLE001 - whatever failed, the sender goes on: the bundle stays
                failed = exc
            if failed is not None:
                self.counters["send_failed"] += 1
                self.last_error = (f"no acknowledgement within {self.ack_s} s"
                                   if isinstance(failed, TimeoutError) and not str(failed)
                                   else f"{type(failed).__name__}: {failed}".splitlines()[0])
                await self._drop_session()
                await asyncio.sleep(backoff)
                backoff = min(2 * backoff, self.reconnect_max_s)
                continue
            backoff = self.reconnect_s
            self._pending.popleft()
            self.counters["sent"] += 1
            self.counters["bytes_sent"] += len(data)
            self.sent.append((bid, len(data), hashlib.sha256(data).hexdigest()))
            self.t_last_ack = time.monotonic()
            self._acks.put(bid)

    async def _flush(self) -> None:
        deadline = time.monotonic() + self.flush_s
        while self._pending and time.monotonic() < deadline:
            await asyncio.sleep(0.05)

    async def _end(self, session) -> None:
        if self.spec.cl == "tcpcl4":
            await session.terminate(timeout_s=2.0)
        else:
            await session.close(timeout_s=2.0)

    async def _drop_session(self) -> None:
        """End the session, if open; one whose end does not finish in END_S s (a peer that does not
        read: the SESS_TERM / SHUTDOWN cannot be written) is aborted."""
        s, self._session = self._session, None
        if s is None or s.closed:
            return
        try:
            await asyncio.wait_for(self._end(s), END_S)
        except Exception:  # noqa: BLE001 - time-out or a failed end: drop the connection
            self.counters["sessions_aborted"] += 1
            s.abort()

    async def _close(self) -> None:
        self._stop = True
        if self._sender is not None:
            self._sender.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await self._sender
        await self._drop_session()
        if self._listener is not None:
            with contextlib.suppress(Exception):
                await self._listener.close()


def _drain(q: queue.SimpleQueue) -> list:
    out = []
    while True:
        try:
            out.append(q.get_nowait())
        except queue.Empty:
            return out
