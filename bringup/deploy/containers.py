"""Run a `constellation compose` project with podman directly: one container per process.

``docker compose`` needs a Docker engine and ``podman-compose`` follows the compose file loosely
(docker/README.md says which of its versions run the file as written). This driver reads the same
file and does what ``up`` / ``down`` must, with the settings measured on the project's machines
(bringup/deploy/podman.py: runc, ulimits):

* ``up``: remove what is left of an earlier run of the same project; create the ``internal``
  network (no gateway off the bridge, no DNS: services use fixed addresses) and the ``runs`` volume;
  create every service's container (fixed address, environment, bind mounts relative to the compose
  file, ``--init``, restart policy, ``--pull never``), all labelled with the project; prepare their
  network namespaces (``podman init``) so that an impairment (bringup/deploy/impair.py) is in place
  before the first packet; start them.
* ``wait``: follow the clock's progress lines; when the clock exits, give the hosts 10 s to leave
  (as the local launcher does), stop the rest and collect every container's exit code and restart
  count. A container whose restart policy brings it back gets a new network namespace: the driver
  sees it (its sandbox changed) and impairs the new one too.
* ``copy_out``: the run folder (bag, report.json, report.md) from the volume to a host folder.
* ``down``: remove every container, network and volume labelled with the project (also after a
  crash of the driver: the labels find them), by this driver or by podman-compose.

Oracle: tests/containers/test_container_run.py, test_impair.py and test_container_faults.py (a 12-satellite run through this driver equals the local engine's
observations and bundle deliveries; with an impairment on every container too; a satellite killed
inside its container is restarted by its restart policy and nothing is lost; nothing labelled is
left afterwards).
"""

from __future__ import annotations

import json
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from bringup.deploy.impair import Impairment
from bringup.deploy.podman import LABEL, ULIMITS, label_filter, podman, podman_argv, podman_json
from bringup.errors import UserError

__all__ = ["ContainerRun", "Outcome", "down", "leftovers", "load_compose"]

CLOCK = "clock"
PODMAN_COMPOSE_LABEL = "io.podman.compose.project"
# Wall seconds hosts get to leave after the clock ended the run (bringup/engine/ros/launcher.py)
_HOST_EXIT_GRACE_S = 10.0


def load_compose(path: Path) -> dict:
    """The compose document written by `constellation compose` (one-line errors on anything else)."""
    path = Path(path)
    try:
        doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise UserError(f"compose file {path}: no such file") from None
    except yaml.YAMLError as exc:
        raise UserError(f"compose file {path}: not YAML ({str(exc).splitlines()[0]})") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("services"), dict) or CLOCK not in doc["services"]:
        raise UserError(f"compose file {path}: no 'services' with a '{CLOCK}' service (write it with "
                        "`constellation compose`)")
    if not isinstance(doc.get("name"), str) or len(doc.get("networks", {})) != 1:
        raise UserError(f"compose file {path}: expected a project 'name' and one network")
    return doc


def leftovers(project: str | None = None) -> dict[str, list[str]]:
    """Containers, networks and volumes labelled with ``project`` by this driver or by podman-compose
    (every project of this driver when None)."""
    filters = [label_filter(project)]
    if project:
        filters.append(("--filter", f"label={PODMAN_COMPOSE_LABEL}={project}"))
    found: dict[str, list[str]] = {"containers": [], "networks": [], "volumes": []}
    for f in filters:
        for kind, argv in (("containers", ("ps", "-a", *f, "--format", "{{.Names}}")),
                           ("networks", ("network", "ls", *f, "--format", "{{.Name}}")),
                           ("volumes", ("volume", "ls", *f, "--format", "{{.Name}}"))):
            found[kind] += [n for n in podman(*argv).stdout.decode().split() if n not in found[kind]]
    return found


def down(project: str | None, *, volumes: bool = True) -> dict[str, list[str]]:
    """Remove every container, network (and volume) labelled with ``project``; returns what was removed."""
    found = leftovers(project)
    if found["containers"]:
        # --volumes: also the anonymous volumes of the image's VOLUME (a container without a /runs mount)
        podman("rm", "--force", "--volumes", "--time", "5", *found["containers"], check=False, timeout=300)
    for net in found["networks"]:
        podman("network", "rm", "--force", net, check=False)
    if volumes:
        for vol in found["volumes"]:
            podman("volume", "rm", "--force", vol, check=False)
    else:
        found["volumes"] = []
    return found


@dataclass
class Outcome:
    """How a containers run ended."""

    returncode: int  # the clock's exit code (0: complete), or 124 when the wall limit was hit
    message: str
    wall_s: float
    exit_codes: dict[str, int | None]
    restarts: dict[str, int]
    lingered: list[str] = field(default_factory=list)
    last_progress: dict | None = None
    impair_stats: dict[str, list[dict]] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.returncode == 0 and not self.failed_hosts

    @property
    def failed_hosts(self) -> list[str]:
        return [s for s, c in self.exit_codes.items() if s != CLOCK and c not in (0, None) and s not in self.lingered]


class ContainerRun:
    """One compose project run with podman (see the module docstring)."""

    def __init__(self, compose_path: Path, *, impair: Impairment | None = None, seed: int = 0):
        self.path = Path(compose_path).resolve()
        self.doc = load_compose(self.path)
        self.project: str = self.doc["name"]
        (self.net_key, net), = self.doc["networks"].items()
        self.network = f"{self.project}_{self.net_key}"
        self.subnet = net["ipam"]["config"][0]["subnet"]
        self.volumes = {v: f"{self.project}_{v}" for v in self.doc.get("volumes", {})}
        self.containers = {svc: f"{self.project}-{svc}" for svc in self.doc["services"]}
        self.impair = impair
        self.seed = seed
        self._impairers: dict[str, tuple[str, subprocess.Popen]] = {}
        self.impair_stats: dict[str, list[dict]] = {}

    # -- up -----------------------------------------------------------------------------------------
    def _create_args(self, svc: str, s: dict) -> list[str]:
        args = ["create", "--name", self.containers[svc], "--label", f"{LABEL}={self.project}", "--pull", "never",
                "--network", self.network, "--ip", s["networks"][self.net_key]["ipv4_address"], *ULIMITS]
        if s.get("hostname"):
            args += ["--hostname", s["hostname"]]
        for k, v in (s.get("environment") or {}).items():
            args += ["--env", f"{k}={v}"]
        for m in s.get("volumes", []):
            src, _, rest = m.partition(":")
            if src.startswith("."):
                src = str((self.path.parent / src).resolve())
            elif not src.startswith("/"):
                src = self.volumes[src]
            args += ["--volume", f"{src}:{rest}"]
        if s.get("init"):
            args.append("--init")
        if s.get("restart"):
            args += ["--restart", s["restart"]]
        if s.get("stop_grace_period"):
            args += ["--stop-timeout", str(int(float(s["stop_grace_period"].rstrip("s"))))]
        return [*args, s["image"], *s["command"]]

    def up(self) -> None:
        down(self.project)
        podman("network", "create", "--internal", "--disable-dns", "--subnet", self.subnet,
               "--label", f"{LABEL}={self.project}", self.network)
        for vol in self.volumes.values():
            podman("volume", "create", "--label", f"{LABEL}={self.project}", vol)
        for svc, s in self.doc["services"].items():
            podman(*self._create_args(svc, s))
        names = list(self.containers.values())
        podman("init", *names, timeout=300)
        if self.impair is not None:
            self._impair_all()
        podman("start", *names, timeout=300)

    # -- impairment -----------------------------------------------------------------------------------
    def _sandboxes(self) -> dict[str, str]:
        info = podman_json("inspect", *self.containers.values())
        by_name = {i["Name"]: i for i in info}
        return {svc: (by_name[c].get("NetworkSettings") or {}).get("SandboxKey") or "" for svc, c in self.containers.items()}

    def _impair_all(self) -> None:
        for svc, sandbox in self._sandboxes().items():
            if sandbox and self._impairers.get(svc, ("",))[0] != sandbox:
                self._start_impairer(svc, sandbox)

    def _start_impairer(self, svc: str, sandbox: str) -> None:
        old = self._impairers.pop(svc, None)
        if old is not None:
            self._stop_impairer(svc, old[1])
        seed = self.seed * 1000 + sorted(self.containers).index(svc) + 17 * len(self.impair_stats.get(svc, []))
        proc = subprocess.Popen(["nsenter", f"--net={sandbox}", sys.executable, "-m", "bringup.deploy.impair",
                                 *self.impair.args(), "--seed", str(seed)],  # type: ignore[union-attr]
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        line = proc.stdout.readline()  # type: ignore[union-attr]
        if '"ready"' not in line:
            err = proc.stderr.read().strip() if proc.poll() is not None else ""  # type: ignore[union-attr]
            proc.kill()
            raise UserError(f"impairment of {svc} ({sandbox}) did not start: {err or line.strip() or 'no message'}")
        self._impairers[svc] = (sandbox, proc)

    def _stop_impairer(self, svc: str, proc: subprocess.Popen) -> None:
        proc.terminate()
        try:
            out, _err = proc.communicate(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            out, _err = proc.communicate()
        for line in out.splitlines():
            if line.startswith('{"done"'):
                self.impair_stats.setdefault(svc, []).append(json.loads(line)["done"])

    def stop_impairment(self) -> None:
        for svc, (_sb, proc) in list(self._impairers.items()):
            self._stop_impairer(svc, proc)
        self._impairers.clear()

    # -- wait ---------------------------------------------------------------------------------------
    def states(self) -> dict[str, dict]:
        info = podman_json("inspect", *self.containers.values())
        by_name = {i["Name"]: i for i in info}
        out = {}
        for svc, c in self.containers.items():
            i = by_name.get(c)
            if i is None:
                out[svc] = {"status": "missing", "exit": None, "restarts": 0, "pid": 0}
                continue
            st = i["State"]
            out[svc] = {"status": st["Status"], "exit": st.get("ExitCode"), "restarts": int(i.get("RestartCount") or 0),
                        "pid": int(st.get("Pid") or 0)}
        return out

    def wait(self, *, timeout_s: float = 3600.0, progress: Callable[[dict], None] | None = None,
             poll_s: float = 1.0) -> Outcome:
        t0 = time.monotonic()
        last: list[dict | None] = [None]
        logs = subprocess.Popen(podman_argv("logs", "--follow", self.containers[CLOCK]), stdout=subprocess.PIPE,
                                stderr=subprocess.DEVNULL, text=True)

        def follow() -> None:
            for line in logs.stdout:  # type: ignore[union-attr]
                try:
                    rec = json.loads(line)
                except ValueError:
                    continue
                body = rec.get("progress") or rec.get("done") if isinstance(rec, dict) else None
                if isinstance(body, dict):
                    last[0] = body
                    if progress is not None:
                        progress(body)

        reader = threading.Thread(target=follow, daemon=True)
        reader.start()
        rc, message = 0, ""
        try:
            while True:
                st = self.states()
                if self.impair is not None:
                    self._impair_all()
                if st[CLOCK]["status"] in ("exited", "stopped") and st[CLOCK]["exit"] is not None:
                    rc = int(st[CLOCK]["exit"])
                    break
                if time.monotonic() - t0 > timeout_s:
                    rc, message = 124, f"the run did not end within {timeout_s:g} s"
                    break
                time.sleep(poll_s)
            deadline = time.monotonic() + _HOST_EXIT_GRACE_S
            while time.monotonic() < deadline:
                st = self.states()
                if all(v["status"] in ("exited", "stopped", "missing") for v in st.values()):
                    break
                time.sleep(0.5)
            running = [s for s, v in st.items() if v["status"] not in ("exited", "stopped", "missing")]
            if running:
                podman("stop", "--time", "5", *(self.containers[s] for s in running), check=False, timeout=120)
                st = self.states()
        finally:
            logs.terminate()
            reader.join(timeout=2.0)
            self.stop_impairment()
        wall = time.monotonic() - t0
        lingered = running if rc == 0 else []
        exit_codes = {s: v["exit"] for s, v in st.items()}
        restarts = {s: v["restarts"] for s, v in st.items() if v["restarts"]}
        if rc != 0 and not message:
            message = self.clock_error() or f"clock exited with code {rc}"
        failed = [s for s, c in exit_codes.items() if s != CLOCK and c not in (0, None) and s not in lingered]
        if rc == 0 and failed:
            message = "; ".join(f"container '{s}' exited with code {exit_codes[s]}" for s in failed)
        return Outcome(rc, message, wall, exit_codes, restarts, lingered, last[0], dict(self.impair_stats))

    def clock_error(self) -> str:
        r = podman("logs", self.containers[CLOCK], check=False)
        lines = [ln for ln in (r.stderr or b"").decode(errors="replace").splitlines() if ln.strip()]
        errs = [ln for ln in lines if "error" in ln.lower()]
        return (errs or lines or [""])[-1].strip()

    def logs(self, svc: str) -> str:
        r = podman("logs", self.containers[svc], check=False)
        return (r.stdout or b"").decode(errors="replace") + (r.stderr or b"").decode(errors="replace")

    # -- results and teardown -----------------------------------------------------------------------
    def copy_out(self, dest: Path) -> Path:
        """Copy the run folder (bag/, report.json, report.md, store/, state/) to ``dest`` (which must
        not exist yet)."""
        spec = json.loads((self.path.parent / "run_spec.json").read_text())
        run_dir = spec["extra"].get("report_dir") or str(Path(spec["bag_dir"]).parent)
        dest = Path(dest)
        if dest.exists():
            raise UserError(f"{dest} exists: the run folder is copied to a new folder")
        dest.parent.mkdir(parents=True, exist_ok=True)
        podman("cp", f"{self.containers[CLOCK]}:{run_dir}", str(dest), timeout=600)
        return dest

    def down(self, *, volumes: bool = True) -> dict[str, list[str]]:
        self.stop_impairment()
        return down(self.project, volumes=volumes)

    def host_pid(self, svc: str, *, child: bool = True) -> int:
        """Host pid of ``svc``'s process (``child``: the node process under the container's init;
        else the container's pid 1)."""
        pid = self.states()[svc]["pid"]
        if not pid:
            raise UserError(f"container {self.containers[svc]} is not running")
        if not child:
            return pid
        kids = []
        for task in Path(f"/proc/{pid}/task").iterdir():
            kids += (task / "children").read_text().split()
        if not kids:
            raise UserError(f"container {self.containers[svc]}: its init has no child process")
        return int(kids[0])
