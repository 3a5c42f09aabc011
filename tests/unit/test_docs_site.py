"""The documentation site builds with no warning, and its generated references match the code.

Oracles: MkDocs itself in strict mode (every warning - a broken link, a page left out of the
navigation, a docstring the API pages cannot render - fails the build); the scenario structs' own
``__struct_fields__`` (not the msgspec.inspect walk bringup/cli/reference.py uses) for the keys the
loader has; the loader itself for whether a listed key is accepted; the argument parsers for the
commands and options.
"""

from __future__ import annotations

import copy
import subprocess
import sys
import tomllib
import types
import typing
from pathlib import Path

import msgspec
import pytest

from bringup.cli.reference import cli_reference_md, config_keys, config_reference_md
from bringup.scenario import config as cfg

REPO = Path(__file__).resolve().parents[2]


def test_site_builds_strict(tmp_path):
    r = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(tmp_path / "site")],
                       cwd=REPO, capture_output=True, text=True, timeout=600, check=False)
    assert r.returncode == 0, r.stdout + r.stderr
    site = tmp_path / "site"
    for page in ("reference/configuration/index.html", "reference/cli/index.html", "api/planner/index.html",
                 "design/index.html", "changelog/index.html"):
        assert (site / page).is_file(), page
    assert "Planner" in (site / "api/planner/index.html").read_text()


def _unwrap(t):
    while typing.get_origin(t) is typing.Annotated:
        t = typing.get_args(t)[0]
    return t


def _struct_keys(tp, prefix: str = "") -> set[str]:
    """Every TOML key under a struct type, read from ``__struct_fields__`` and the type hints."""
    out = set()
    hints = typing.get_type_hints(tp, include_extras=True)
    for name in tp.__struct_fields__:
        if name == "source_path":
            continue
        t = _unwrap(hints[name])
        options = typing.get_args(t) if typing.get_origin(t) in (typing.Union, types.UnionType) else (t,)
        structs = []
        for a in map(_unwrap, options):
            if typing.get_origin(a) is list:
                inner = _unwrap(typing.get_args(a)[0])
                if isinstance(inner, type) and issubclass(inner, msgspec.Struct):
                    structs.append((inner, "[]."))
            elif isinstance(a, type) and issubclass(a, msgspec.Struct):
                structs.append((a, "."))
        key = prefix + name
        if structs:
            for s, sep in structs:
                out |= _struct_keys(s, key + sep)
        else:
            out.add(key)
    return out


def test_configuration_reference_lists_every_key():
    listed = {k["key"] for k in config_keys() if not k["table"]}
    assert _struct_keys(cfg.Scenario) <= listed
    page = config_reference_md()
    for key in _struct_keys(cfg.Scenario):
        assert f"`{key}`" in page, key


def _set(raw: dict, key: str, value) -> None:
    cur = raw
    parts = key.split(".")
    for p in parts[:-1]:
        cur = cur[p[:-2]][0] if p.endswith("[]") else cur.setdefault(p, {})
    cur[parts[-1]] = value


def test_every_listed_key_loads_and_an_unlisted_one_does_not():
    base = tomllib.loads((cfg.SCENARIO_DIR / "paper.toml").read_text())
    scalar = {k["key"]: k for k in config_keys() if not k["table"] and k["default"] not in ("required", "(table)", "optional")}
    assert scalar, "no key with a default"
    for key, k in scalar.items():
        raw = copy.deepcopy(base)
        default = tomllib.loads(f"v = {k['default'].strip('`')}")["v"]
        try:
            _set(raw, key, default)
        except (KeyError, IndexError, TypeError):
            continue  # a key inside an optional table the reference scenario does not use
        cfg._validate(raw, "<test>")  # raises ScenarioError if the loader refused it
    raw = copy.deepcopy(base)
    raw["isl"]["no_such_key_s"] = 1.0
    with pytest.raises(cfg.ScenarioError, match="no_such_key_s"):
        cfg._validate(raw, "<test>")


def test_cli_reference_lists_every_command_and_option():
    from bringup.cli.main import COMMANDS, build_parser

    page = cli_reference_md()
    for name in COMMANDS:
        assert f"\n## {name}\n" in page, name
    parser = build_parser()
    sub = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    for opt in sub.choices["run"]._actions:
        for s in opt.option_strings:
            if s in ("-h", "--help"):
                continue
            assert f"`{s}`" in page, s


def test_every_option_of_every_command_has_help():
    """An option without help shows nothing in `--help` nor in the CLI reference."""
    import argparse

    from bringup.cli.main import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    bare = [f"{name} {a.option_strings or a.dest}" for name, p in sub.choices.items() for a in p._actions
            if not isinstance(a, argparse._HelpAction) and not (a.help or "").strip()]
    assert not bare, bare


def test_compose_and_run_accept_the_same_domain_ids(tmp_path, capsys):
    from bringup.cli.main import main
    from bringup.engine.ros.run_spec import MAX_DOMAIN_ID

    out = tmp_path / "c" / "docker-compose.yml"
    base = ["compose", "--sats", "3", "--hours", "0.1", "--out", str(out)]
    assert main([*base, "--domain-id", str(MAX_DOMAIN_ID)]) == 0
    assert main([*base, "--domain-id", str(MAX_DOMAIN_ID + 1)]) == 2
    assert f"0..{MAX_DOMAIN_ID}" in capsys.readouterr().err
    assert main(["run", "--sats", "3", "--hours", "0.01", "--out", str(tmp_path / "r"),
                 "--domain-id", str(MAX_DOMAIN_ID + 1)]) == 2
    assert f"0..{MAX_DOMAIN_ID}" in capsys.readouterr().err


def test_every_help_text_formats():
    """`constellation --help` and every command's `--help` print (a '%' in a help text that argparse
    reads as a format once broke the top-level help, and with it the container image's build)."""
    import argparse

    from bringup.cli.main import build_parser

    parser = build_parser()
    assert "usage: constellation" in parser.format_help()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for name, p in sub.choices.items():
        assert p.format_help().startswith("usage:"), name
        for a in p._actions:
            if isinstance(a, argparse._SubParsersAction):
                for q in a.choices.values():
                    assert q.format_help().startswith("usage:"), name
