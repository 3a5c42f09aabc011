"""Provenance: what a run, a sweep or a comparison was made from, kept beside its figures.

Every ``report.json`` (and the bag's ``/run/meta`` record it is rebuilt from, so
``constellation report BAG`` gives it back), ``compare.json`` and ``sweep.json`` carry a
``provenance`` object:

* ``scenario_toml`` - the resolved scenario as TOML text, after every override (``--sats``,
  ``--set``, a sweep cell, the seed); relative data-file paths (:data:`FILE_KEYS`) made absolute
  against the scenario file's folder, so the text loads on its own. :func:`scenario_toml` loads the
  text back through the one validation (bringup/scenario/config.py) and refuses to return a text that
  does not give the same scenario;
* ``scenario_source`` - the file the scenario was loaded from;
* ``seed`` - the scenario seed of the run (a sweep or comparison: the first of its seeds);
* ``version`` - the project's version (:func:`version`: ``[project] version`` of the
  pyproject.toml beside the package in a source checkout, else the installed distribution's
  metadata, which setuptools writes from the same key);
* ``git_commit`` - ``git rev-parse HEAD`` of the checkout the package runs from, or ``"not a git
  checkout"``; ``git_dirty`` - whether tracked files differ from that commit (None: unknown);
* ``command`` - the command line as typed (``constellation run ...``);
* ``python`` - the interpreter's version; ``dependencies`` - the installed version of every runtime
  dependency the project declares (pyproject ``[project] dependencies``), ``"not installed"`` for
  one that is missing.

How we know it is right: tests/unit/test_provenance.py - a local run's report.json holds every key,
its ``scenario_toml`` loads back to the run's scenario (with a ``--set`` applied), the report
rebuilt from the bag alone holds the same provenance, the version equals pyproject's and
``constellation --version`` prints it, and the commit equals what git itself says.
"""

from __future__ import annotations

import copy
import functools
import platform
import re
import shlex
import subprocess
import sys
import tomllib
from importlib import metadata
from pathlib import Path

import msgspec

from bringup.scenario.canonical import canonical_data
from bringup.scenario.config import Scenario, _validate
from bringup.scenario.toml_text import to_toml

__all__ = ["DIST_NAME", "FILE_KEYS", "NOT_GIT", "command_line", "dependencies", "git_state", "provenance",
           "scenario_toml", "version"]

DIST_NAME = "agile-dtn-constellation"
NOT_GIT = "not a git checkout"
#: scenario keys holding a path to a data file, resolved against the scenario file's folder
#: (ground_station/osse_sources.py); made absolute in ``scenario_toml``
FILE_KEYS = ("value.osse_file", "value.osse_forecast_file")  # and constellation groups' tle_file / omm_file

_ROOT = Path(__file__).resolve().parents[2]  # the checkout (or site-packages) holding bringup/


def _pyproject() -> dict | None:
    p = _ROOT / "pyproject.toml"
    try:
        d = tomllib.loads(p.read_text(encoding="utf-8"))
    except (OSError, tomllib.TOMLDecodeError):
        return None
    return d if d.get("project", {}).get("name") == DIST_NAME else None


@functools.lru_cache(maxsize=1)
def version() -> str:
    """The project's version: pyproject.toml's in a source checkout, else the installed metadata."""
    pp = _pyproject()
    if pp is not None and pp["project"].get("version"):
        return str(pp["project"]["version"])
    try:
        return metadata.version(DIST_NAME)
    except metadata.PackageNotFoundError:
        return "unknown (neither a source checkout nor an installed distribution)"


def _git(*args: str) -> str | None:
    try:
        r = subprocess.run(["git", "-C", str(_ROOT), *args], capture_output=True, text=True, timeout=10,
                           check=False)
    except (OSError, subprocess.TimeoutExpired):
        return None
    return r.stdout.strip() if r.returncode == 0 else None


@functools.lru_cache(maxsize=1)
def git_state() -> tuple[str, bool | None]:
    """(commit, dirty) of the checkout the package runs from; (NOT_GIT, None) outside one."""
    if not (_ROOT / ".git").exists():
        return NOT_GIT, None
    commit = _git("rev-parse", "HEAD")
    if not commit or not re.fullmatch(r"[0-9a-f]{40,64}", commit):
        return NOT_GIT, None
    status = _git("status", "--porcelain", "--untracked-files=no")
    return commit, (None if status is None else bool(status))


@functools.lru_cache(maxsize=1)
def dependencies() -> dict[str, str]:
    """Installed version of each declared runtime dependency (pyproject, else the metadata)."""
    pp = _pyproject()
    if pp is not None:
        reqs = list(pp["project"].get("dependencies", []))
    else:
        try:
            reqs = [r for r in (metadata.requires(DIST_NAME) or []) if "extra ==" not in r]
        except metadata.PackageNotFoundError:
            reqs = []
    out = {}
    for r in reqs:
        name = re.split(r"[\[<>=!~; ]", r, maxsplit=1)[0]
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    return dict(sorted(out.items()))


def command_line(argv: list[str] | None = None) -> str:
    """``constellation ARGS`` as typed (``argv``: the arguments after the program name; default
    this process's)."""
    return shlex.join(["constellation", *(sys.argv[1:] if argv is None else argv)])


def _resolved_raw(sc: Scenario) -> dict:
    raw = msgspec.to_builtins(sc)
    raw.pop("source_path", None)
    src = sc.source_path
    for key in FILE_KEYS:
        table, name = key.split(".")
        v = raw.get(table, {}).get(name)
        if v and not Path(v).is_absolute() and src and not src.startswith("<"):
            raw[table][name] = str((Path(src).parent / v).resolve())
    # the constellation's element files (bringup/scenario/groups.py): one group or a list of them
    groups = raw.get("constellation")
    for g in groups if isinstance(groups, list) else [groups] if isinstance(groups, dict) else []:
        for name in ("tle_file", "omm_file"):
            v = g.get(name)
            if v and not Path(v).is_absolute() and src and not src.startswith("<"):
                g[name] = str((Path(src).parent / v).resolve())
    return raw


def scenario_toml(sc: Scenario) -> str:
    """The scenario as TOML text that loads back to it (data-file paths made absolute); RuntimeError
    naming the first key that would not round-trip (a writer bug, never silently a different one)."""
    raw = _resolved_raw(sc)
    head = (f"# Scenario '{sc.name}' as run (every override applied), written by constellation {version()}\n"
            f"# from {sc.source_path or 'overrides'}\n")
    text = head + to_toml(raw)
    back = canonical_data(_validate(tomllib.loads(text), "<provenance>"))
    want = canonical_data(_validate(copy.deepcopy(raw), "<provenance>"))
    back.pop("source_path", None), want.pop("source_path", None)
    if back != want:
        bad = next((k for k in want if back.get(k) != want[k]), "?")
        raise RuntimeError(f"provenance: the scenario's TOML text does not load back to it (table '{bad}')")
    return text


def provenance(sc: Scenario, argv: list[str] | None = None) -> dict:
    """The ``provenance`` object of a run, sweep or comparison of scenario ``sc`` (module docstring)."""
    commit, dirty = git_state()
    return {"scenario_toml": scenario_toml(sc), "scenario_source": sc.source_path, "seed": sc.scenario.seed,
            "version": version(), "git_commit": commit, "git_dirty": dirty, "command": command_line(argv),
            "python": platform.python_version(), "dependencies": dependencies()}
