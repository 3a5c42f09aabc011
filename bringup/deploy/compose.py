"""Docker Compose file for one container per process of a ROS-engine run.

:func:`compose_project` returns the compose file (a dict, written as YAML), the run spec every
container is started with and the run's world (orbits, access, contact plans: one pickle every
process loads, as the local launcher's processes do). Services, all from one image
(docker/Dockerfile) on one internal bridge network:

* ``clock``: the lockstep clock and the recorder; writes the bag, then ``report.json`` and
  ``report.md``, under ``/runs/<project>/`` on the named volume ``runs``;
* the run's other roles (bringup/scenario/participants.py ``roles_for``): ``router`` (the DTN ISL
  medium, distributed mode) or ``ground`` (the ground segment, centralized mode), and one
  ``sat_PS`` per satellite, whose bundle stores (and, with ``restart``, checkpoints) are on the
  same volume;

each runs ``constellation node --run-spec /run/constellation/run_spec.json --role ROLE``, the entry
the launcher (bringup/engine/ros/launcher.py) starts each local process with. The run spec, the
world and the run's keys (``run.keys``: the run key that authenticates every envelope and the
BPSec key, bringup/engine/keys.py; mode 0600, owned by the image's user) are bind-mounted
read-only from beside the compose file. With ``restart = N`` every service
has the restart policy ``on-failure:N``: a process killed inside its container ends the container,
the engine restarts it, and it resumes from its checkpoint while the clock waits for it by name (the
guarantees of ``constellation run --restart``, bringup/engine/checkpoint.py).

Discovery: static unicast peers, not multicast and not a discovery server. Every service gets a
fixed address on the compose network (``ipv4_address`` in a declared subnet) and runs with
``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` plus ``ROS_STATIC_PEERS`` = every other service's
address. Why: (1) it is the configuration measured to work between network-namespace hosts
(tests/multihost/test_netns.py runs it), and a container is such a host; (2) it needs no multicast,
which many networks (overlay/swarm, cloud VPCs) drop, and sends nothing beyond the listed peers;
(3) a Fast DDS discovery server would be one more process whose crash stops discovery for the whole
constellation, the opposite of what the fault tests demand; (4) the peer list is N-1 addresses,
cheap at N = 24. Addresses rather than service names, because ROS_STATIC_PEERS is read once at
participant creation and must not depend on the order containers come up in DNS. The network is
``internal`` (no gateway off the bridge), so nothing a container sends leaves the machine.

How we know it is right: tests/unit/test_docker_files.py validates the files for N = 3 and N = 24
against a JSON schema of the compose-spec subset used (written from the compose specification,
independent of this module), parses every command with the CLI's parser, checks the run spec's
roles against ``roles_for`` and every service's peers against the other services' addresses;
tests/containers/ run the file for real (podman, and podman-compose) and compare the run's
observations and bundle deliveries with the local engine's.
"""

from __future__ import annotations

import ipaddress
import os
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from bringup.engine.keys import KEYS_FILE_NAME, RunKeys
from bringup.engine.ros.factory import FACTORY, PREPARE
from bringup.engine.ros.run_spec import CLOCK_ROLE, MAX_DOMAIN_ID, RunSpec
from bringup.errors import UserError
from bringup.scenario.config import load_scenario
from bringup.scenario.participants import CONTACTS_ROLE, GROUND_ROLE, ROUTER_ROLE, roles_for
from bringup.scenario.world import World

__all__ = [
    "GROUND_ROLE",
    "IMAGE",
    "RESTART_WAIT_S",
    "ROUTER_ROLE",
    "SPEC_IN_CONTAINER",
    "ComposeProject",
    "compose_project",
    "repo_root",
    "write_project",
]

IMAGE = "localhost/agile-dtn-constellation:0.1.0"
_NON_SAT = (ROUTER_ROLE, GROUND_ROLE, CONTACTS_ROLE)
NETWORK = "constellation"
VOLUME = "runs"
RUNS_IN_CONTAINER = "/runs"
SPEC_IN_CONTAINER = "/run/constellation/run_spec.json"
SCENARIO_IN_CONTAINER = "/run/constellation/scenario.toml"
WORLD_IN_CONTAINER = "/run/constellation/world.pkl"
KEYS_IN_CONTAINER = "/run/constellation/run.keys"
SPEC_FILE_NAME = "run_spec.json"
# The image's user (docker/Dockerfile `useradd --uid`): it must own the run keys inside the container.
IMAGE_UID = 10001
WORLD_FILE_NAME = "world.pkl"
# Host numbers inside the subnet: .1 is the bridge's gateway; clock, router, ground, contacts, then the satellites.
_FIRST_HOST = 2
_SAT_OFFSET = 10
# Wall seconds the clock waits for a silent host that its restart policy brings back (as `run --restart`).
RESTART_WAIT_S = 120.0


@dataclass(frozen=True)
class ComposeProject:
    """What `constellation compose` writes: the compose document, the run spec and the world beside it."""

    compose: dict[str, Any]
    run_spec: RunSpec
    addresses: dict[str, str]  # service name -> IPv4 address on the compose network
    world: Any = None  # bringup.scenario.world.World, pickled beside the compose file
    keys: RunKeys | None = None  # the run's keys (bringup/engine/keys.py), written beside it (mode 0600)

    @property
    def name(self) -> str:
        return self.compose["name"]

    @property
    def run_dir(self) -> str:
        """The run's folder inside the containers (on the ``runs`` volume): bag/, report.json, ..."""
        return f"{RUNS_IN_CONTAINER}/{self.name}"


def repo_root() -> Path:
    """The checkout this package runs from (holds pyproject.toml and docker/Dockerfile)."""
    return Path(__file__).resolve().parents[2]


def compose_project(
    *,
    scenario: str = "paper",
    sats: int | None = None,
    hours: float | None = None,
    seed: int | None = None,
    mode: str = "distributed",
    domain_id: int = 7,
    subnet: str = "10.231.0.0/24",
    factory: str | None = None,
    build_context: str = "..",
    project_name: str | None = None,
    image: str = IMAGE,
    restart: int = 0,
    router_kw: dict | None = None,
    ack_timeout_s: float = 30.0,
    meta: Callable[[Any, str], dict] | None = None,
    real_time_factor: float | None = None,
    keys: RunKeys | None = None,
) -> ComposeProject:
    """Compose document + run spec for the scenario with ``sats`` satellites.

    ``build_context``: the repository root as seen from the folder the compose file is written to.
    ``restart``: > 0 gives every service the restart policy ``on-failure:N`` and the run the
    checkpoints that let a restarted process resume (the clock waits ``RESTART_WAIT_S`` for it).
    ``router_kw``: the DTN router's extra delay and ISL cuts (``constellation run --isl-delay-s/--cut``).
    ``meta(world, mode)``: the run's ``/run/meta`` record (bringup/analysis/report.py ``RunMeta``);
    with it the clock also writes report.json / report.md next to the bag.
    ``keys``: the run's keys (default: a new run key and the deployment's BPSec key,
    bringup/engine/keys.py), mounted read-only into every container as the run spec is.
    """
    sc = load_scenario(scenario)
    if sats is not None or hours is not None or seed is not None:
        sc = sc.with_overrides(sats=sats, hours=hours, seed=seed)
    if sc.commands:
        raise UserError(f"scenario {sc.name}: [[commands]] are not deployed by compose (no command gateway "
                        "container); run them with `constellation run`")
    if not 0 <= domain_id <= MAX_DOMAIN_ID:
        raise UserError(f"--domain-id {domain_id}: expected 0..{MAX_DOMAIN_ID}")
    if restart < 0:
        raise UserError(f"--restart must be >= 0, got {restart}")
    try:
        net = ipaddress.IPv4Network(subnet, strict=True)
    except ValueError as exc:
        raise UserError(f"--subnet {subnet!r}: {exc}") from None
    if factory is not None and ":" not in factory:
        raise UserError(f"--factory must be 'module:function', got {factory!r}")
    sat_roles = list(sc.sat_names)
    others = [r for r in roles_for(sat_roles, mode) if r not in sat_roles]
    roles = [*others, *sat_roles]
    services_order = [CLOCK_ROLE, *roles]
    needed = _SAT_OFFSET + len(sat_roles)
    if net.num_addresses - 2 < needed:
        raise UserError(f"--subnet {subnet} is too small for {len(services_order)} services (need "
                        f"{needed} host addresses)")
    if net.num_addresses > 65536:
        raise UserError(f"--subnet {subnet}: use a prefix of /16 or longer")
    hosts = list(net.hosts())
    addresses = {CLOCK_ROLE: str(hosts[_FIRST_HOST - 1]), ROUTER_ROLE: str(hosts[_FIRST_HOST]),
                 GROUND_ROLE: str(hosts[_FIRST_HOST + 1]), CONTACTS_ROLE: str(hosts[_FIRST_HOST + 2])}
    for i, name in enumerate(sat_roles):
        addresses[name] = str(hosts[_SAT_OFFSET - 1 + i])
    addresses = {r: addresses[r] for r in services_order}

    scenario_path = Path(scenario)
    is_file = scenario_path.suffix == ".toml" or os.sep in scenario
    name = project_name or f"{sc.scenario.name}-{mode}-{len(sat_roles)}sats".replace("_", "-").lower()
    world = World.build(sc)
    run_dir = f"{RUNS_IN_CONTAINER}/{name}"
    spec = RunSpec(
        factory=factory or FACTORY,
        # each process loads its numba kernels (compiled into the image's cache) before it is ready
        prepare=None if factory else PREPARE,
        roles=roles,
        scenario=SCENARIO_IN_CONTAINER if is_file else scenario,
        overrides={"sats": len(sat_roles), "hours": hours, "seed": seed},
        mode=mode,
        seed=sc.scenario.seed,
        bag_dir=f"{run_dir}/bag",
        # containers on a loaded machine answer slower than local processes; the clock names a host
        # silent for this long (after the start, where every container imports numpy/numba/rclpy)
        ack_timeout_s=ack_timeout_s,
        startup_timeout_s=180.0,
        real_time_factor=real_time_factor,
        max_restarts=restart,
        restart_wait_s=RESTART_WAIT_S if restart else 0.0,
        state_dir=f"{run_dir}/state" if restart else None,
        keys_file=KEYS_IN_CONTAINER,
        domain_id=domain_id,
        extra={"world": WORLD_IN_CONTAINER, "world_key": world.key, "store_dir": f"{run_dir}/store",
               "router": router_kw or None},
    )
    if meta is not None:  # the bag's /run/meta record, and so the clock's report at the end
        spec.extra.update(meta=meta(world, mode), report_dir=run_dir)
    spec.check("compose run spec")

    mounts_common = [f"./{SPEC_FILE_NAME}:{SPEC_IN_CONTAINER}:ro", f"./{WORLD_FILE_NAME}:{WORLD_IN_CONTAINER}:ro",
                     f"./{KEYS_FILE_NAME}:{KEYS_IN_CONTAINER}:ro", f"{VOLUME}:{RUNS_IN_CONTAINER}"]
    if is_file:
        mounts_common.append(f"{scenario_path.resolve()}:{SCENARIO_IN_CONTAINER}:ro")
    services: dict[str, Any] = {}
    for svc in services_order:
        peers = ";".join(addresses[o] for o in services_order if o != svc)
        service: dict[str, Any] = {
            "image": image,
            "command": ["constellation", "node", "--run-spec", SPEC_IN_CONTAINER, "--role", svc],
            "environment": {
                "ROS_DOMAIN_ID": str(domain_id),
                "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
                "ROS_STATIC_PEERS": peers,
            },
            "volumes": list(mounts_common),
            "networks": {NETWORK: {"ipv4_address": addresses[svc]}},
            "hostname": svc.replace("_", "-"),
            "init": True,
            "stop_grace_period": "10s",
            "ulimits": {"nofile": {"soft": 4096, "hard": 4096}, "nproc": {"soft": 4096, "hard": 4096}},
        }
        if restart:
            service["restart"] = f"on-failure:{restart}"
        if svc == CLOCK_ROLE:
            # The one service that builds the image; the others reuse it and never pull it.
            service["build"] = {"context": build_context, "dockerfile": "docker/Dockerfile"}
        else:
            service["pull_policy"] = "never"
            service["depends_on"] = [CLOCK_ROLE]
        services[svc] = service
    compose = {
        "name": name,
        "services": services,
        # internal: no route off the bridge (no NAT, no gateway out); DDS sends only to the listed peers
        "networks": {NETWORK: {"driver": "bridge", "internal": True, "ipam": {"config": [{"subnet": str(net)}]}}},
        "volumes": {VOLUME: {}},
    }
    return ComposeProject(compose=compose, run_spec=spec, addresses=addresses, world=world,
                          keys=keys or RunKeys.generate())


_HEADER = """\
# Generated by `constellation compose` (bringup/deploy/compose.py); regenerate rather than edit.
# One container per process of a ROS-engine run: clock (+ recorder; bag and report on volume '{volume}'),
# {others}{n} satellites, on the internal network '{network}' ({subnet}). Discovery: static unicast
# peers (ROS_STATIC_PEERS = every other service's fixed address, ROS_DOMAIN_ID={domain}); no multicast,
# no discovery server (a single point of failure). See docker/README.md.
#   docker compose -f {file} build && docker compose -f {file} up --abort-on-container-exit --exit-code-from clock
"""


def write_project(project: ComposeProject, out: Path) -> list[Path]:
    """Write the compose file at ``out``, the run spec and the world beside it; return the paths."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    net = project.compose["networks"][NETWORK]["ipam"]["config"][0]["subnet"]
    clock_env = project.compose["services"][CLOCK_ROLE]["environment"]
    sats = [r for r in project.run_spec.roles if r not in _NON_SAT]
    others = "".join(f"{r}, " for r in project.run_spec.roles if r in _NON_SAT)
    header = _HEADER.format(volume=VOLUME, others=others, n=len(sats), network=NETWORK, subnet=net,
                            domain=clock_env["ROS_DOMAIN_ID"], file=out.name)
    text = header + yaml.safe_dump(project.compose, sort_keys=False, default_flow_style=False, width=110)
    out.write_text(text, encoding="utf-8")
    spec_path = out.parent / SPEC_FILE_NAME
    project.run_spec.to_file(spec_path)
    paths = [out, spec_path]
    if project.world is not None:
        paths.append(project.world.save(out.parent / WORLD_FILE_NAME))
    if project.keys is not None:
        paths.append(_write_keys(project.keys, out.parent / KEYS_FILE_NAME))
    return paths


def _write_keys(keys: RunKeys, path: Path) -> Path:
    """The run's keys beside the compose file, mode 0600, owned by the image's user (uid
    ``IMAGE_UID``) when we may give it away (root, as rootful podman/docker need anyway);
    otherwise the file stays ours and stderr says how to hand it over."""
    keys.write(path)
    if os.geteuid() == 0:
        os.chown(path, IMAGE_UID, IMAGE_UID)
    elif os.geteuid() != IMAGE_UID:
        print(f"compose: {path} (mode 600) must be owned by the containers' user, uid {IMAGE_UID}: "
              f"`sudo chown {IMAGE_UID} {path}` (rootless podman: `podman unshare chown {IMAGE_UID} {path}`)",
              file=sys.stderr)
    return path
