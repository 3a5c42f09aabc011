"""Helpers for the tests that break a scenario one field at a time (tests/unit/test_scenario.py
through the loader, tests/faults/test_faults_scenario_cli.py through each command)."""

from __future__ import annotations

import msgspec

from bringup.scenario.toml_text import to_toml  # noqa: F401  (re-exported for the tests)


def raw_scenario(sc) -> dict:
    """A loaded scenario as plain builtins (what a TOML file holds), without its source path."""
    raw = msgspec.to_builtins(sc)
    raw.pop("source_path", None)
    return raw


def leaves(d: dict, prefix: str = ""):
    """(dotted key, value) of every scalar or scalar list; tables of arrays as key[i]."""
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            yield from leaves(v, key + ".")
        elif isinstance(v, list) and v and isinstance(v[0], dict):
            for i, item in enumerate(v):
                yield from leaves(item, f"{key}[{i}].")
        elif v is not None:
            yield key, v


def set_key(d: dict, key: str, value) -> None:
    """Set a dotted key (as :func:`leaves` names it) in place."""
    parts = key.replace("[", ".[").split(".")
    for p in parts[:-1]:
        d = d[int(p[1:-1])] if p.startswith("[") else d[p]
    d[parts[-1]] = value


def bad_value(v):
    """A value of the wrong type for ``v``'s field."""
    if isinstance(v, bool):
        return "yes"
    if isinstance(v, (int, float)):
        return "not a number"
    if isinstance(v, str):
        return 12
    return "not a list"


