"""Fixtures of the container tests (marker ``containers``; root, podman: scripts/setup_containers.sh).

* ``images`` (session): a base image debootstrapped from Debian packages and the project image on it,
  both with tags unique to this test session, built cold once and removed at the end (also when a
  test failed); the build's wall times are printed in one ``CONTAINERS build`` line.
* ``lab`` (function): run-unique compose projects (name, subnet, ROS domain) in a temporary folder;
  at the end every container, network and volume labelled with its projects is removed and the
  test fails if anything labelled is left, or a new anonymous volume or podman network namespace.
* ``local_ref`` (session): the 12-satellite, 1-h local-engine run the container runs must equal.

Nothing here reaches a registry: the base comes from the Debian mirror apt uses, the wheels from the
host's pip; the containers sit on ``--internal`` networks the tests create and remove.
"""

from __future__ import annotations

import ipaddress
import json
import os
import random
import shutil
import subprocess
import sys
import time
import uuid
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
SATS, HOURS = 12, 1.0
RUN_ID = f"{os.getpid():x}{uuid.uuid4().hex[:6]}"


def _require_tools() -> None:
    missing = [t for t in ("podman", "debootstrap", "iptables-legacy", "nsenter", "tc") if shutil.which(t) is None]
    if missing:
        pytest.fail(f"the container tests need {', '.join(missing)}: run `bash scripts/setup_containers.sh "
                    "--packages-only` as root first", pytrace=False)
    if os.geteuid() != 0:
        pytest.fail("the container tests run as root (podman networks, nsenter, iptables in the containers' "
                    "namespaces)", pytrace=False)


@pytest.fixture(scope="session")
def images():
    from bringup.deploy.images import build_base, build_image, image_exists, remove_image, wheelhouse

    _require_tools()
    base = f"localhost/cdtn-test-{RUN_ID}-base:bookworm"
    image = f"localhost/cdtn-test-{RUN_ID}:img"
    times = {}
    try:
        times["base_s"] = build_base(base)
        times["wheels_s"] = wheelhouse(REPO)
        times["image_s"] = build_image(image, base=base, context=REPO, layers=False)
        print(f"\nCONTAINERS build {json.dumps({k: round(v, 1) for k, v in times.items()})}")
        yield {"image": image, "base": base, "times": times}
    finally:
        for tag in (image, base):
            remove_image(tag)
        left = [t for t in (image, base) if image_exists(t)]
        assert not left, f"images left behind: {left}"


def _used_subnets() -> set[str]:
    from bringup.deploy.podman import podman_json

    nets = podman_json("network", "ls")
    used = {s.get("subnet") for n in nets for s in (n.get("subnets") or [])}
    routes = subprocess.run(["ip", "-4", "route"], capture_output=True, text=True, check=False).stdout
    used |= {ln.split()[0] for ln in routes.splitlines() if ln and ln[0].isdigit()}
    return {u for u in used if u}


class Lab:
    """Run-unique compose projects of one test, all removed at the end."""

    def __init__(self, tmp: Path, image: str):
        self.tmp, self.image = tmp, image
        self.projects: list[str] = []

    def subnet(self, name: str) -> str:
        """A 10.231.x.0/24 that no podman network and no host route uses."""
        used = _used_subnets()
        rng = random.Random(name)
        for _ in range(200):
            net = f"10.231.{rng.randrange(100, 250)}.0/24"
            if not any(ipaddress.ip_network(net).overlaps(ipaddress.ip_network(u, strict=False)) for u in used):
                return net
        raise RuntimeError("no free 10.231.x.0/24 subnet")

    def compose(self, tag: str, *args: str, sats: int = SATS, hours: float = HOURS) -> Path:
        from bringup.cli.main import main

        name = f"cdtn-{RUN_ID}-{tag}"
        net = self.subnet(name)
        rng = random.Random(name)
        out = self.tmp / tag / "docker-compose.yml"
        rc = main(["compose", "--sats", str(sats), "--hours", str(hours), "--out", str(out), "--name", name,
                   "--subnet", net, "--domain-id", str(rng.randrange(1, 101)), "--image", self.image, *args])
        assert rc == 0
        self.projects.append(name)
        return out

    def leftovers(self) -> dict:
        from bringup.deploy.containers import leftovers

        out: dict[str, list[str]] = {}
        for p in self.projects:
            for kind, names in leftovers(p).items():
                out.setdefault(kind, []).extend(names)
        return {k: v for k, v in out.items() if v}


def _netns() -> set[str]:
    """podman's network namespaces (``netns-<uuid>``; other tests' namespaces are not ours to judge)."""
    r = subprocess.run(["ip", "netns", "list"], capture_output=True, text=True, check=False)
    return {ln.split()[0] for ln in r.stdout.splitlines() if ln.startswith("netns-")}


def _dangling_volumes() -> set[str]:
    from bringup.deploy.podman import podman

    return set(podman("volume", "ls", "--quiet", "--filter", "dangling=true").stdout.decode().split())


@pytest.fixture
def lab(images, tmp_path):
    from bringup.deploy.containers import down

    before = _netns()
    volumes_before = _dangling_volumes()
    lb = Lab(tmp_path, images["image"])
    try:
        yield lb
    finally:
        for p in lb.projects:
            down(p)
    assert not lb.leftovers(), f"left behind: {lb.leftovers()}"
    assert not (_dangling_volumes() - volumes_before), f"anonymous volumes left: {_dangling_volumes() - volumes_before}"
    deadline = time.monotonic() + 10
    while _netns() - before and time.monotonic() < deadline:
        time.sleep(0.5)
    assert not (_netns() - before), f"network namespaces left behind: {_netns() - before}"


def local_run(out: Path, *extra: str) -> Path:
    cmd = [sys.executable, "-m", "bringup.cli", "run", "--engine", "local", "--sats", str(SATS), "--hours",
           str(HOURS), "--out", str(out), "--no-plots", "--no-progress", *extra]
    r = subprocess.run(cmd, check=False, capture_output=True, text=True, timeout=900, cwd=REPO)
    assert r.returncode == 0, r.stderr[-3000:]
    return out


@pytest.fixture(scope="session")
def local_ref(tmp_path_factory):
    return local_run(tmp_path_factory.mktemp("local") / "local")


def traces(run_dir: Path) -> tuple[list, list]:
    from bringup.analysis.trace import deliveries_from_bag, observations_from_bag

    return observations_from_bag(run_dir / "bag"), deliveries_from_bag(run_dir / "bag")


def accounting(run_dir: Path) -> dict:
    from bringup.analysis.report import report_from_bag

    d = report_from_bag(run_dir / "bag")["dtn"]
    dropped = sum(v for v in d.get("dropped", {}).values() if isinstance(v, int))
    return {"created": d["bundles_created"], "delivered": d["bundles_delivered"], "dropped": dropped,
            "held": d.get("held_at_end", 0)}
