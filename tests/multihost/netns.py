"""Several "hosts" on one machine: Linux network namespaces joined by a bridge (issue 7).

A :class:`NetnsLab` creates, for one test:

* one namespace ``<prefix>br`` holding a Linux bridge ``br0`` (no address, no uplink);
* N host namespaces ``<prefix>h<i>``, each with loopback up and one interface ``eth0`` at
  ``10.231.<subnet>.<i+1>/24``, the far end of a veth pair whose near end is a port of ``br0``.

Every link is created *inside* the lab's namespaces (``ip -n BR link add ... peer name eth0 netns
H``), so nothing is ever added to, changed in or named in the root namespace, and no namespace gets
a default route: a packet for any address outside 10.231.<subnet>.0/24 fails with "network
unreachable" at route lookup, before it is sent. Everything is removed on exit, also when the body
raised or setup failed halfway: processes the lab started are killed (process group) and every
namespace whose name carries the lab's prefix is deleted. Leftovers of a crashed earlier run (a
prefix whose pid is gone) are removed when the next lab starts.

How we know it is right (tests/multihost/test_netns.py, marker ``multihost``): UDP datagrams cross
between every pair of hosts; a route lookup for an outside address fails in every host; the root
namespace's link list and ``ip netns list`` are the same before and after; a real rclpy publisher in
one namespace and a subscriber in another exchange messages over DDS, and the hosts' ``eth0``
counters show the traffic crossed the veth/bridge (each namespace has its own loopback, so there is
no other path).

Reference: ip-netns(8), veth(4), docs/design.md section 7 "Several hosts on one machine".
Not done: link delay/rate (``tc netem`` is absent on this kernel; the DTN router emulates them);
``cut()`` takes a host's link down and up, which is what the fault tests need.
"""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Self

__all__ = [
    "NetnsHost",
    "NetnsLab",
    "NetnsUnavailable",
    "list_netns",
    "netns_available",
    "netns_lab",
    "ros_env",
]

SUBNET_PREFIX = "10.231"
_NAME_ROOT = "cdtn"  # every namespace this module creates starts with this
_NAME_RE = re.compile(rf"^{_NAME_ROOT}(\d+)x[0-9a-f]+-")


class NetnsUnavailable(RuntimeError):
    """Network namespaces cannot be made here (not root, no iproute2, no CAP_SYS_ADMIN)."""


@dataclass(frozen=True, slots=True)
class NetnsHost:
    """One emulated host: its namespace, its address on the lab's bridge, its interface."""

    index: int
    netns: str
    addr: str
    iface: str = "eth0"

    def wrap(self, argv: Sequence[str]) -> list[str]:
        """``argv`` run inside this host's namespace (``ip netns exec NS argv...``)."""
        return ["ip", "netns", "exec", self.netns, *argv]


def _ip(*args: str, check: bool = True) -> subprocess.CompletedProcess:
    return subprocess.run(["ip", *args], capture_output=True, text=True, check=check, timeout=20)


def list_netns() -> list[str]:
    """Names in ``ip netns list`` (first word of each line)."""
    out = _ip("netns", "list").stdout
    return sorted(line.split()[0] for line in out.splitlines() if line.strip())


def netns_available() -> tuple[bool, str]:
    """(True, "") if this process can create namespaces, else (False, reason)."""
    if shutil.which("ip") is None:
        return False, "iproute2 'ip' command not found"
    if os.geteuid() != 0:
        return False, f"network namespaces need root (euid is {os.geteuid()})"
    if _ip("netns", "list", check=False).returncode != 0:
        return False, "'ip netns' is not available"
    probe = f"{_NAME_ROOT}{os.getpid()}x0-probe"
    res = _ip("netns", "add", probe, check=False)
    if res.returncode != 0:
        return False, f"cannot create a network namespace: {res.stderr.strip()}"
    _ip("netns", "del", probe, check=False)
    return True, ""


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def remove_stale() -> list[str]:
    """Delete namespaces of this module left by processes that no longer exist; return their names."""
    removed = []
    for name in list_netns():
        m = _NAME_RE.match(name)
        if m and not _pid_alive(int(m.group(1))):
            _kill_pids_in(name)
            _ip("netns", "del", name, check=False)
            removed.append(name)
    return removed


def _kill_pids_in(netns: str) -> None:
    res = _ip("netns", "pids", netns, check=False)
    for tok in res.stdout.split():
        if tok.isdigit() and int(tok) != os.getpid():
            try:
                os.kill(int(tok), signal.SIGKILL)
            except ProcessLookupError:
                pass


@dataclass
class NetnsLab:
    """N hosts on one bridge, each in its own network namespace. Use as a context manager."""

    n_hosts: int
    subnet: int = 0
    prefix: str = field(default="")
    hosts: list[NetnsHost] = field(default_factory=list, init=False)
    bridge_netns: str = field(default="", init=False)
    _procs: list[subprocess.Popen] = field(default_factory=list, init=False, repr=False)
    _created: list[str] = field(default_factory=list, init=False, repr=False)

    def __post_init__(self) -> None:
        if not 1 <= self.n_hosts <= 250:
            raise ValueError(f"NetnsLab: n_hosts must be 1..250, got {self.n_hosts}")
        if not 0 <= self.subnet <= 255:
            raise ValueError(f"NetnsLab: subnet must be 0..255, got {self.subnet}")
        if not self.prefix:
            self.prefix = f"{_NAME_ROOT}{os.getpid()}x{os.urandom(3).hex()}-"
        self.bridge_netns = f"{self.prefix}br"

    # -- lifecycle -------------------------------------------------------------------------------
    def __enter__(self) -> Self:
        ok, reason = netns_available()
        if not ok:
            raise NetnsUnavailable(reason)
        remove_stale()
        try:
            self._build()
        except BaseException:
            self.close()
            raise
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _add_ns(self, name: str) -> None:
        _ip("netns", "add", name)
        self._created.append(name)
        _ip("-n", name, "link", "set", "lo", "up")

    def _build(self) -> None:
        br = self.bridge_netns
        self._add_ns(br)
        _ip("-n", br, "link", "add", "br0", "type", "bridge")
        _ip("-n", br, "link", "set", "br0", "up")
        for i in range(self.n_hosts):
            ns = f"{self.prefix}h{i}"
            self._add_ns(ns)
            port = f"p{i}"
            # Both ends are born inside the lab: the near end in the bridge namespace, the peer
            # moved straight into the host namespace. The root namespace never sees either.
            _ip("-n", br, "link", "add", port, "type", "veth", "peer", "name", "eth0", "netns", ns)
            _ip("-n", br, "link", "set", port, "master", "br0")
            _ip("-n", br, "link", "set", port, "up")
            addr = f"{SUBNET_PREFIX}.{self.subnet}.{i + 1}"
            _ip("-n", ns, "addr", "add", f"{addr}/24", "dev", "eth0")
            _ip("-n", ns, "link", "set", "eth0", "up")
            self.hosts.append(NetnsHost(index=i, netns=ns, addr=addr))

    def close(self) -> None:
        """Stop every process started through the lab, then delete every namespace it made."""
        for p in self._procs:
            if p.poll() is None:
                try:
                    os.killpg(p.pid, signal.SIGKILL)
                except (ProcessLookupError, PermissionError):
                    p.kill()
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                pass
        self._procs.clear()
        names = set(self._created) | {n for n in list_netns() if n.startswith(self.prefix)}
        for name in sorted(names):
            _kill_pids_in(name)  # anything else still inside (e.g. a grandchild that escaped its group)
            _ip("netns", "del", name, check=False)
        self._created.clear()
        leftover = [n for n in list_netns() if n.startswith(self.prefix)]
        if leftover:
            raise RuntimeError(f"NetnsLab: could not delete namespaces {leftover}")

    # -- using the hosts ---------------------------------------------------------------------------
    def popen(
        self,
        host: NetnsHost,
        argv: Sequence[str],
        *,
        env: Mapping[str, str] | None = None,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        cwd: str | Path | None = None,
    ) -> subprocess.Popen:
        """Start ``argv`` inside ``host``'s namespace in its own process group; killed on close()."""
        p = subprocess.Popen(
            host.wrap(argv),
            env=dict(env) if env is not None else None,
            stdout=stdout,
            stderr=stderr,
            text=True,
            cwd=cwd,
            start_new_session=True,
        )
        self._procs.append(p)
        return p

    def run(self, host: NetnsHost, argv: Sequence[str], *, timeout_s: float = 30.0,
            env: Mapping[str, str] | None = None) -> subprocess.CompletedProcess:
        """Run ``argv`` inside ``host``'s namespace to completion (output captured as text)."""
        return subprocess.run(host.wrap(argv), check=False, capture_output=True, text=True,
                              timeout=timeout_s, env=dict(env) if env is not None else None)

    def link_bytes(self, host: NetnsHost) -> tuple[int, int]:
        """(rx_bytes, tx_bytes) of the host's interface, from its namespace's sysfs view."""
        res = self.run(host, ["cat", f"/sys/class/net/{host.iface}/statistics/rx_bytes",
                              f"/sys/class/net/{host.iface}/statistics/tx_bytes"])
        rx, tx = (int(x) for x in res.stdout.split())
        return rx, tx

    def cut(self, host: NetnsHost, up: bool) -> None:
        """Take the host's bridge port down (``up=False``) or up again: a link cut (fault tests)."""
        _ip("-n", self.bridge_netns, "link", "set", f"p{host.index}", "up" if up else "down")

    def peers_of(self, host: NetnsHost) -> list[str]:
        """Addresses of every other host (what ROS_STATIC_PEERS should list)."""
        return [h.addr for h in self.hosts if h is not host]


def ros_env(
    lab: NetnsLab,
    host: NetnsHost,
    domain_id: int,
    *,
    discovery: str = "static",
    base: Mapping[str, str] | None = None,
) -> dict[str, str]:
    """Environment for a ROS 2 process on ``host``.

    ``discovery="static"``: ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` plus ``ROS_STATIC_PEERS`` =
    the other hosts (unicast only). ``discovery="subnet"``: default multicast discovery, which is
    safe here because the namespace's only interface is the lab's bridge. ``discovery="none"``:
    LOCALHOST without peers (a negative control: nothing should be discovered across hosts).
    """
    if not 0 <= domain_id <= 101:
        raise ValueError(f"ros_env: ROS_DOMAIN_ID must be 0..101, got {domain_id}")
    env = dict(os.environ if base is None else base)
    for k in ("ROS_STATIC_PEERS", "ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_LOCALHOST_ONLY"):
        env.pop(k, None)
    env["ROS_DOMAIN_ID"] = str(domain_id)
    env["PYTHONUNBUFFERED"] = "1"
    if discovery == "static":
        env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
        env["ROS_STATIC_PEERS"] = ";".join(lab.peers_of(host))
    elif discovery == "subnet":
        env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "SUBNET"
    elif discovery == "none":
        env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    else:
        raise ValueError(f"ros_env: discovery must be static|subnet|none, got {discovery!r}")
    return env


@contextmanager
def netns_lab(n_hosts: int, *, subnet: int = 0) -> Iterator[NetnsLab]:
    """A :class:`NetnsLab` for a pytest test: skips (with the reason) where namespaces cannot be made."""
    import pytest

    ok, reason = netns_available()
    if not ok:
        pytest.skip(f"multihost: {reason}")
    with NetnsLab(n_hosts, subnet=subnet) as lab:
        yield lab


if __name__ == "__main__":  # manual check: python tests/multihost/netns.py [N]
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 3
    with NetnsLab(n) as lab:
        for h in lab.hosts:
            print(h.netns, h.addr)
        print(_ip("-n", lab.hosts[0].netns, "route").stdout)
    print("after:", [x for x in list_netns() if x.startswith(_NAME_ROOT)])
