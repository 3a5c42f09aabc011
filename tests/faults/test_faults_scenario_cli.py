"""Scenario files with fields wrong in turn through the CLI (issue 7): one clear error, no traceback.

tests/unit/test_scenario.py does every field at the loader level; here each bad file goes through
``constellation run|access|contacts|constellation --scenario BAD.toml`` (the commands that take a
scenario), in process via ``bringup.cli.main`` for every field and as a real process for a sample.
Oracle: exit status 2, exactly one stderr line naming the command, the file and the field, no
"Traceback"; the unchanged file written by the same emitter loads (so the emitter is not the fault).
"""

from __future__ import annotations

import subprocess
import sys

import msgspec
import pytest
from scenario_edit import bad_value as _bad_value
from scenario_edit import leaves as _leaves
from scenario_edit import raw_scenario, to_toml
from scenario_edit import set_key as _set

from bringup.scenario.config import load_scenario

pytestmark = [pytest.mark.faults]

COMMANDS = ("run", "access", "contacts", "constellation")


def _raw():
    return raw_scenario(load_scenario("paper"))


KEYS = [k for k, _ in _leaves(_raw())]
# out-of-range (well-typed) values: the loader's own checks, through the CLI
RANGE = [("isl.rate_bps", -1.0), ("constellation.total_sats", 25), ("constellation.pattern", "ring"),
         ("scenario.epoch_utc", "2000-01-01 11:59:28"), ("regions.list[0].lat_deg", 91.0),
         ("isl.ttl_p1_s", 5000.0), ("value.belief_sigma_min", 0.5)]


def _bad_file(tmp_path, key, value):
    raw = _raw()
    _set(raw, key, value)
    p = tmp_path / "BAD.toml"
    p.write_text(to_toml(raw))
    return p


def _argv(cmd, path, tmp_path):
    argv = [cmd, "--scenario", str(path)]
    if cmd == "run":
        argv += ["--out", str(tmp_path / "out"), "--no-plots", "--no-progress"]
    return argv


def test_emitter_round_trips_the_paper_scenario(tmp_path):
    p = tmp_path / "good.toml"
    p.write_text(to_toml(_raw()))
    sc = load_scenario(p)
    assert msgspec.to_builtins(sc) | {"source_path": None} == _raw() | {"source_path": None}


def _check_one_line(cmd, err, key, rc):
    assert rc == 2, (cmd, key, err)
    assert "Traceback" not in err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, (cmd, key, err)
    assert lines[0].startswith(f"constellation {cmd}: error: ") and "BAD.toml" in lines[0], lines[0]
    assert key in lines[0], (key, lines[0])


@pytest.mark.parametrize("cmd", COMMANDS)
def test_every_field_wrong_in_turn_through_each_command(tmp_path, capsys, cmd):
    from bringup.cli.main import main

    cases = [(k, _bad_value(v)) for k, v in _leaves(_raw())] + RANGE
    for key, value in cases:
        path = _bad_file(tmp_path, key, value)
        rc = main(_argv(cmd, path, tmp_path))
        _check_one_line(cmd, capsys.readouterr().err, key, rc)
        assert not (tmp_path / "out" / "report.json").exists()
    assert len(cases) >= 40


@pytest.mark.parametrize("cmd", COMMANDS)
def test_sample_as_real_processes(tmp_path, cmd):
    for key, value in [("isl.rate_bps", "fast"), ("constellation.total_sats", 25), (KEYS[len(KEYS) // 2], None)]:
        if value is None:
            value = _bad_value(dict(_leaves(_raw()))[key])
        path = _bad_file(tmp_path, key, value)
        r = subprocess.run([sys.executable, "-m", "bringup.cli", *_argv(cmd, path, tmp_path)],
                           capture_output=True, text=True, timeout=120)
        _check_one_line(cmd, r.stderr, key, r.returncode)


def test_broken_toml_and_missing_file_through_each_command(tmp_path, capsys):
    from bringup.cli.main import main

    bad = tmp_path / "BAD.toml"
    bad.write_text("[scenario\nname=1\n")
    for cmd in COMMANDS:
        for path in (bad, tmp_path / "missing.toml"):
            rc = main(_argv(cmd, path, tmp_path))
            err = capsys.readouterr().err
            assert rc == 2 and "Traceback" not in err and len(err.strip().splitlines()) == 1, err
