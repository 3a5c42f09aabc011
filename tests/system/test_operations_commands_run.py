"""Operator commands through whole runs (sat_node/operations/commands.py, ground_station/commander.py),
on both engines.

Scenario: the paper's, 12 satellites, 0.5 h, ground stations Svalbard and Troll (set by
the test), with ``[[commands]]``: sat_33 (in contact with gs_troll
from the start to ~500 s) commanded SAFE at 50 s and NOMINAL at 300 s, both uplinked straight to it;
a forged SAFE for sat_33 at 100 s; a ``set`` for sat_13 at 250 s that goes up through sat_33 and on
over the ISLs, uplinked twice (a replay); a SAFE for sat_14 valid for 1 s (it expires before it
arrives).

Oracles: the command rules (an authenticated command for this satellite, first time, in time, is
executed; otherwise rejected by reason and nothing changes), the mode rule "commanded SAFE" of
sat_node/operations/modes.py, and the ROS engine's report equal to the local engine's.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import msgspec
import pytest

from tests.run_messages import bag_messages
from tests.run_messages import comparable_report as _report

pytestmark = [pytest.mark.system]

_NS = 1_000_000_000
STATIONS = [{"name": "svalbard", "lat_deg": 78.2298, "lon_deg": 15.4078, "alt_m": 500.0},
            {"name": "troll", "lat_deg": -72.0117, "lon_deg": 2.535, "alt_m": 1270.0}]
COMMANDS = [
    {"sat": "sat_33", "kind": "mode", "mode": "safe", "at_s": 50.0},
    {"sat": "sat_33", "kind": "mode", "mode": "safe", "at_s": 100.0, "forge": True},
    {"sat": "sat_33", "kind": "mode", "mode": "nominal", "at_s": 300.0},
    {"sat": "sat_13", "kind": "set", "name": "operations.pointing_error_max_deg", "value": 7.5, "at_s": 250.0,
     "repeat": True},
    {"sat": "sat_14", "kind": "mode", "mode": "safe", "at_s": 300.0, "valid_s": 1.0},
]


def _scenario(path: Path) -> Path:
    from bringup.scenario.config import load_scenario
    from bringup.scenario.toml_text import to_toml

    raw = msgspec.to_builtins(load_scenario("paper"))
    raw.pop("source_path", None)
    raw["commands"] = COMMANDS
    raw["ground"]["stations"] = STATIONS  # the commands' uplinks are timed for these stations
    path.write_text(to_toml(raw))
    return path


def _run(engine: str, out: Path) -> Path:
    scenario = _scenario(out.with_suffix(".toml"))
    cmd = [sys.executable, "-m", "bringup.cli", "run", "--engine", engine, "--scenario", str(scenario),
           "--sats", "12", "--hours", "0.5", "--out", str(out), "--no-plots", "--no-progress"]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=900, check=False)
    assert r.returncode == 0, r.stderr[-3000:]
    return out


@pytest.fixture(scope="module")
def local(tmp_path_factory):
    return _run("local", tmp_path_factory.mktemp("cmd") / "local")


def _messages(bag: Path, suffix: str):
    return bag_messages(bag, lambda topic: topic.endswith(suffix))


def test_commands_executed_rejected_and_the_mode_they_set(local):
    ev = _messages(local / "bag", "/ops/command")
    outcomes = {(e.sat, e.command_id, e.stage, e.reason) for e in ev if e.stage != "received"}
    assert outcomes == {("sat_33", "c1", "executed", ""), ("sat_33", "c3", "executed", ""),
                        ("sat_33", "?", "rejected", "forged"), ("sat_13", "c4", "executed", ""),
                        ("sat_13", "c4", "rejected", "replayed"), ("sat_14", "c5", "rejected", "expired")}
    received = {(e.sat, e.command_id) for e in ev if e.stage == "received"}
    assert received == {("sat_33", "c1"), ("sat_33", "c3"), ("sat_13", "c4")}
    done = {e.command_id: e for e in ev if e.stage == "executed"}
    for cid, issued_s in (("c1", 50.0), ("c3", 300.0), ("c4", 250.0)):
        e = done[cid]
        assert e.issued_ns == issued_s * _NS and e.latency_s == (e.t_ns - e.issued_ns) / _NS >= 0
    ups = _messages(local / "bag", "/commands")
    relays = {u.relay for u in ups if json.loads(u.payload.split("\n")[0])["command"] == "c4"}
    assert relays == {"sat_33"}  # up to sat_33, then over the ISLs to sat_13
    modes = [(m.sat, m.t_ns, m.mode, m.reason) for m in _messages(local / "bag", "/ops/mode")]
    # the forged SAFE (100 s) changed nothing: only the two authenticated commands show
    assert modes == [("sat_33", done["c1"].t_ns, "SAFE", "commanded"),
                     ("sat_33", done["c3"].t_ns, "NOMINAL", "")]
    rep = _report(local)["operations"]
    assert rep["commands"]["executed"] == 3 and rep["commands"]["received"] == 3
    assert rep["commands"]["rejected"] == {"expired": 1, "forged": 1, "replayed": 1}
    assert rep["time_in_mode_s"]["sat_33"]["SAFE"] == (done["c3"].t_ns - done["c1"].t_ns) / _NS
    print("command latency [s]:", {k: round(e.latency_s, 3) for k, e in sorted(done.items())})


def test_report_rebuilt_from_the_bag_has_the_same_operations(local):
    from bringup.analysis.report import report_from_bag

    assert report_from_bag(local / "bag")["operations"] == _report(local)["operations"]


@pytest.mark.ros
def test_ros_engine_gives_the_same_report(local, tmp_path):
    assert _report(_run("ros", tmp_path / "ros")) == _report(local)


def test_event_log_of_the_run(local):
    from bringup.cli.ops import events_from_bag

    log = events_from_bag(local / "bag")
    got = [(e["sat"], e["id"], e["severity"]) for e in log]
    assert ("sat_33", 1003, "high") in got  # SAFE, commanded
    assert ("sat_33", 1000, "informative") in got  # back to NOMINAL
    assert ("sat_33", 2101, "medium") in got  # the forged one
    assert ("sat_13", 2103, "medium") in got and ("sat_14", 2104, "low") in got  # replayed, expired
    assert sum(1 for e in log if e["id"] == 2002) == 3  # executed
    assert [e["t_s"] for e in log] == sorted(e["t_s"] for e in log)
