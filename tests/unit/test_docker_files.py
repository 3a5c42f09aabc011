"""Static checks of docker/ and `constellation compose` (no Docker engine on the build machines; the
files run for real under podman in tests/containers/).

Oracles, independent of bringup/deploy/compose.py:
* COMPOSE_SUBSET_SCHEMA below: a JSON schema of the part of the Compose Specification
  (compose-spec/compose-spec, schema/compose-spec.json) the generated files use, with the spec's
  key patterns and types and ``additionalProperties: false`` (a key outside the subset, or a typo,
  fails). Checked with jsonschema (draft 7, as the spec's own schema).
* the project's CLI parser (``bringup.cli.main.build_parser()``): every service's command must parse;
* RunSpec.from_file: the run spec written beside the compose file loads, and its roles are exactly
  the services that are not the clock;
* the file system: every Dockerfile COPY source exists in the build context, and the packages
  pyproject.toml installs are all copied.
"""

from __future__ import annotations

import ipaddress
import json
import re
import tomllib
from pathlib import Path

import jsonschema
import pytest
import yaml

from bringup.cli.main import build_parser, main
from bringup.engine.ros.run_spec import CLOCK_ROLE, RunSpec

REPO = Path(__file__).resolve().parents[2]
DOCKERFILE = REPO / "docker" / "Dockerfile"
NAME = "^[a-zA-Z0-9._-]+$"

_string_list = {"type": "array", "items": {"type": "string"}}
COMPOSE_SUBSET_SCHEMA = {
    "$schema": "http://json-schema.org/draft-07/schema#",
    "type": "object",
    "required": ["services"],
    "properties": {
        "name": {"type": "string", "pattern": "^[a-z0-9][a-z0-9_-]*$"},
        "services": {
            "type": "object",
            "minProperties": 1,
            "patternProperties": {NAME: {"$ref": "#/definitions/service"}},
            "additionalProperties": False,
        },
        "networks": {
            "type": "object",
            "patternProperties": {NAME: {"$ref": "#/definitions/network"}},
            "additionalProperties": False,
        },
        "volumes": {
            "type": "object",
            "patternProperties": {NAME: {"type": ["object", "null"]}},
            "additionalProperties": False,
        },
    },
    "patternProperties": {"^x-": {}},
    "additionalProperties": False,
    "definitions": {
        "service": {
            "type": "object",
            "anyOf": [{"required": ["image"]}, {"required": ["build"]}],
            "required": ["command"],
            "properties": {
                "image": {"type": "string"},
                "build": {
                    "oneOf": [
                        {"type": "string"},
                        {
                            "type": "object",
                            "properties": {"context": {"type": "string"}, "dockerfile": {"type": "string"}},
                            "additionalProperties": False,
                        },
                    ]
                },
                "command": {**_string_list, "minItems": 1},  # the exec form; this project never uses a shell
                "environment": {
                    "type": "object",
                    "patternProperties": {".+": {"type": ["string", "number", "boolean", "null"]}},
                    "additionalProperties": False,
                },
                "volumes": {**_string_list, "uniqueItems": True},
                "networks": {
                    "oneOf": [
                        {**_string_list, "uniqueItems": True},
                        {
                            "type": "object",
                            "patternProperties": {
                                NAME: {
                                    "type": ["object", "null"],
                                    "properties": {"ipv4_address": {"type": "string", "format": "ipv4"}},
                                    "additionalProperties": False,
                                }
                            },
                            "additionalProperties": False,
                        },
                    ]
                },
                "depends_on": {**_string_list, "uniqueItems": True},
                "hostname": {"type": "string", "pattern": "^[a-zA-Z0-9-]+$"},
                "init": {"type": "boolean"},
                "stop_grace_period": {"type": "string", "pattern": "^[0-9]+(ms|s|m|h)$"},
                "pull_policy": {"type": "string", "enum": ["always", "never", "if_not_present", "build",
                                                           "missing"]},
                "restart": {"type": "string", "pattern": "^(no|always|unless-stopped|on-failure(:[0-9]+)?)$"},
                "ulimits": {
                    "type": "object",
                    "patternProperties": {
                        "^[a-z]+$": {
                            "oneOf": [
                                {"type": "integer"},
                                {"type": "object", "required": ["soft", "hard"],
                                 "properties": {"soft": {"type": "integer"}, "hard": {"type": "integer"}},
                                 "additionalProperties": False},
                            ]
                        }
                    },
                    "additionalProperties": False,
                },
            },
            "additionalProperties": False,
        },
        "network": {
            "type": ["object", "null"],
            "properties": {
                "driver": {"type": "string"},
                "internal": {"type": "boolean"},
                "ipam": {
                    "type": "object",
                    "properties": {
                        "driver": {"type": "string"},
                        "config": {
                            "type": "array",
                            "items": {
                                "type": "object",
                                "properties": {"subnet": {"type": "string"}, "gateway": {"type": "string"}},
                                "additionalProperties": False,
                            },
                        },
                    },
                    "additionalProperties": False,
                },
            },
            "additionalProperties": False,
        },
    },
}


def _write(tmp_path: Path, n_sats: int, *extra: str) -> tuple[dict, Path]:
    out = tmp_path / f"n{n_sats}" / "docker-compose.yml"
    rc = main(["compose", "--sats", str(n_sats), "--scenario", "paper", "--hours", "1", "--out", str(out), *extra])
    assert rc == 0
    return yaml.safe_load(out.read_text(encoding="utf-8")), out


def _named_volumes(service: dict) -> list[str]:
    return [v.split(":")[0] for v in service.get("volumes", []) if not v.startswith(("/", "."))]


@pytest.mark.parametrize("n_sats", [3, 24])
def test_compose_file_is_valid_and_complete(tmp_path, n_sats):
    doc, out = _write(tmp_path, n_sats)
    jsonschema.Draft7Validator(COMPOSE_SUBSET_SCHEMA,
                               format_checker=jsonschema.Draft7Validator.FORMAT_CHECKER).validate(doc)
    services = doc["services"]
    sats = [s for s in services if s.startswith("sat_")]
    # distributed: clock, router, contact-window announcer, satellites
    assert len(sats) == n_sats and len(services) == n_sats + 3
    assert {CLOCK_ROLE, "router", "contacts"} <= set(services)

    spec = RunSpec.from_file(out.parent / "run_spec.json")
    assert sorted(spec.roles) == sorted(s for s in services if s != CLOCK_ROLE)
    assert spec.overrides["sats"] == n_sats
    assert spec.bag_dir and spec.bag_dir.startswith("/runs/")
    # the ROS engine's own factory and roles (the file runs as written, with no --factory)
    from bringup.engine.ros.factory import FACTORY
    from bringup.scenario.participants import roles_for
    from bringup.scenario.world import World

    assert spec.factory == FACTORY
    world = World.load(out.parent / "world.pkl", spec.extra["world_key"])
    assert sorted(spec.roles) == sorted(roles_for(world, "distributed")) and len(world.sat_names) == n_sats
    assert spec.extra["world"] in {v.split(":")[1] for v in services[CLOCK_ROLE]["volumes"]}
    assert spec.extra["store_dir"].startswith("/runs/") and spec.extra["report_dir"].startswith("/runs/")
    assert doc["networks"]["constellation"]["internal"] is True

    # every image is built by some service (the others never pull it)
    built = {s["image"] for s in services.values() if "build" in s}
    assert built and all(s["image"] in built for s in services.values())
    ctx = (out.parent / services[CLOCK_ROLE]["build"]["context"]).resolve()
    assert (ctx / services[CLOCK_ROLE]["build"]["dockerfile"]).resolve() == DOCKERFILE.resolve()

    # declared networks/volumes cover every use; the recorder (clock) has the runs volume
    for s in services.values():
        assert set(s["networks"]) <= set(doc["networks"])
        assert set(_named_volumes(s)) <= set(doc.get("volumes", {}))
        for dep in s.get("depends_on", []):
            assert dep in services
        for v in s["volumes"]:
            if v.startswith("./"):
                assert (out.parent / v.split(":")[0]).exists(), v
    assert all(any(v.endswith(":/runs") for v in s["volumes"]) for s in services.values())

    # addresses: unique, inside the declared subnet; peers = exactly every other service's address
    net = ipaddress.IPv4Network(doc["networks"]["constellation"]["ipam"]["config"][0]["subnet"])
    addr = {n: s["networks"]["constellation"]["ipv4_address"] for n, s in services.items()}
    assert len(set(addr.values())) == len(addr)
    assert all(ipaddress.IPv4Address(a) in net and a != str(next(net.hosts())) for a in addr.values())
    domains = {s["environment"]["ROS_DOMAIN_ID"] for s in services.values()}
    assert len(domains) == 1 and 0 <= int(domains.pop()) <= 101
    for n, s in services.items():
        env = s["environment"]
        assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
        assert sorted(env["ROS_STATIC_PEERS"].split(";")) == sorted(a for m, a in addr.items() if m != n)


def test_compose_run_meta_is_the_runs(tmp_path):
    """A container run's /run/meta (so its report.json) has what `run` gives: the knowledge model and
    the OSSE figures included (compose built it by hand before and lost them)."""
    from bringup.analysis.report import RunMeta
    from bringup.scenario.config import load_scenario
    from bringup.scenario.world import World, scenario_key

    _, out = _write(tmp_path, 3)
    spec = RunSpec.from_file(out.parent / "run_spec.json")
    world = World.load(out.parent / "world.pkl", spec.extra["world_key"])
    want = RunMeta.for_world(world, "distributed", "ros").__dict__
    got = dict(spec.extra["meta"])
    prov = got.pop("provenance")  # and the same provenance as a run's (bringup/scenario/provenance.py)
    assert got == json.loads(json.dumps({k: v for k, v in want.items() if k != "provenance"}))
    assert spec.extra["meta"]["knowledge"] and spec.extra["meta"]["osse"]
    assert prov["command"].startswith("constellation compose --sats 3") and prov["seed"] == world.scenario.scenario.seed
    back = load_scenario(_text_file(tmp_path / "back.toml", prov["scenario_toml"]))
    assert scenario_key(back) == scenario_key(world.scenario)


def _text_file(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


@pytest.mark.parametrize("n_sats", [3, 24])
def test_every_command_is_a_real_subcommand(tmp_path, n_sats):
    doc, out = _write(tmp_path, n_sats)
    spec = RunSpec.from_file(out.parent / "run_spec.json")
    parser = build_parser()
    node_mod = "bringup.cli.node"
    try:
        __import__(node_mod)
    except ModuleNotFoundError as exc:
        if exc.name == node_mod:
            pytest.skip("bringup/cli/node.py (the ROS engine's process entry) has not landed yet")
        raise
    for name, s in doc["services"].items():
        argv = s["command"]
        assert argv[0] == "constellation", argv  # the console script of pyproject [project.scripts]
        args = parser.parse_args(argv[1:])  # argparse exits (SystemExit) on anything it does not accept
        assert args.command == "node"
        assert args.role == name
        assert args.role == CLOCK_ROLE or args.role in spec.roles
        mounted = {v.split(":")[1] for v in s["volumes"]}
        assert str(args.run_spec) in mounted


def test_compose_restart_and_router_options(tmp_path):
    doc, out = _write(tmp_path, 3, "--restart", "2", "--isl-delay-s", "30", "--cut", "sat_11-sat_21@600-1200",
                      "--mode", "centralized")
    spec = RunSpec.from_file(out.parent / "run_spec.json")
    assert spec.max_restarts == 2 and spec.restart_wait_s > 0 and spec.state_dir.startswith("/runs/")
    assert all(s["restart"] == "on-failure:2" for s in doc["services"].values())
    assert spec.extra["router"] == {"extra_delay_s": 30.0, "cuts": [["sat_11", "sat_21", 600.0, 1200.0]]}
    assert "ground" in doc["services"] and "router" not in doc["services"]
    doc0, out0 = _write(tmp_path / "plain", 3)
    assert all("restart" not in s for s in doc0["services"].values())
    assert RunSpec.from_file(out0.parent / "run_spec.json").state_dir is None


def test_compose_rejects_bad_options(tmp_path, capsys):
    out = str(tmp_path / "c.yml")
    base = ["compose", "--sats", "3", "--out", out, "--factory", "a:b"]
    assert main([*base, "--domain-id", "300"]) == 2
    assert "--domain-id" in capsys.readouterr().err
    assert main([*base, "--subnet", "10.0.0.1/24"]) == 2  # host bits set
    assert "--subnet" in capsys.readouterr().err
    assert main(["compose", "--sats", "24", "--out", out, "--factory", "a:b", "--subnet", "10.1.0.0/28"]) == 2
    assert "too small" in capsys.readouterr().err
    assert main([*base, "--factory", "nocolon"]) == 2
    assert main([*base, "--cut", "sat_11-sat_99@1-2"]) == 2
    assert "sat_99" in capsys.readouterr().err
    assert not Path(out).exists()


def _dockerfile_instructions() -> list[tuple[str, str]]:
    text = DOCKERFILE.read_text(encoding="utf-8")
    joined = re.sub(r"\\\n", " ", "\n".join(ln for ln in text.splitlines() if not ln.lstrip().startswith("#")))
    return [(m.group(1).upper(), m.group(2).strip())
            for m in re.finditer(r"^\s*([A-Za-z]+)\s+(.*)$", joined, re.MULTILINE)]


def test_dockerfile_installs_the_project_from_existing_files():
    ins = _dockerfile_instructions()
    # the base is a build argument, python:3.11-slim by default (bringup/deploy/images.py passes the
    # Debian-built one)
    assert ins[0] == ("ARG", "BASE=python:3.11-slim") and ins[1] == ("FROM", "${BASE}")
    copied = []
    for op, arg in ins:
        assert op != "ADD", "use COPY (ADD fetches URLs and unpacks archives)"
        if op == "RUN" and arg.startswith("--mount="):
            opts = dict(kv.split("=", 1) for kv in arg.split()[0].removeprefix("--mount=").split(","))
            assert opts["type"] == "bind" and (REPO / opts["source"]).is_dir(), arg
        if op == "COPY":
            *srcs, _dst = arg.split()
            assert not any(s.startswith("--") for s in srcs), arg
            for src in srcs:
                assert (REPO / src).exists(), f"Dockerfile COPY {src}: not in the build context"
                copied.append(src.rstrip("/"))
    pyproject = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))
    assert "pyproject.toml" in copied and pyproject["project"]["readme"] in copied
    packages = [p.rstrip("*") for p in pyproject["tool"]["setuptools"]["packages"]["find"]["include"]]
    assert sorted(packages) == sorted(c for c in copied if c not in ("pyproject.toml", "README.md"))
    runs = " ".join(arg for op, arg in ins if op == "RUN")
    assert "pip install --no-deps ." in runs and "pip install -r" in runs and "python3 -m venv /opt/venv" in runs
    assert "constellation --help" in runs  # the console script exists in the image
    assert ("USER", "sat") in ins
    # the compose file builds with docker/Dockerfile from the repo root, and the ignore file at the
    # context root (read by BuildKit and buildah) keeps local state out of the context
    ignore = (REPO / ".dockerignore").read_text(encoding="utf-8").split()
    assert ".venv" in ignore and ".git" in ignore and "docker" not in ignore


def test_dockerfile_profile_is_the_launchers():
    """The image points FastDDS at the profile the local launcher uses (same lockstep timing)."""
    env = dict(re.findall(r"(\w+)=(\S+)", " ".join(a for op, a in _dockerfile_instructions() if op == "ENV")))
    installed = env["FASTRTPS_DEFAULT_PROFILES_FILE"]
    prefix = "/opt/venv/lib/python3.11/site-packages/"
    assert installed.startswith(prefix)
    assert (REPO / installed.removeprefix(prefix)).is_file()
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"


def test_the_documented_compose_folder_is_git_ignored():
    """The containers guide writes compose files - and a key file - into deploy/: never to be committed."""
    import subprocess

    repo = Path(__file__).resolve().parents[2]
    assert "deploy/docker-compose.yml" in (repo / "docs" / "guide" / "containers.md").read_text()
    for f in ("deploy/run.keys", "deploy/docker-compose.yml", "deploy/world.pkl"):
        assert subprocess.run(["git", "check-ignore", "-q", f], cwd=repo, check=False).returncode == 0, f
