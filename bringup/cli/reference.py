"""The documentation's two generated references: the scenario keys and the command line.

Both are made from the code itself when the documentation is built (docs/hooks.py calls them), so
neither can drift from what the program accepts:

* :func:`config_reference_md` walks the scenario schema (the msgspec structs of
  bringup/scenario/config.py, through ``msgspec.inspect``): every key as a dotted path (``[]`` for the
  entries of an array of tables), its type, limits (msgspec's ``ge``/``gt``/``le``/``lt``, lengths,
  allowed strings), its default, and the comment that stands above the key in the annotated
  reference scenario (bringup/scenario/toml/paper.toml), which is where every key's unit and meaning
  are written;
* :func:`cli_reference_md` walks the argparse parsers of bringup/cli/main.py: every command, its help
  line, and each option with its metavar, choices, default and help.

How we know it is right: tests/unit/test_docs_site.py - every field of every scenario struct
(read through ``__struct_fields__``, not msgspec.inspect) appears in the configuration reference;
every key the reference lists, set to its listed default in the reference scenario, loads, and a key
that is not listed is refused; every command of the registry and every option of ``run`` appear in
the CLI reference; and the whole site builds with ``mkdocs build --strict``.
"""

from __future__ import annotations

import argparse
import re

import msgspec

from bringup.scenario.config import SCENARIO_DIR, Scenario

__all__ = ["cli_reference_md", "config_keys", "config_reference_md"]

_LIMITS = (("ge", ">="), ("gt", ">"), ("le", "<="), ("lt", "<"), ("min_length", "length >="),
           ("max_length", "length <="))


def _type_name(t) -> str:
    mi = msgspec.inspect
    if isinstance(t, mi.LiteralType):
        return " | ".join(f'`"{v}"`' if isinstance(v, str) else f"`{v}`" for v in t.values)
    if isinstance(t, mi.ListType):
        return f"array of {_type_name(t.item_type)}"
    if isinstance(t, mi.UnionType):
        return " or ".join(_type_name(x) for x in t.types)
    if isinstance(t, mi.StructType):
        return "table"
    names = {mi.FloatType: "float", mi.IntType: "integer", mi.StrType: "string", mi.BoolType: "boolean",
             mi.NoneType: "none", mi.DictType: "table"}
    for cls, name in names.items():
        if isinstance(t, cls):
            return name
    return type(t).__name__.removesuffix("Type").lower()


def _limits(t) -> str:
    if isinstance(t, msgspec.inspect.UnionType):  # an optional key: the limits of its value
        return ", ".join(x for x in (_limits(u) for u in t.types) if x)
    parts = []
    for attr, sym in _LIMITS:
        v = getattr(t, attr, None)
        if v is not None:
            parts.append(f"{sym} {v:g}" if isinstance(v, float) else f"{sym} {v}")
    return ", ".join(parts)


def _default(f) -> str:
    if f.required:
        return "required"
    if f.default is msgspec.NODEFAULT and f.default_factory is msgspec.NODEFAULT:
        return "optional"  # (msgspec.UNSET: a key that may be left out, e.g. one form of a region)
    d = f.default if f.default is not msgspec.NODEFAULT else f.default_factory()
    if isinstance(d, msgspec.Struct):
        return "(table)"
    if d is None:  # a key that may be left out (e.g. a constellation group's override: the scenario's)
        return "optional"
    if isinstance(d, str):
        return f'`"{d}"`'
    if isinstance(d, bool):
        return f"`{str(d).lower()}`"
    return f"`{d}`"


def config_keys(struct=Scenario) -> list[dict]:
    """Every key of the schema, depth first: ``{"key", "type", "limits", "default", "table"}``."""
    out: list[dict] = []
    _walk(msgspec.inspect.type_info(struct), "", out)
    return out


def _struct_of(t):
    mi = msgspec.inspect
    if isinstance(t, mi.StructType):
        return t
    if isinstance(t, mi.ListType) and isinstance(t.item_type, mi.StructType):
        return t.item_type
    return None


def _walk(st, prefix: str, out: list[dict]) -> None:
    mi = msgspec.inspect
    for f in st.fields:
        if f.name == "source_path":  # set by the loader, not a TOML key
            continue
        key = f"{prefix}{f.name}"
        t = f.type
        sub = _struct_of(t)
        if sub is not None:
            is_list = isinstance(t, mi.ListType)
            out.append({"key": key + ("[]" if is_list else ""), "type": "array of tables" if is_list else "table",
                        "limits": _limits(t), "default": _default(f), "table": True})
            _walk(sub, key + ("[]." if is_list else "."), out)
        elif isinstance(t, mi.UnionType) and any(_struct_of(x) for x in t.types):
            out.append({"key": key, "type": _type_name(t), "limits": "", "default": _default(f), "table": True})
            for x in t.types:
                s = _struct_of(x)
                if s is not None:
                    _walk(s, key + ("[]." if isinstance(x, mi.ListType) else "."), out)
        else:
            out.append({"key": key, "type": _type_name(t), "limits": _limits(t), "default": _default(f),
                        "table": False})


def _toml_comments() -> dict[str, str]:
    """dotted key -> the comment block above it in the reference scenario (``[]`` for array tables)."""
    text = (SCENARIO_DIR / "paper.toml").read_text()
    out: dict[str, str] = {}
    table, pending, last = "", [], None
    for line in text.splitlines():
        s = line.strip()
        if s.startswith("#"):
            pending.append(s.lstrip("#").strip())
            continue
        m = re.match(r"^\[\[(.+)\]\]$", s) or re.match(r"^\[(.+)\]$", s)
        if m:
            table = m.group(1).strip() + ("[]" if s.startswith("[[") else "")
            pending, last = [], None
            continue
        m = re.match(r"^([A-Za-z0-9_]+)\s*=", s)
        if m:
            key = f"{table}.{m.group(1)}" if table else m.group(1)
            if key not in out and pending:
                out[key] = " ".join(pending)
                last = key
            elif key not in out and last is not None:
                out[key] = f"(with `{last}` above)"
            pending = []
        elif not s:
            pending, last = [], None
    return out


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def config_reference_md() -> str:
    """The configuration reference page (Markdown)."""
    notes = _toml_comments()
    lines = ["# Scenario configuration reference", "",
             ("Generated from the scenario schema (bringup/scenario/config.py) when the documentation is "
             "built; the descriptions are the comments of the annotated reference scenario "
             "(bringup/scenario/toml/paper.toml). Units are in the key names (`_s`, `_km`, `_deg`, "
             "`_bps`...). Any key can be set on the command line of `run` with `--set KEY=VALUE` where "
             "that option is available; a file or an override that breaks a limit is refused in one line "
             "naming the key."), ""]
    section = None
    for k in config_keys():
        top = k["key"].split(".")[0].removesuffix("[]")
        if top != section:
            section = top
            lines += ["", f"## `[{section}]`", "", "| key | type | limits | default | meaning |",
                      "|---|---|---|---|---|"]
        note = notes.get(k["key"], "")
        lines.append(f"| `{k['key']}` | {_cell(k['type'])} | {_cell(k['limits'])} | {_cell(k['default'])} | "
                     f"{_cell(note)} |")
    return "\n".join(lines) + "\n"


def _option_row(a: argparse.Action) -> str:
    flags = ", ".join(f"`{s}`" for s in a.option_strings) or f"`{a.dest}`"
    meta = ""
    if a.choices is not None:
        meta = " | ".join(f"`{c}`" for c in a.choices)
    elif a.nargs != 0:
        meta = f"`{a.metavar or a.dest.upper()}`" if not isinstance(a.metavar, tuple) else ""
    default = "" if a.default in (None, argparse.SUPPRESS, False) or a.nargs == 0 else f"`{a.default}`"
    help_text = (a.help or "").replace("%(default)s", str(a.default)).replace("%%", "%")
    return f"| {flags} | {meta} | {default} | {_cell(help_text)} |"


def cli_reference_md() -> str:
    """The command-line reference page (Markdown)."""
    from bringup.cli.main import COMMANDS, build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    lines = ["# Command-line reference", "",
             ("Generated from the argument parsers (bringup/cli/) when the documentation is built. "
             "Every command exits 0 on success and 2 with one line on a usage or input error."), "",
             "| command | what it does |", "|---|---|"]
    lines += [f"| [`{name}`](#{name}) | {_cell(COMMANDS[name][1])} |" for name in COMMANDS]
    for name in COMMANDS:
        p = sub.choices.get(name)
        lines += ["", f"## {name}", "", COMMANDS[name][1] + ".", ""]
        if p is None:
            lines.append("(not available in this installation)")
            continue
        lines += ["```", p.format_usage().strip(), "```", "", "| option | value | default | help |",
                  "|---|---|---|---|"]
        lines += [_option_row(a) for a in p._actions if not isinstance(a, argparse._HelpAction)]
    return "\n".join(lines) + "\n"
