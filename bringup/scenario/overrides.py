"""``--set KEY=VALUE``: any scenario key changed on the command line, validated exactly like the file.

A KEY is the dotted path of a TOML key as the scenario file spells it: ``isl.rate_bps``,
``scheduler.replan_period_s``, ``value.knowledge``, ``regions.list[1].size_km`` (``[i]``: the i-th
element of an array of tables, from 0). A VALUE is a TOML literal, as it would stand on the right
of ``=`` in the file: ``250``, ``1.5e3``, ``true``, ``"observed"``, ``[1.0, 2.0]``,
``{ name = "X", lat_deg = 1.0, lon_deg = 2.0 }``. A bare word that is not a TOML literal
(``observed``) is taken as the string it spells, so a shell user need not quote it twice.

The changed scenario goes through the one validation of bringup/scenario/config.py (msgspec types,
ranges, unknown keys, the cross-field rules): a bad key or value is one ScenarioError line naming
the ``--set`` and the key, as the file would. Overrides are applied in the order given, after the
named options (``--sats``, ``--hours``, ``--knowledge``...); a ``--set`` of a key that an explicit
named option also sets is refused (:func:`check_conflicts`), so no option is silently overridden.

How we know it is right: tests/unit/test_overrides.py - every value written with ``--set`` equals
the same value written into a copy of the TOML file and loaded (the file is the oracle), bad keys,
bad values and bad indices are one line naming the key, and literals parse as tomllib parses them.
"""

from __future__ import annotations

import re
import tomllib
from collections.abc import Iterable

import msgspec

from bringup.scenario.config import Scenario, ScenarioError, _validate

__all__ = ["KEY_RE", "OPTION_KEYS", "apply_sets", "check_conflicts", "parse_set", "parse_value", "set_raw"]

KEY_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*(\[\d+\])?(\.[A-Za-z_][A-Za-z0-9_]*(\[\d+\])?)*$")
_BARE = re.compile(r"^[A-Za-z_][A-Za-z0-9_.:/+-]*$")

#: the named command-line options and the scenario keys they set (argparse dest -> keys)
OPTION_KEYS: dict[str, tuple[str, ...]] = {
    "sats": ("constellation.total_sats", "constellation.planes"),
    "planes": ("constellation.planes", "constellation.phasing_f"),
    "hours": ("scenario.horizon_s",),
    "seed": ("scenario.seed",),
    "knowledge": ("value.knowledge",),
    "transiency_min": ("value.transiency_min",),
    "gp_spacing_km": ("regions.gp_spacing_km",),
    "planning": ("scheduler.joint_planning",),
    "joint_max_partners": ("scheduler.joint_max_partners",),
    "forwarding": ("isl.forwarding",),
    "viz_period_s": ("viz.period_s",),
    "regions": ("regions.list",),
    "epoch_utc": ("scenario.epoch_utc",),
}


def parse_value(text: str):
    """A TOML literal's value (``250`` -> 250, ``"a"`` / ``a`` -> 'a', ``[1, 2]`` -> [1, 2]);
    ValueError naming the text when it is neither a literal nor a bare word."""
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        pass
    if _BARE.match(text.strip()):
        return text.strip()
    raise ValueError(f"{text!r} is not a TOML value (a number, true/false, a \"string\", [a, list] or "
                     "{ an = inline table })")


def parse_set(text: str) -> tuple[str, object]:
    """``"isl.rate_bps=250"`` -> ``("isl.rate_bps", 250)``; ScenarioError (one line) when malformed."""
    key, eq, val = text.partition("=")
    key = key.strip()
    if not eq or not key or not val.strip():
        raise ScenarioError(f"--set {text!r}: expected KEY=VALUE, e.g. isl.rate_bps=250")
    if not KEY_RE.match(key):
        raise ScenarioError(f"--set {text!r}: {key!r} is not a dotted scenario key (e.g. scheduler.replan_period_s)")
    try:
        return key, parse_value(val.strip())
    except ValueError as exc:
        raise ScenarioError(f"--set {text!r}: {exc}") from None


def _parts(key: str) -> list[str | int]:
    out: list[str | int] = []
    for part in key.split("."):
        name, _, idx = part.partition("[")
        out.append(name)
        if idx:
            out.append(int(idx.rstrip("]")))
    return out


def set_raw(raw: dict, key: str, value, where: str) -> None:
    """Put ``value`` at dotted ``key`` in the plain-builtins scenario ``raw``. A missing table is
    made (the schema then names an unknown key); an index past an array's end is refused here."""
    parts = _parts(key)
    cur = raw
    for i, p in enumerate(parts[:-1]):
        nxt = parts[i + 1]
        if isinstance(p, int):
            if not isinstance(cur, list) or not p < len(cur):
                n = len(cur) if isinstance(cur, list) else 0
                raise ScenarioError(f"{where}: key '{key}': index [{p}] is past the end ({n} elements)")
            cur = cur[p]
            continue
        if not isinstance(cur, dict):
            raise ScenarioError(f"{where}: key '{key}': '{p}' is inside a value that is not a table")
        if p not in cur:
            cur[p] = [] if isinstance(nxt, int) else {}
        cur = cur[p]
    last = parts[-1]
    if isinstance(last, int):
        if not isinstance(cur, list) or not last < len(cur):
            n = len(cur) if isinstance(cur, list) else 0
            raise ScenarioError(f"{where}: key '{key}': index [{last}] is past the end ({n} elements)")
        cur[last] = value
    elif not isinstance(cur, dict):
        raise ScenarioError(f"{where}: key '{key}': the value above '{last}' is not a table")
    else:
        cur[last] = value


def _as_pairs(sets: Iterable) -> list[tuple[str, object, str]]:
    """(key, value, as the user wrote it) for each ``"KEY=VALUE"`` text or ``(key, value)`` pair."""
    out = []
    for s in sets:
        if isinstance(s, str):
            k, v = parse_set(s)
            out.append((k, v, s))
        else:
            k, v = s
            out.append((k, v, f"{k}={v!r}"))
    return out


def apply_sets(sc: Scenario, sets: Iterable, *, what: str = "--set") -> Scenario:
    """A copy of ``sc`` with each override applied in order (``"KEY=VALUE"`` texts or ``(key,
    value)`` pairs), validated like the file; ScenarioError naming the ``--set`` and the key."""
    pairs = _as_pairs(sets)
    if not pairs:
        return sc
    raw = msgspec.to_builtins(sc)
    raw.pop("source_path", None)
    where = sc.source_path or "<scenario>"
    for k, v, text in pairs:
        set_raw(raw, k, v, f"{what} {text}")
    try:
        return _validate(raw, where)
    except ScenarioError as exc:
        msg = str(exc)
        m = re.search(r"key '([^']*)'", msg)
        bad = m.group(1) if m else ""
        for k, _, text in pairs:  # name the --set the schema's complaint is about
            if bad and (bad == k or k.startswith((bad + ".", bad + "[")) or bad.startswith(k)):
                raise ScenarioError(f"{what} {text}: {msg}") from None
        raise ScenarioError(f"{what} {' '.join(t for _, _, t in pairs)}: {msg}") from None


def check_conflicts(sets: Iterable, explicit: Iterable[str]) -> None:
    """Refuse a ``--set`` of a key that an explicitly given named option (argparse dest in
    :data:`OPTION_KEYS`) also sets: one of them would be silently overridden."""
    pairs = _as_pairs(sets)
    for opt in explicit:
        for k, _, text in pairs:
            if k in OPTION_KEYS.get(opt, ()):
                flag = {"epoch_utc": "epoch"}.get(opt, opt)  # (--epoch's dest is the scenario key's name)
                raise ScenarioError(f"--set {text}: --{flag.replace('_', '-')} sets the same key; give one of them")
