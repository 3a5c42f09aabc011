"""How the project calls podman on a machine without a Docker engine (podman + runc from Debian).

Every podman command the project runs goes through :func:`podman` so that it carries the two global
settings measured on the project's machines (docs/design.md section 7): the runtime is runc (the default
crun stops with "cgroups in hybrid mode not supported") and containers and builds get
explicit ulimits (podman otherwise asks for RLIMIT_NOFILE 1048576, above the hard limit:
"setrlimit: Operation not permitted"). ``CONSTELLATION_PODMAN`` overrides the podman binary and
``CONSTELLATION_OCI_RUNTIME`` the runtime (empty: podman's own default).

Objects the project makes carry the label ``LABEL=<project name>`` so that ``constellation
containers down`` finds every container, network and volume of a project, also after a crash.

Oracle: tests/containers/test_container_run.py and the other container tests run real containers
with these settings (and fail loudly when podman is missing: scripts/setup_containers.sh installs it).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from collections.abc import Sequence

from bringup.errors import UserError

__all__ = ["LABEL", "ULIMITS", "PodmanError", "podman", "podman_argv", "podman_json", "require_podman"]

LABEL = "io.agile-dtn-constellation.project"
ULIMITS = ("--ulimit", "nofile=4096:4096", "--ulimit", "nproc=4096:4096")
_RUNC = "/usr/bin/runc"


class PodmanError(UserError):
    """A podman command failed; the message names the command and podman's last line."""


def require_podman() -> str:
    """The podman binary, or a one-line error saying how to install it."""
    exe = os.environ.get("CONSTELLATION_PODMAN") or shutil.which("podman")
    if not exe:
        raise UserError("podman is not installed: run `bash scripts/setup_containers.sh` (as root; it installs "
                        "podman, runc and debootstrap from Debian and builds the images)")
    return exe


def podman_argv(*args: str) -> list[str]:
    """``podman [--runtime runc] ARGS``."""
    runtime = os.environ.get("CONSTELLATION_OCI_RUNTIME", _RUNC if os.path.exists(_RUNC) else "")
    return [require_podman(), *(("--runtime", runtime) if runtime else ()), *args]


def podman(*args: str, check: bool = True, timeout: float | None = 600.0, input: bytes | None = None,
           capture: bool = True) -> subprocess.CompletedProcess:
    """Run ``podman ARGS``; with ``check`` a failure raises :class:`PodmanError` naming the command."""
    argv = podman_argv(*args)
    r = subprocess.run(argv, input=input, capture_output=capture, timeout=timeout, check=False)
    if check and r.returncode != 0:
        err = (r.stderr or b"").decode(errors="replace").strip().splitlines() if capture else []
        raise PodmanError(f"`podman {' '.join(args[:3])} ...` failed (exit {r.returncode}): "
                          f"{err[-1] if err else 'no message'}")
    return r


def podman_json(*args: str) -> list | dict:
    """``podman ARGS --format json`` decoded (an empty output is an empty list)."""
    out = podman(*args, "--format", "json").stdout.decode()
    return json.loads(out) if out.strip() else []


def label_filter(project: str | None) -> Sequence[str]:
    return ("--filter", f"label={LABEL}={project}" if project else f"label={LABEL}")
