"""``constellation bundles send|listen``: exchange BPv7 bundle files with another DTN node over a real
convergence layer (sat_node/dtn/cl: TCPCLv4, TCPCLv3, UDP).

* ``send --cl tcpcl4|tcpcl3|udp --to HOST:PORT FILES...``: one session (TCPCL) or one socket (UDP),
  each file one bundle, in the order given; a line per bundle. Every file is read and decoded as a
  BPv7 bundle before anything is sent (``--no-check`` sends any bytes): a missing or malformed file
  is refused up front, one line naming it, exit 2. A bundle the peer refuses is named on its line
  and the command exits 1.
* ``listen --cl ... --at HOST:PORT --out DIR``: accepts sessions (or datagrams) until ``--count``
  bundles arrived, ``--duration`` passed or SIGINT/SIGTERM; the first line names the address it
  listens on (port 0: a free port); each received bundle is decoded, written to
  ``DIR/<n>.bpv7`` (before its last acknowledgment leaves: a bundle the sender saw acknowledged is
  on disk) and printed as a line; one that does not decode is rejected and counted, never written.

Checked by tests/unit/test_cli_bundles.py (every layer on loopback: files byte-identical, the
lines, refusals up front, malformed bundles counted).
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import os
import signal
import ssl
import sys
from datetime import UTC, datetime, timedelta
from pathlib import Path

from bringup.errors import UserError
from sat_node.dtn.bpv7 import Bundle, BundleError, decode_bundle, eid_text
from sat_node.dtn.cl import ClError, TransferRefused, tcpcl3, tcpcl4, udp

LAYERS = ("tcpcl4", "tcpcl3", "udp")
_DTN_EPOCH = datetime(2000, 1, 1, tzinfo=UTC)


def add_arguments(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="action", metavar="ACTION", required=True,
                           help="send: bundle files to a peer in one session; listen: accept sessions, save bundles")
    s = sub.add_parser("send", help="send bundle files to a DTN node (one session, each file one bundle)")
    s.add_argument("--cl", choices=LAYERS, required=True, help="convergence layer")
    s.add_argument("--to", required=True, metavar="HOST:PORT", help="the peer's address")
    s.add_argument("files", nargs="+", type=Path, metavar="FILE", help="BPv7 bundle files (.bpv7)")
    s.add_argument("--no-check", action="store_true", help="send the files without decoding them first")
    _common(s)
    lp = sub.add_parser("listen", help="receive bundles from DTN nodes into a folder, a line per bundle")
    lp.add_argument("--cl", choices=LAYERS, required=True, help="convergence layer")
    lp.add_argument("--at", required=True, metavar="HOST:PORT", help="address to listen on (port 0: any free one)")
    lp.add_argument("--out", type=Path, required=True, metavar="DIR", help="folder for the received bundles")
    lp.add_argument("--count", type=int, default=None, help="stop after this many bundles")
    lp.add_argument("--duration", type=float, default=None, metavar="S", help="stop after S seconds")
    _common(lp)


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--node-id", default="ipn:0.0",
                   help="this node's ID in the TCPCL contact header / SESS_INIT (default ipn:0.0)")
    p.add_argument("--keepalive", type=int, default=15, metavar="S", help="TCPCL keepalive interval [s] (default 15)")
    p.add_argument("--segment", type=int, default=64 * 1024, metavar="BYTES",
                   help="TCPCL segment size sent (v3) / segment MRU offered (v4) (default 65536)")
    p.add_argument("--tls-cert", type=Path, default=None, help="TCPCLv4: this node's TLS certificate (PEM)")
    p.add_argument("--tls-key", type=Path, default=None, help="TCPCLv4: its private key (PEM)")
    p.add_argument("--tls-ca", type=Path, default=None, help="TCPCLv4: CA certificates to trust (PEM)")
    p.add_argument("--timeout", type=float, default=30.0, metavar="S",
                   help="seconds to wait for a session or an acknowledgment (default 30)")


def host_port(text: str, flag: str) -> tuple[str, int]:
    host, sep, port = text.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 <= int(port) <= 65535:
        raise UserError(f"{flag} {text!r}: expected HOST:PORT (port 0-65535)")
    return host.strip("[]"), int(port)


def describe(b: Bundle) -> str:
    created = (_DTN_EPOCH + timedelta(milliseconds=b.creation_ms)).strftime("%Y-%m-%dT%H:%M:%S.%fZ")
    return (f"{eid_text(b.src)} -> {eid_text(b.dest)} created {created[:-4]}Z seq {b.seq} "
            f"lifetime {b.lifetime_ms / 1000:g} s payload {len(b.payload)} B")


def _ssl_context(args, server: bool) -> ssl.SSLContext | None:
    if args.tls_cert is None and args.tls_ca is None:
        return None
    if args.cl != "tcpcl4":
        raise UserError(f"--tls-*: TLS is a TCPCLv4 option, not {args.cl}")
    try:
        ctx = ssl.create_default_context(ssl.Purpose.CLIENT_AUTH if server else ssl.Purpose.SERVER_AUTH,
                                         cafile=str(args.tls_ca) if args.tls_ca else None)
        if args.tls_cert is not None:
            ctx.load_cert_chain(args.tls_cert, args.tls_key)
    except (OSError, ssl.SSLError) as exc:
        raise UserError(f"--tls-cert/--tls-key/--tls-ca: {exc}") from None
    ctx.check_hostname = False
    return ctx


def _config(args, server: bool):
    if args.cl == "tcpcl4":
        return tcpcl4.Config(node_id=args.node_id, keepalive_s=args.keepalive, segment_mru=args.segment,
                             ssl_context=_ssl_context(args, server), handshake_timeout_s=args.timeout)
    _ssl_context(args, server)
    return tcpcl3.Config(eid=args.node_id, keepalive_s=args.keepalive, tx_segment=args.segment,
                         handshake_timeout_s=args.timeout)


def run(args: argparse.Namespace) -> int:
    if args.keepalive < 0 or args.keepalive > 0xFFFF:
        raise UserError(f"--keepalive {args.keepalive}: must be 0..65535")
    if args.segment < 1:
        raise UserError(f"--segment {args.segment}: must be at least 1")
    return _send(args) if args.action == "send" else _listen(args)


# --- send --------------------------------------------------------------------------------------

def _read_bundles(args) -> list[tuple[Path, bytes, str]]:
    out = []
    for f in args.files:
        try:
            data = f.read_bytes()
        except OSError as exc:
            raise UserError(f"{f}: cannot read ({exc.strerror or exc})") from None
        if not data:
            raise UserError(f"{f}: empty file, not a bundle")
        what = f"{len(data)} B"
        if not args.no_check:
            try:
                what = describe(decode_bundle(data))
            except BundleError as exc:
                raise UserError(f"{f}: not a BPv7 bundle: {exc}") from None
        out.append((f, data, what))
    return out


def _send(args) -> int:
    host, port = host_port(args.to, "--to")
    items = _read_bundles(args)
    return asyncio.run(_send_async(args, host, port, items))


async def _send_async(args, host, port, items) -> int:
    if args.cl == "udp":
        try:
            await udp.send(host, port, [d for _, d, _ in items], gap_s=0.001)
        except ClError as exc:
            raise UserError(str(exc)) from None
        for f, data, what in items:
            print(f"sent {f} ({len(data)} B) over udp to {host}:{port}: {what}")
        print(f"{len(items)} bundles sent (UDP: no acknowledgment)")
        return 0
    mod = tcpcl4 if args.cl == "tcpcl4" else tcpcl3
    try:
        session = await mod.connect(host, port, _config(args, server=False))
    except ClError as exc:
        raise UserError(str(exc)) from None
    refused = sent = 0
    try:
        for f, data, what in items:
            try:
                await session.send(data, timeout_s=args.timeout)
            except TransferRefused as exc:
                refused += 1
                print(f"refused {f}: {exc}")
                continue
            except TimeoutError:
                raise UserError(f"{args.cl} {host}:{port}: no acknowledgment of {f} within {args.timeout} s") \
                    from None
            except ClError as exc:
                raise UserError(f"{exc} (sending {f}; {sent} bundles acknowledged before it)") from None
            sent += 1
            print(f"sent {f} ({len(data)} B) over {args.cl} to {host}:{port}: {what}", flush=True)
    finally:
        if args.cl == "tcpcl4":
            await session.terminate(timeout_s=args.timeout)
        else:
            await session.close(timeout_s=args.timeout)
    print(f"{sent} bundles sent and acknowledged" + (f", {refused} refused" if refused else ""))
    return 1 if refused else 0


# --- listen ------------------------------------------------------------------------------------

class _Sink:
    """Writes each decodable bundle to DIR/<n>.bpv7 (atomically) and prints its line."""

    def __init__(self, out: Path, count: int | None, done: asyncio.Event):
        self.out, self.count, self.done = out, count, done
        self.n = self.rejected = 0

    def take(self, data: bytes, peer: str) -> None:
        try:
            what = describe(decode_bundle(data))
        except BundleError as exc:
            self.rejected += 1
            print(f"rejected {len(data)} B from {peer}: not a BPv7 bundle: {exc}", flush=True)
            return
        self.n += 1
        path = self.out / f"{self.n:06d}.bpv7"
        tmp = path.with_suffix(".part")
        tmp.write_bytes(data)
        os.replace(tmp, path)
        print(f"received {path} ({len(data)} B) from {peer}: {what}", flush=True)
        if self.count is not None and self.n >= self.count:
            self.done.set()


def _listen(args) -> int:
    host, port = host_port(args.at, "--at")
    if args.count is not None and args.count < 1:
        raise UserError(f"--count {args.count}: must be at least 1")
    if args.out.exists() and not args.out.is_dir():
        raise UserError(f"--out {args.out}: is a file, not a folder")
    args.out.mkdir(parents=True, exist_ok=True)
    return asyncio.run(_listen_async(args, host, port))


async def _listen_async(args, host, port) -> int:
    done = asyncio.Event()
    sink = _Sink(args.out, args.count, done)
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        with contextlib.suppress(NotImplementedError, RuntimeError):
            loop.add_signal_handler(sig, done.set)
    try:
        if args.cl == "udp":
            lst = await udp.serve(host, port, sink.take)
        else:
            mod = tcpcl4 if args.cl == "tcpcl4" else tcpcl3
            lst = await mod.serve(host, port, _config(args, server=True), on_bundle=lambda b, s: sink.take(b, s.peer))
    except ClError as exc:
        raise UserError(str(exc)) from None
    except OSError as exc:
        raise UserError(f"--at {host}:{port}: cannot listen ({exc.strerror or exc})") from None
    print(f"listening on {args.cl}://{host}:{lst.port}, writing to {args.out}", flush=True)
    try:
        await asyncio.wait_for(done.wait(), args.duration)
    except TimeoutError:
        pass
    await lst.close()
    sessions = getattr(lst, "sessions", [])
    errors = [s.error for s in sessions if s.error and not s.error.startswith("connection lost: closed")]
    for e in errors:
        print(f"session error: {e}", file=sys.stderr)
    print(f"{sink.n} bundles received" + (f", {sink.rejected} rejected (not BPv7)" if sink.rejected else ""))
    return 0
