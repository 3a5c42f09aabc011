"""Network impairment of a container's interface: per-packet delay, jitter and loss (and rate).

What ``tc qdisc add dev eth0 root netem delay 50ms 10ms loss 1%`` does on a container's interface,
for kernels built without netem. This project's machines run such a kernel: ``tc ... netem`` fails
with "Error: Specified qdisc kind is unknown." and the kernel config (``/proc/config.gz``) has
``# CONFIG_NET_SCH_NETEM is not set`` and ``# CONFIG_MODULES is not set`` (no module can be
loaded). What the kernel does have is netfilter's NFQUEUE target (``CONFIG_NETFILTER_XT_TARGET_NFQUEUE``,
``CONFIG_NETFILTER_NETLINK_QUEUE``) and the ``tbf`` qdisc. So, inside the container's network
namespace:

* an iptables rule ``OUTPUT -o eth0 -j NFQUEUE --queue-num Q`` hands every packet the container
  sends on its interface to this process (the kernel holds the packet itself);
* this process draws, per packet, a loss (probability ``loss``: verdict DROP at once) or a delay
  ``delay +- jitter`` (uniform, as netem's default), and gives the kernel the verdict ACCEPT when the
  delay has passed; packets then leave in due-time order, so jitter reorders them, as with netem;
* ``rate`` (optional) adds a ``tbf`` qdisc on the interface (a real kernel token bucket).

The DDS traffic between containers really is delayed and lost on the wire: a reliable DDS writer
sees the losses and repairs them (heartbeats, NACKs), the lockstep barrier waits longer. The
protocol is nfnetlink_queue's (linux/netfilter/nfnetlink_queue.h), spoken over a raw
``NETLINK_NETFILTER`` socket; the rule uses ``iptables-legacy`` (``iptables-nft`` would translate the
target into nftables' ``queue``, which this kernel lacks: ``CONFIG_NFT_QUEUE`` is not set).

Run as ``nsenter --net=/proc/PID/ns/net python -m bringup.deploy.impair --delay-ms 50 ...`` (the
container driver, bringup/deploy/containers.py, starts one per container); SIGTERM removes the rule
and the qdisc, and the last line on stdout is a JSON record of what was done (packets seen,
dropped, mean delay, receive-buffer overruns).

Oracle: tests/containers/test_impair.py measures, between two containers on an internal network, the
UDP round-trip time (about 2x the delay, spread by the jitter) and the loss rate over many datagrams
against the configured figures, and checks that the rule and the queue are gone afterwards.
"""

from __future__ import annotations

import argparse
import errno
import heapq
import json
import os
import random
import re
import select
import signal
import socket
import struct
import subprocess
import sys
import time
from dataclasses import dataclass

__all__ = ["Impairment", "NfQueue", "main", "parse_impairment"]

NETLINK_NETFILTER = 12
NFNL_SUBSYS_QUEUE = 3
NFQNL_MSG_PACKET, NFQNL_MSG_VERDICT, NFQNL_MSG_CONFIG = 0, 1, 2
NFQA_PACKET_HDR, NFQA_VERDICT_HDR = 1, 2
NFQA_CFG_CMD, NFQA_CFG_PARAMS, NFQA_CFG_QUEUE_MAXLEN = 1, 2, 3
NFQNL_CFG_CMD_BIND, NFQNL_CFG_CMD_UNBIND = 1, 2
NFQNL_COPY_META = 1
NLM_F_REQUEST, NLM_F_ACK = 1, 4
NLMSG_ERROR, NLMSG_DONE = 2, 3
NF_DROP, NF_ACCEPT = 0, 1
_NLMSGHDR = struct.Struct("=IHHII")
_NLATTR = struct.Struct("=HH")


@dataclass(frozen=True)
class Impairment:
    """netem's figures: one-way delay and its jitter [s] (uniform), loss probability, rate [bit/s]."""

    delay_s: float = 0.0
    jitter_s: float = 0.0
    loss: float = 0.0
    rate_bps: int | None = None

    def args(self) -> list[str]:
        """Command-line arguments of :func:`main` for these figures."""
        a = ["--delay-ms", f"{self.delay_s * 1e3:g}", "--jitter-ms", f"{self.jitter_s * 1e3:g}",
             "--loss", f"{self.loss:g}"]
        return a + (["--rate-bit", str(self.rate_bps)] if self.rate_bps else [])

    def __str__(self) -> str:
        s = f"delay {self.delay_s * 1e3:g} ms +- {self.jitter_s * 1e3:g} ms, loss {self.loss * 100:g} %"
        return s + (f", rate {self.rate_bps / 1e6:g} Mbit/s" if self.rate_bps else "")


_UNITS_S = {"us": 1e-6, "ms": 1e-3, "s": 1.0}
_UNITS_BIT = {"bit": 1, "kbit": 10**3, "mbit": 10**6, "gbit": 10**9}


def parse_impairment(text: str) -> Impairment:
    """``"delay=50ms,jitter=10ms,loss=1%[,rate=10mbit]"`` (netem's words) -> :class:`Impairment`;
    a bad item is named in a one-line ValueError."""
    kw: dict = {}
    for item in filter(None, (p.strip() for p in text.split(","))):
        key, _, val = item.partition("=")
        key, val = key.strip().lower(), val.strip().lower()
        if key in ("delay", "jitter"):
            m = re.fullmatch(r"([0-9.]+)\s*(us|ms|s)", val)
            if not m:
                raise ValueError(f"impairment {item!r}: expected e.g. {key}=50ms")
            kw[f"{key}_s"] = float(m.group(1)) * _UNITS_S[m.group(2)]
        elif key == "loss":
            m = re.fullmatch(r"([0-9.]+)\s*(%?)", val)
            if not m:
                raise ValueError(f"impairment {item!r}: expected e.g. loss=1%")
            kw["loss"] = float(m.group(1)) / (100.0 if m.group(2) else 1.0)
        elif key == "rate":
            m = re.fullmatch(r"([0-9.]+)\s*(bit|kbit|mbit|gbit)", val)
            if not m:
                raise ValueError(f"impairment {item!r}: expected e.g. rate=10mbit")
            kw["rate_bps"] = int(float(m.group(1)) * _UNITS_BIT[m.group(2)])
        else:
            raise ValueError(f"impairment {item!r}: unknown key {key!r} (delay, jitter, loss, rate)")
    imp = Impairment(**kw)
    if not 0.0 <= imp.loss < 1.0:
        raise ValueError(f"impairment {text!r}: loss must be in [0, 100) %")
    if imp.jitter_s > imp.delay_s:
        raise ValueError(f"impairment {text!r}: jitter must not exceed the delay")
    return imp


def _attr(kind: int, payload: bytes) -> bytes:
    n = _NLATTR.size + len(payload)
    return _NLATTR.pack(n, kind) + payload + b"\0" * (-n % 4)


class NfQueue:
    """One bound nfnetlink queue in the current network namespace."""

    def __init__(self, queue: int, maxlen: int = 65536, rcvbuf: int = 16 << 20):
        self.queue = queue
        self.sock = socket.socket(socket.AF_NETLINK, socket.SOCK_RAW, NETLINK_NETFILTER)
        try:
            self.sock.setsockopt(socket.SOL_SOCKET, 33, rcvbuf)  # SO_RCVBUFFORCE (root)
        except OSError:
            self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
        self.sock.bind((0, 0))
        self._seq = 0
        self._config(_attr(NFQA_CFG_CMD, struct.pack("!BBH", NFQNL_CFG_CMD_BIND, 0, socket.AF_INET)))
        self._config(_attr(NFQA_CFG_PARAMS, struct.pack("!IB", 0, NFQNL_COPY_META))
                     + _attr(NFQA_CFG_QUEUE_MAXLEN, struct.pack("!I", maxlen)))
        self.sock.setblocking(False)

    def _msg(self, msg_type: int, flags: int, body: bytes) -> bytes:
        self._seq += 1
        nfgen = struct.pack("!BBH", socket.AF_UNSPEC, 0, self.queue)
        n = _NLMSGHDR.size + len(nfgen) + len(body)
        return _NLMSGHDR.pack(n, (NFNL_SUBSYS_QUEUE << 8) | msg_type, NLM_F_REQUEST | flags, self._seq, 0) + nfgen + body

    def _config(self, attrs: bytes) -> None:
        self.sock.send(self._msg(NFQNL_MSG_CONFIG, NLM_F_ACK, attrs))
        data = self.sock.recv(65536)
        _len, kind, _f, _s, _p = _NLMSGHDR.unpack_from(data)
        if kind == NLMSG_ERROR:
            (err,) = struct.unpack_from("=i", data, _NLMSGHDR.size)
            if err != 0:
                raise OSError(-err, f"nfnetlink_queue config of queue {self.queue}: {os.strerror(-err)}")

    def packets(self) -> list[int]:
        """Ids of the packets queued since the last call (non-blocking); ENOBUFS (the kernel found the
        socket buffer full and dropped a packet) raises BlockingIOError's sibling OSError(ENOBUFS)."""
        ids = []
        while True:
            try:
                data = self.sock.recv(1 << 20)
            except BlockingIOError:
                return ids
            off = 0
            while off + _NLMSGHDR.size <= len(data):
                length, kind, _f, _s, _p = _NLMSGHDR.unpack_from(data, off)
                if length < _NLMSGHDR.size:
                    break
                if kind == ((NFNL_SUBSYS_QUEUE << 8) | NFQNL_MSG_PACKET):
                    a = off + _NLMSGHDR.size + 4  # after nfgenmsg
                    end = off + length
                    while a + _NLATTR.size <= end:
                        alen, atype = _NLATTR.unpack_from(data, a)
                        if alen < _NLATTR.size:
                            break
                        if (atype & 0x3FFF) == NFQA_PACKET_HDR:
                            ids.append(struct.unpack_from("!I", data, a + _NLATTR.size)[0])
                            break
                        a += (alen + 3) & ~3
                off += (length + 3) & ~3

    def verdict(self, packet_id: int, verdict: int) -> None:
        self.sock.send(self._msg(NFQNL_MSG_VERDICT, 0, _attr(NFQA_VERDICT_HDR, struct.pack("!II", verdict, packet_id))))

    def close(self) -> None:
        try:
            self.sock.setblocking(True)
            self._config(_attr(NFQA_CFG_CMD, struct.pack("!BBH", NFQNL_CFG_CMD_UNBIND, 0, socket.AF_INET)))
        except OSError:
            pass
        self.sock.close()


def _iptables(*args: str) -> None:
    r = subprocess.run(["iptables-legacy", "-w", *args], capture_output=True, text=True, check=False)
    if r.returncode != 0:
        raise OSError(f"iptables-legacy {' '.join(args)}: {r.stderr.strip() or r.returncode}")


def _tc(*args: str, check: bool = True) -> None:
    r = subprocess.run(["tc", *args], capture_output=True, text=True, check=False)
    if check and r.returncode != 0:
        raise OSError(f"tc {' '.join(args)}: {r.stderr.strip() or r.returncode}")


def run(imp: Impairment, *, queue: int = 0, iface: str = "eth0", seed: int = 0) -> dict:
    """Impair every packet leaving ``iface`` of this network namespace until SIGTERM/SIGINT; returns
    the figures of what was done."""
    stop = {"now": False}

    def on_signal(*_a) -> None:
        stop["now"] = True

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    rng = random.Random(seed)
    q = NfQueue(queue)
    rule = ("OUTPUT", "-o", iface, "-j", "NFQUEUE", "--queue-num", str(queue))
    stats = {"iface": iface, "impairment": str(imp), "packets": 0, "dropped": 0, "overruns": 0,
             "delay_sum_s": 0.0, "max_held": 0}
    try:
        if imp.rate_bps:
            burst = max(1600, imp.rate_bps // 8 // 100)  # 10 ms of tokens, at least one full frame
            _tc("qdisc", "replace", "dev", iface, "root", "tbf", "rate", f"{imp.rate_bps}bit", "burst",
                str(burst), "latency", "1s")
        _iptables("-A", *rule)
        print(json.dumps({"ready": True, "pid": os.getpid()}), flush=True)
        due: list[tuple[float, int]] = []
        lo, hi = imp.delay_s - imp.jitter_s, imp.delay_s + imp.jitter_s
        while not stop["now"]:
            timeout = max(0.0, due[0][0] - time.monotonic()) if due else 0.2
            try:
                select.select([q.sock], [], [], min(timeout, 0.2))
            except InterruptedError:
                continue
            try:
                ids = q.packets()
            except OSError as exc:
                if exc.errno != errno.ENOBUFS:
                    raise
                stats["overruns"] += 1
                ids = []
            now = time.monotonic()
            for pid in ids:
                stats["packets"] += 1
                if imp.loss and rng.random() < imp.loss:
                    stats["dropped"] += 1
                    q.verdict(pid, NF_DROP)
                    continue
                d = rng.uniform(lo, hi) if imp.jitter_s else imp.delay_s
                stats["delay_sum_s"] += d
                heapq.heappush(due, (now + d, pid))
            stats["max_held"] = max(stats["max_held"], len(due))
            now = time.monotonic()
            while due and due[0][0] <= now:
                q.verdict(heapq.heappop(due)[1], NF_ACCEPT)
        for _t, pid in due:  # leaving: let the held packets go
            q.verdict(pid, NF_ACCEPT)
    finally:
        try:
            _iptables("-D", *rule)
        except OSError:
            pass
        if imp.rate_bps:
            _tc("qdisc", "del", "dev", iface, "root", check=False)
        q.close()
    sent = stats["packets"] - stats["dropped"]
    stats["mean_delay_s"] = stats["delay_sum_s"] / sent if sent else None
    return stats


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m bringup.deploy.impair", description=__doc__.splitlines()[0])
    p.add_argument("--delay-ms", type=float, default=0.0)
    p.add_argument("--jitter-ms", type=float, default=0.0)
    p.add_argument("--loss", type=float, default=0.0, help="probability in [0, 1)")
    p.add_argument("--rate-bit", type=int, default=None, help="tbf rate limit [bit/s]")
    p.add_argument("--queue", type=int, default=0)
    p.add_argument("--iface", default="eth0")
    p.add_argument("--seed", type=int, default=0)
    a = p.parse_args(argv)
    imp = Impairment(a.delay_ms / 1e3, a.jitter_ms / 1e3, a.loss, a.rate_bit)
    try:
        stats = run(imp, queue=a.queue, iface=a.iface, seed=a.seed)
    except OSError as exc:
        print(f"impair: error: {exc}", file=sys.stderr, flush=True)
        return 2
    print(json.dumps({"done": stats}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
