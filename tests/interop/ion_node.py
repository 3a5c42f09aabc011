"""An ION-DTN node on loopback for the interop tests (tests/interop/test_ion.py), configured the way
ION's own test suite configures its nodes (ionrc / bprc / ipnrc files read by ionadmin, bpadmin and
ipnadmin), not through the project's code.

ION comes from ``scripts/build_ion.sh`` (its install prefix: ``$ION_PREFIX``, default
``~/.cache/constellation/ion``). Each node gets its own shared-memory key and SDR name, so two test
runs (or another engineer's ION) on the machine do not meet; it is stopped with ``bpadmin .`` and
``ionadmin .`` (never ``killm``, which would stop every ION on the host).
"""

from __future__ import annotations

import os
import random
import socket
import subprocess
import time
from pathlib import Path


def ion_prefix() -> Path:
    prefix = Path(os.environ.get("ION_PREFIX", Path.home() / ".cache" / "constellation" / "ion"))
    if not (prefix / "bin" / "ionadmin").exists():
        raise FileNotFoundError(f"ION not found in {prefix} (build it: scripts/build_ion.sh SRC {prefix}, "
                                "or set ION_PREFIX)")
    return prefix


def free_port(kind: int = socket.SOCK_STREAM) -> int:
    s = socket.socket(socket.AF_INET, kind)
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


class IonNode:
    """ION node ``node`` in folder ``home``: a TCP (TCPCLv3) and a UDP induct of its own, and plans
    to the peers ``plans`` = {node number: "tcp/127.0.0.1:PORT" or "udp/127.0.0.1:PORT"}."""

    def __init__(self, home: Path, node: int, plans: dict[int, str], endpoints=(1, 2),
                 contacts: str = "", exits: str = ""):
        self.home, self.node, self.plans, self.exits = home, node, plans, exits
        self.prefix = ion_prefix()
        self.tcp_port, self.udp_port = free_port(), free_port(socket.SOCK_DGRAM)
        self.endpoints, self.contacts = endpoints, contacts
        self._pids: list[int] = []
        home.mkdir(parents=True, exist_ok=True)
        self.env = dict(os.environ, PATH=f"{self.prefix / 'bin'}:{os.environ['PATH']}",
                        LD_LIBRARY_PATH=str(self.prefix / "lib"), ION_NODE_LIST_DIR=str(home))

    def cmd(self, *argv: str, timeout: float = 30, check: bool = True, **kw) -> subprocess.CompletedProcess:
        return subprocess.run(list(argv), cwd=self.home, env=self.env, capture_output=True, text=True,
                              timeout=timeout, check=check, **kw)

    def admin(self, *argv: str, timeout: float = 60) -> int:
        """Run an ION admin program; its output goes to admin.log (not a pipe: the daemons it starts
        inherit its descriptors and would hold a pipe open). Returns its process id."""
        with open(self.home / "admin.log", "a") as log:
            p = subprocess.Popen(list(argv), cwd=self.home, env=self.env, stdout=log, stderr=log,
                                 stdin=subprocess.DEVNULL)
            if p.wait(timeout=timeout) != 0:
                raise RuntimeError(f"{' '.join(argv)} exited {p.returncode}; admin.log:\n"
                                   f"{(self.home / 'admin.log').read_text()[-2000:]}")
        return p.pid

    def start(self) -> IonNode:
        h = self.home
        key = random.randint(20000, 60000)
        (h / "n.ionconfig").write_text(f"wmKey {key}\nsdrName dtncl{key}\nwmSize 8000000\nconfigFlags 1\n"
                                       "heapWords 1000000\n")
        (h / "n.ionrc").write_text(f"1 {self.node} n.ionconfig\n{self.contacts}s\n")
        (h / "n.ionsecrc").write_text("1\n")
        (h / "n.ipnrc").write_text("".join(f"a plan {n} {duct}\n" for n, duct in self.plans.items()) + self.exits)
        ducts = "".join(f"a outduct tcp {d[4:]} ''\n" if d.startswith("tcp/") else f"a outduct udp {d[4:]} udpclo\n"
                        for d in self.plans.values())
        eps = "".join(f"a endpoint ipn:{self.node}.{e} q\n" for e in self.endpoints)
        (h / "n.bprc").write_text(
            "1\na scheme ipn 'ipnfw' 'ipnadminep'\n" + eps
            + "a protocol tcp 1400 100\na protocol udp 1400 100\n"
            + f"a induct tcp 127.0.0.1:{self.tcp_port} tcpcli\na induct udp 127.0.0.1:{self.udp_port} udpcli\n"
            + ducts + "r 'ipnadmin n.ipnrc'\ns\n")
        self._pids = [self.admin("ionadmin", "n.ionrc")]
        self._pids.append(self.admin("ionsecadmin", "n.ionsecrc"))
        self._pids.append(self.admin("bpadmin", "n.bprc"))
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline:
            log = self.log()
            if "tcpcli is running" in log and "udpcli is running" in log:
                return self
            time.sleep(0.2)
        raise RuntimeError(f"ION node {self.node} did not start; ion.log:\n{self.log()[-2000:]}")

    def log(self) -> str:
        p = self.home / "ion.log"
        return p.read_text(errors="replace") if p.exists() else ""

    def version(self) -> str:
        """ION's release (the VNAME compiled into libici) and its bundle protocol (bpversion)."""
        lib = (self.prefix / "lib" / "libici.so").read_bytes()
        i = lib.find(b"ION-OPEN-SOURCE-")
        release = lib[i:lib.index(b"\0", i)].decode() if i >= 0 else "unknown release"
        bp = self.cmd("bpversion", check=False).stdout.strip()  # it exits with a non-zero status
        return f"{release} {bp}"

    def stop(self) -> None:
        with open(self.home / "admin.log", "a") as log:
            for prog in ("bpadmin", "ionadmin"):
                subprocess.run([prog, "."], cwd=self.home, env=self.env, stdout=log, stderr=log, timeout=60,
                               stdin=subprocess.DEVNULL, check=False)
                time.sleep(1)
        # the shared-memory segments this node's admin programs created (ION leaves them behind)
        out = subprocess.run(["ipcs", "-m", "-p"], check=False, capture_output=True, text=True).stdout
        for line in out.splitlines():
            f = line.split()
            if len(f) >= 4 and f[0].isdigit() and int(f[2]) in self._pids:
                subprocess.run(["ipcrm", "-m", f[0]], check=False, capture_output=True)

    def receive_files(self, endpoint: str, count: int, timeout: float = 30) -> list[bytes]:
        """Payloads of ``count`` bundles delivered at ``endpoint`` (ION's bprecvfile: testfile1...)."""
        for f in self.home.glob("testfile*"):
            f.unlink()
        self.cmd("bprecvfile", endpoint, str(count), timeout=timeout)
        return [(self.home / f"testfile{i}").read_bytes() for i in range(1, count + 1)]

    def send_file(self, src: str, dest: str, path: Path, ttl_s: int | None = None) -> None:
        """One bundle with ``path``'s bytes as payload, ION's default class of service and lifetime
        (300 s), or class of service "0.1" (no custody, standard priority) and ``ttl_s``. (With the
        class of service "1" - custody requested - ION 4.1.3 queued the bundles and never sent them
        on the TCP outduct: measured.)"""
        extra = [] if ttl_s is None else ["0.1", str(int(ttl_s))]
        self.cmd("bpsendfile", src, dest, str(path), *extra)
