"""HDTN (NASA's High-rate DTN, C++, built from its source by scripts/build_hdtn.sh) on loopback for the
interop tests (tests/interop/test_hdtn.py), configured the way HDTN's own test scripts configure it: an
HDTN config JSON (``hdtnConfigName``, ``inductsConfig``/``outductsConfig`` with ``tcpcl_v4`` ducts,
``storageConfig``) and a contact plan JSON for ``hdtn-one-process``; an inducts or outducts JSON for
its ``bpsink-async`` / ``bpgen-async`` apps (HDTN_SRC/config_files/ and HDTN_SRC/tests/test_scripts_linux/ in its source tree).

HDTN's TCP inducts bind the wildcard address (``tcp::v4()``, no option to bind one address), so every
HDTN process, and every project process that talks to it, runs in a network namespace of its own
whose only interface is loopback (``unshare --net``, entered with ``nsenter``): nothing of a test
is reachable from, or sends to, any address but 127.0.0.1, and two test runs (or another engineer's
HDTN on its fixed ZeroMQ ports) never meet. Needs root (CAP_SYS_ADMIN) for the namespace.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import time
from pathlib import Path


def hdtn_prefix(program: str = "hdtn-one-process") -> Path:
    prefix = Path(os.environ.get("HDTN_PREFIX", Path.home() / ".cache" / "constellation" / "hdtn"))
    if not (prefix / "bin" / program).exists():
        raise FileNotFoundError(f"HDTN's {program} not found in {prefix}/bin (build it: scripts/build_hdtn.sh SRC "
                                f"{prefix}, or set HDTN_PREFIX)")
    return prefix


def hdtn_version(prefix: Path) -> str:
    """The source description scripts/build_hdtn.sh kept next to the binaries (git tag, changelog)."""
    info = prefix / "share" / "HDTN" / "BUILD_INFO"
    return " | ".join(info.read_text().split("\n")[1:3]) if info.exists() else "unknown"


class NetNs:
    """A network namespace with loopback only, held by a ``sleep`` process; ``argv`` wraps a command
    to run inside it."""

    def __init__(self) -> None:
        for tool in ("unshare", "nsenter", "ip", "ss"):
            if shutil.which(tool) is None:
                raise FileNotFoundError(f"{tool} not found (util-linux / iproute2): the HDTN tests run HDTN in a "
                                        "network namespace of its own")
        self.holder = subprocess.Popen(["unshare", "--net", "sh", "-c", "ip link set lo up && echo up && exec sleep 3600"],
                                       stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        line = self.holder.stdout.readline().strip()
        if line != "up":
            self.holder.kill()
            raise PermissionError(f"cannot make a network namespace (unshare --net, needs root): "
                                  f"{self.holder.stderr.read().strip()}")

    def argv(self, *cmd: str) -> list[str]:
        return ["nsenter", "-t", str(self.holder.pid), "-n", *cmd]

    def listening(self, port: int) -> bool:
        out = subprocess.run(self.argv("ss", "-Hltn", f"sport = :{port}"), capture_output=True, text=True,
                             check=True).stdout
        return bool(out.strip())

    def wait_listening(self, port: int, proc: subprocess.Popen, log: Path, timeout: float = 60) -> None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.listening(port):
                return
            if proc.poll() is not None:
                raise RuntimeError(f"{proc.args[3]} exited {proc.returncode} before listening on {port}; log:\n"
                                   f"{log.read_text(errors='replace')[-3000:]}")
            time.sleep(0.2)
        raise RuntimeError(f"nothing listens on 127.0.0.1:{port} after {timeout} s; log:\n"
                           f"{log.read_text(errors='replace')[-3000:]}")

    def close(self) -> None:
        self.holder.kill()
        self.holder.wait(timeout=10)


def tcpcl4_induct(name: str, port: int, segment_mru: int) -> dict:
    """One ``tcpcl_v4`` induct, HDTN's field names (config_files/inducts/bpsink_one_tcpclv4_port4558.json)."""
    return {"name": name, "convergenceLayer": "tcpcl_v4", "boundPort": port, "numRxCircularBufferElements": 200,
            "numRxCircularBufferBytesPerElement": 20000, "keepAliveIntervalSeconds": 15,
            "tcpclV4MyMaxRxSegmentSizeBytes": segment_mru, "tlsIsRequired": False, "certificatePemFile": "",
            "privateKeyPemFile": "", "diffieHellmanParametersPemFile": ""}


def tcpcl4_outduct(name: str, next_hop: int, port: int, segment_mru: int = 200000) -> dict:
    """One ``tcpcl_v4`` outduct to 127.0.0.1:``port`` whose peer must say ``ipn:<next_hop>.0`` in its
    SESS_INIT (config_files/outducts/bpgen_one_tcpclv4_port4556.json)."""
    return {"name": name, "convergenceLayer": "tcpcl_v4", "nextHopNodeId": next_hop, "remoteHostname": "127.0.0.1",
            "remotePort": port, "maxNumberOfBundlesInPipeline": 50, "maxSumOfBundleBytesInPipeline": 50000000,
            "keepAliveIntervalSeconds": 17, "tcpclAllowOpportunisticReceiveBundles": True,
            "tcpclV4MyMaxRxSegmentSizeBytes": segment_mru, "tryUseTls": False, "tlsIsRequired": False,
            "useTlsVersion1_3": False, "doX509CertificateVerification": False,
            "verifySubjectAltNameInX509Certificate": False, "certificationAuthorityPemFileForVerification": ""}


def hdtn_config(node: int, inducts: list[dict], outducts: list[dict], home: Path) -> dict:
    """An ``hdtn-one-process`` config (config_files/hdtn/hdtn_ingress1tcpclv4_port4556_egress1tcpclv4_
    port4558flowid2.json), storage in ``home``."""
    return {
        "hdtnConfigName": "constellation interop", "userInterfaceOn": False, "mySchemeName": "unused_scheme_name",
        "myNodeId": node, "myBpEchoServiceId": 2047, "myCustodialSsp": "unused_custodial_ssp",
        "myCustodialServiceId": 0, "myRouterServiceId": 100, "isAcsAware": True, "acsMaxFillsPerAcsPacket": 100,
        "acsSendPeriodMilliseconds": 1000, "retransmitBundleAfterNoCustodySignalMilliseconds": 10000,
        "maxBundleSizeBytes": 10000000, "maxIngressBundleWaitOnEgressMilliseconds": 2000,
        "bufferRxToStorageOnLinkUpSaturation": False, "maxLtpReceiveUdpPacketSizeBytes": 65536,
        "neighborDepletedStorageDelaySeconds": 0, "fragmentBundlesLargerThanBytes": 0,
        "enforceBundlePriority": False, "zmqBoundRouterPubSubPortPath": 10200, "zmqBoundTelemApiPortPath": 10305,
        "inductsConfig": {"inductConfigName": "ours", "inductVector": inducts},
        "outductsConfig": {"outductConfigName": "ours", "outductVector": outducts},
        "storageConfig": {"storageImplementation": "asio_single_threaded", "tryToRestoreFromDisk": False,
                          "autoDeleteFilesOnExit": True, "totalStorageCapacityBytes": 200_000_000,
                          "storageDeletionPolicy": "never",
                          "storageDiskConfigVector": [{"name": "d1", "storeFilePath": str(home / "store1.bin")}]},
    }


def contact_plan(links: list[tuple[int, int]], seconds: int = 3600) -> dict:
    """HDTN's contact plan JSON (module/router/contact_plans/contactPlan.json): each (source, dest) link
    up from HDTN's start for ``seconds``, 1 Gbit/s."""
    return {"contacts": [{"contact": i, "source": s, "dest": d, "startTime": 0, "endTime": seconds,
                          "rateBitsPerSec": 1_000_000_000, "owlt": 1} for i, (s, d) in enumerate(links)]}


class HdtnProc:
    """One HDTN program in the namespace, its console log in ``home/<name>.log``."""

    def __init__(self, ns: NetNs, home: Path, name: str, *args: str) -> None:
        self.prefix = hdtn_prefix(name)
        home.mkdir(parents=True, exist_ok=True)
        self.log_path = home / f"{name}.log"
        self._log = open(self.log_path, "w")  # noqa: SIM115 - closed in stop()
        self.proc = subprocess.Popen(ns.argv(str(self.prefix / "bin" / name), *args), cwd=home,
                                     stdout=self._log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)

    def log(self) -> str:
        return self.log_path.read_text(errors="replace")

    def stop(self, timeout: float = 30) -> int:
        """SIGINT (HDTN's clean exit: it logs its totals), then SIGKILL if it hangs."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(timeout=10)
        self._log.close()
        return self.proc.returncode


def write_json(path: Path, obj: dict) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(obj, indent=2))
    return path
