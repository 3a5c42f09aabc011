"""Docker Compose file for one container per process of a ROS-engine run.

:func:`compose_project` returns the compose file (a dict, written as YAML) and the run spec every
container is started with. Services, all from one image (docker/Dockerfile) on one bridge network:

* ``clock``: the lockstep clock (orbit_clock) and the recorder; writes the bag under ``/runs`` on the
  named volume ``runs``;
* ``router`` (the DTN ISL medium), ``ground`` (ground station), and one ``sat_PS`` per satellite;

each runs ``constellation node --run-spec /run/constellation/run_spec.json --role ROLE``, the entry
the launcher (bringup/engine/ros/launcher.py) starts each local process with. The run spec is bind-mounted
read-only from beside the compose file.

Discovery: static unicast peers, not multicast and not a discovery server. Every service gets a
fixed address on the compose network (``ipv4_address`` in a declared subnet) and runs with
``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` plus ``ROS_STATIC_PEERS`` = every other service's
address. Why: (1) it is the configuration measured to work between network-namespace hosts
(tests/multihost/test_netns.py runs it), and a container is such a host; (2) it needs no multicast,
which many networks (overlay/swarm, cloud VPCs) drop, and sends nothing beyond the listed peers;
(3) a Fast DDS discovery server would be one more process whose crash stops discovery for the whole
constellation, the opposite of what the fault tests demand; (4) the peer list is N-1 addresses,
cheap at N = 24. Addresses rather than service names, because ROS_STATIC_PEERS is read once at
participant creation and must not depend on the order containers come up in DNS.

How we know it is right (tests/unit/test_docker_files.py): the files for N = 3 and N = 24 parse as
YAML and validate against a JSON schema of the compose-spec subset used (written from the compose
specification, independent of this module); every command parses with ``bringup.cli.main.build_parser()``
and names a role of the run spec, which round-trips through :class:`bringup.engine.ros.run_spec.RunSpec`; every
service's peers are exactly the other services' addresses; every volume/network used is declared.
No Docker engine runs on the build machines, so the files are not started in the tests.
"""

from __future__ import annotations

import ipaddress
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from bringup.errors import UserError
from bringup.engine.ros.run_spec import CLOCK_ROLE, RunSpec
from bringup.scenario.participants import CONTACTS_ROLE

__all__ = [
    "GROUND_ROLE",
    "IMAGE",
    "ROUTER_ROLE",
    "SPEC_IN_CONTAINER",
    "ComposeProject",
    "compose_project",
    "repo_root",
    "write_project",
]

IMAGE = "agile-dtn-constellation:0.1.0"
ROUTER_ROLE = "router"
GROUND_ROLE = "ground"
NETWORK = "constellation"
VOLUME = "runs"
RUNS_IN_CONTAINER = "/runs"
SPEC_IN_CONTAINER = "/run/constellation/run_spec.json"
SCENARIO_IN_CONTAINER = "/run/constellation/scenario.toml"
SPEC_FILE_NAME = "run_spec.json"
# Host numbers inside the subnet: .1 is Docker's gateway; clock, router, ground, contacts, then the satellites.
_FIRST_HOST = 2
_SAT_OFFSET = 10


@dataclass(frozen=True)
class ComposeProject:
    """What `constellation compose` writes: the compose document and the run spec beside it."""

    compose: dict[str, Any]
    run_spec: RunSpec
    addresses: dict[str, str]  # service name -> IPv4 address on the compose network


def repo_root() -> Path:
    """The checkout this package runs from (holds pyproject.toml and docker/Dockerfile)."""
    return Path(__file__).resolve().parents[2]


def _default_factory() -> str:
    """The ROS engine's participant factory for real runs, from the launcher when it is there."""
    try:
        from bringup.engine.ros import launcher
    except ImportError:
        launcher = None
    for attr in ("PARTICIPANT_FACTORY", "DEFAULT_FACTORY"):
        value = getattr(launcher, attr, None)
        if isinstance(value, str) and ":" in value:
            return value
    raise UserError(
        "the ROS engine's participant factory is not available (bringup.engine.ros.launcher has no "
        "PARTICIPANT_FACTORY); pass --factory module:function"
    )


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
) -> ComposeProject:
    """Compose document + run spec for the scenario with ``sats`` satellites.

    ``build_context``: the repository root as seen from the folder the compose file is written to.
    """
    from bringup.scenario.config import load_scenario

    sc = load_scenario(scenario)
    if sats is not None or hours is not None or seed is not None:
        sc = sc.with_overrides(sats=sats, hours=hours, seed=seed)
    if not 0 <= domain_id <= 101:
        raise UserError(f"--domain-id must be 0..101, got {domain_id}")
    try:
        net = ipaddress.IPv4Network(subnet, strict=True)
    except ValueError as exc:
        raise UserError(f"--subnet {subnet!r}: {exc}") from None
    sat_roles = list(sc.sat_names)
    roles = [ROUTER_ROLE, GROUND_ROLE, CONTACTS_ROLE, *sat_roles]
    services_order = [CLOCK_ROLE, *roles]
    needed = _SAT_OFFSET + len(sat_roles)
    if net.num_addresses - 2 < needed:
        raise UserError(f"--subnet {subnet} is too small for {len(services_order)} services (need "
                        f"{needed} host addresses)")
    hosts = list(net.hosts()) if net.num_addresses <= 65536 else None
    if hosts is None:
        raise UserError(f"--subnet {subnet}: use a prefix of /16 or longer")
    addresses = {CLOCK_ROLE: str(hosts[_FIRST_HOST - 1]), ROUTER_ROLE: str(hosts[_FIRST_HOST]),
                 GROUND_ROLE: str(hosts[_FIRST_HOST + 1]), CONTACTS_ROLE: str(hosts[_FIRST_HOST + 2])}
    for i, name in enumerate(sat_roles):
        addresses[name] = str(hosts[_SAT_OFFSET - 1 + i])

    scenario_path = Path(scenario)
    is_file = scenario_path.suffix == ".toml" or os.sep in scenario
    name = project_name or f"{sc.scenario.name}-{mode}-{len(sat_roles)}sats".replace("_", "-").lower()
    spec = RunSpec(
        factory=factory or _default_factory(),
        roles=roles,
        scenario=SCENARIO_IN_CONTAINER if is_file else scenario,
        overrides={"sats": len(sat_roles), "hours": hours},
        mode=mode,
        seed=sc.scenario.seed,
        bag_dir=f"{RUNS_IN_CONTAINER}/{name}/bag",
        # 24 containers importing numpy/numba/rclpy at once come up slower than local processes.
        startup_timeout_s=180.0,
    )
    spec.check("compose run spec")

    mounts_common = [f"./{SPEC_FILE_NAME}:{SPEC_IN_CONTAINER}:ro"]
    if is_file:
        mounts_common.append(f"{scenario_path.resolve()}:{SCENARIO_IN_CONTAINER}:ro")
    services: dict[str, Any] = {}
    for svc in services_order:
        peers = ";".join(addresses[o] for o in services_order if o != svc)
        service: dict[str, Any] = {
            "image": IMAGE,
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
        }
        if svc == CLOCK_ROLE:
            # The one service that builds the image; the others reuse it and never pull it.
            service["build"] = {"context": build_context, "dockerfile": "docker/Dockerfile"}
            service["volumes"].append(f"{VOLUME}:{RUNS_IN_CONTAINER}")
        else:
            service["pull_policy"] = "never"
            service["depends_on"] = [CLOCK_ROLE]
        services[svc] = service
    compose = {
        "name": name,
        "services": services,
        "networks": {NETWORK: {"driver": "bridge", "ipam": {"config": [{"subnet": str(net)}]}}},
        "volumes": {VOLUME: {}},
    }
    return ComposeProject(compose=compose, run_spec=spec, addresses=addresses)


_HEADER = """\
# Generated by `constellation compose` (bringup/deploy/compose.py); regenerate rather than edit.
# One container per process of a ROS-engine run: clock (+ recorder, volume '{volume}'), router, ground
# station, contact-window announcer and {n} satellites, on network '{network}' ({subnet}). Discovery: static unicast peers
# (ROS_STATIC_PEERS = every other service's fixed address, ROS_DOMAIN_ID={domain}); no multicast, no
# discovery server (a single point of failure). See docker/README.md.
#   docker compose -f {file} build && docker compose -f {file} up
"""


def write_project(project: ComposeProject, out: Path) -> list[Path]:
    """Write the compose file at ``out`` and the run spec beside it; return both paths."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    net = project.compose["networks"][NETWORK]["ipam"]["config"][0]["subnet"]
    clock_env = project.compose["services"][CLOCK_ROLE]["environment"]
    header = _HEADER.format(volume=VOLUME, n=len(project.run_spec.roles) - 3, network=NETWORK, subnet=net,
                            domain=clock_env["ROS_DOMAIN_ID"], file=out.name)
    text = header + yaml.safe_dump(project.compose, sort_keys=False, default_flow_style=False, width=110)
    out.write_text(text, encoding="utf-8")
    spec_path = out.parent / SPEC_FILE_NAME
    project.run_spec.to_file(spec_path)
    return [out, spec_path]
