"""Container images of the project, built from its own files and Debian packages only.

Two images:

* the base: Debian ``bookworm`` (minbase) with ``python3`` (3.11), ``python3-venv`` and
  ``ca-certificates``, made by ``debootstrap`` from the Debian mirror apt already uses (read from
  ``/etc/apt/sources.list`` and ``sources.list.d/``) and loaded with ``podman import``; for machines
  that reach no image registry. Users with a registry use ``python:3.11-slim`` instead.
* the project image: docker/Dockerfile on that base (``--build-arg BASE=...``). The dependencies are
  the pins of pyproject.toml; the host's own pip turns them into wheels in docker/wheels/ first
  (``pip wheel``, so the host's pip configuration and caches apply), and the build then installs
  from that wheelhouse with no network at all (``--network none``, ``PIP_NO_INDEX=1``): the same
  ``pip install`` lines as a build from the package index.

Oracle: tests/containers/conftest.py builds both images (cold, every test session) and the tests
in tests/containers/test_container_run.py run the project in them (equal results to the host);
tests/unit/test_docker_files.py checks the Dockerfile against the repository statically.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
import tempfile
import time
import tomllib
from dataclasses import dataclass
from pathlib import Path

from bringup.deploy.podman import ULIMITS, podman, podman_argv
from bringup.errors import UserError

__all__ = [
    "BASE_IMAGE",
    "DEFAULT_BASE",
    "IMAGE",
    "BuildTimes",
    "build_base",
    "build_image",
    "debian_mirror",
    "image_exists",
    "remove_image",
    "repo_root",
    "wheelhouse",
]

IMAGE = "localhost/agile-dtn-constellation:0.1.0"
BASE_IMAGE = "localhost/agile-dtn-base:bookworm"
DEFAULT_BASE = "python:3.11-slim"
SUITE = "bookworm"
BASE_PACKAGES = ("python3", "python3-venv", "ca-certificates")


def repo_root() -> Path:
    """The checkout this package runs from (holds pyproject.toml and docker/Dockerfile)."""
    return Path(__file__).resolve().parents[2]


@dataclass
class BuildTimes:
    """Wall seconds of each step of :func:`build_all` (None: the step was not needed)."""

    base_s: float | None = None
    wheels_s: float | None = None
    image_s: float | None = None


def debian_mirror(apt_dir: Path = Path("/etc/apt")) -> str:
    """The first Debian archive URI apt is configured with (one-line or deb822 sources), not the
    security archive."""
    uris: list[str] = []
    files = [apt_dir / "sources.list", *sorted((apt_dir / "sources.list.d").glob("*.list")),
             *sorted((apt_dir / "sources.list.d").glob("*.sources"))]
    for f in files:
        try:
            text = f.read_text(encoding="utf-8", errors="replace")
        except OSError:
            continue
        if f.suffix == ".sources":
            for stanza in re.split(r"\n\s*\n", text):
                fields = dict(re.findall(r"^(\w[\w-]*):\s*(.*)$", stanza, re.MULTILINE))
                if "deb" in fields.get("Types", "").split() and SUITE in fields.get("Suites", "").split():
                    uris += fields.get("URIs", "").split()
        else:
            for line in text.splitlines():
                m = re.match(r"^\s*deb\s+(?:\[[^\]]*\]\s+)?(\S+)\s+(\S+)", line)
                if m and m.group(2) == SUITE:
                    uris.append(m.group(1))
    uris = [u for u in uris if "security" not in u]
    if not uris:
        raise UserError(f"no Debian '{SUITE}' archive in apt's sources under {apt_dir}: cannot debootstrap a base image")
    return uris[0]


def image_exists(tag: str) -> bool:
    return podman("image", "exists", tag, check=False).returncode == 0


def remove_image(tag: str) -> None:
    podman("rmi", "--force", tag, check=False)


def build_base(tag: str = BASE_IMAGE, *, mirror: str | None = None, log=None) -> float:
    """debootstrap a minimal bookworm with Python 3.11 and import it as ``tag``; returns wall s."""
    exe = shutil.which("debootstrap") or ("/usr/sbin/debootstrap" if Path("/usr/sbin/debootstrap").exists() else None)
    if exe is None:
        raise UserError("debootstrap is not installed: run `bash scripts/setup_containers.sh` (as root)")
    mirror = mirror or debian_mirror()
    t0 = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="constellation-rootfs-") as tmp:
        root = Path(tmp) / "rootfs"
        r = subprocess.run([exe, "--variant=minbase", f"--include={','.join(BASE_PACKAGES)}", SUITE, str(root), mirror],
                           capture_output=True, text=True, timeout=1800, check=False)
        if r.returncode != 0:
            last = (r.stderr or r.stdout).strip().splitlines()
            raise UserError(f"debootstrap {SUITE} from {mirror} failed: {last[-1] if last else 'no message'}")
        tar = subprocess.Popen(["tar", "-C", str(root), "-c", "."], stdout=subprocess.PIPE)
        imp = subprocess.run(podman_argv("import", "--message", f"debootstrap {SUITE} minbase + "
                                         f"{' '.join(BASE_PACKAGES)}", "-", tag),
                             stdin=tar.stdout, capture_output=True, text=True, timeout=600, check=False)
        tar.stdout.close()
        if tar.wait() != 0 or imp.returncode != 0:
            last = imp.stderr.strip().splitlines()
            raise UserError(f"podman import of the debootstrapped {SUITE} failed: {last[-1] if last else 'tar failed'}")
    dt = time.monotonic() - t0
    if log:
        log(f"base image {tag}: debootstrap + import in {dt:.0f} s (mirror {mirror})")
    return dt


def _requirements(context: Path) -> list[str]:
    pyproject = tomllib.loads((context / "pyproject.toml").read_text(encoding="utf-8"))
    return [*pyproject["project"]["dependencies"], *pyproject["build-system"]["requires"]]


def wheelhouse(context: Path, *, python: str = sys.executable, log=None) -> float:
    """Fill ``context/docker/wheels`` with wheels of the pinned dependencies and of the build backend,
    made by the host's pip (its index configuration and cache); returns wall s."""
    dest = context / "docker" / "wheels"
    dest.mkdir(parents=True, exist_ok=True)
    t0 = time.monotonic()
    r = subprocess.run([python, "-m", "pip", "wheel", "--quiet", "--wheel-dir", str(dest), *_requirements(context)],
                       capture_output=True, text=True, timeout=1800, check=False)
    if r.returncode != 0:
        last = r.stderr.strip().splitlines()
        raise UserError(f"pip wheel of the pinned dependencies failed: {last[-1] if last else 'no message'}")
    dt = time.monotonic() - t0
    if log:
        log(f"wheelhouse {dest}: {len(list(dest.glob('*.whl')))} wheels in {dt:.0f} s")
    return dt


def build_image(tag: str = IMAGE, *, base: str = BASE_IMAGE, context: Path | None = None, offline: bool = True,
                no_cache: bool = False, layers: bool = True, log=None) -> float:
    """``podman build`` docker/Dockerfile on ``base`` as ``tag``; ``offline``: no network in the
    build, dependencies from the wheelhouse only; ``layers``: keep the intermediate layers as a cache
    for the next build (without, removing ``tag`` removes everything the build made). Returns wall s."""
    context = Path(context or repo_root())
    args = ["build", *ULIMITS, "--file", str(context / "docker" / "Dockerfile"), "--tag", tag,
            "--build-arg", f"BASE={base}", f"--layers={'true' if layers else 'false'}"]
    if offline:
        args += ["--network", "none", "--build-arg", "PIP_NO_INDEX=1"]
    if no_cache:
        args.append("--no-cache")
    t0 = time.monotonic()
    podman(*args, str(context), timeout=3600)
    dt = time.monotonic() - t0
    if log:
        log(f"image {tag} (base {base}) built in {dt:.0f} s")
    return dt


def build_all(*, image: str = IMAGE, base: str = BASE_IMAGE, context: Path | None = None, rebuild_base: bool = False,
              online: bool = False, log=None) -> BuildTimes:
    """The base (when it is a ``localhost/`` image that is missing, or ``rebuild_base``), the
    wheelhouse (offline builds) and the project image."""
    context = Path(context or repo_root())
    times = BuildTimes()
    if base.startswith("localhost/") and (rebuild_base or not image_exists(base)):
        times.base_s = build_base(base, log=log)
    if not online:
        times.wheels_s = wheelhouse(context, log=log)
    times.image_s = build_image(image, base=base, context=context, offline=not online, log=log)
    return times
