"""TOML text of a scenario as plain builtins (tables, arrays of tables, scalars, lists): what
tests and benchmarks write to make a scenario file from a loaded one (``msgspec.to_builtins``), read
back by bringup/scenario/config.py like any scenario file. Checked by tests/unit/test_scenario.py
(every field of the paper scenario changed in turn, written with this and loaded again)."""

from __future__ import annotations

import json

__all__ = ["to_toml"]


def _scalar(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(_scalar(x) for x in v) + "]"
    raise TypeError(f"cannot write {v!r} as TOML")


def to_toml(d: dict, prefix: str = "") -> str:
    """Minimal TOML writer for the scenario's shape (tables, arrays of tables, scalars, lists)."""
    lines, subs = [], []
    for k, v in d.items():
        if v is None:
            continue
        if isinstance(v, dict):
            subs.append((k, v, False))
        elif isinstance(v, list) and v and isinstance(v[0], dict):
            subs.append((k, v, True))
        else:
            lines.append(f"{k} = {_scalar(v)}")
    out = "\n".join(lines) + ("\n" if lines else "")
    for k, v, many in subs:
        name = f"{prefix}{k}"
        if many:
            for item in v:
                out += f"\n[[{name}]]\n" + to_toml(item, name + ".")
        else:
            out += f"\n[{name}]\n" + to_toml(v, name + ".")
    return out
