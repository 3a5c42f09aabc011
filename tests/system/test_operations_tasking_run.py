"""Tasking requests and command acknowledgements through whole runs, on both engines
(sat_node/operations/tasking.py, ground_station/commander.py, bringup/analysis/operations.py).

Scenario: the paper's, 12 satellites, 0.5 h, ground stations Svalbard and Troll, with two tasks: one
for sat_12 (in contact with Svalbard from the start) at a ground point of Dallas, which sat_12 flies
over from ~760 s, issued at 100 s, priority 1, deadline 1500 s; and one for the whole constellation
(``sat = "all"``) at a ground point of Rio de Janeiro, issued at 150 s, deadline 1800 s.

Oracles: the tasked GP is observed before the deadline by a satellite that executed the task, and
that look's assumed value is above anything the OSSE scale gives an untasked GP (256 with the belief
noise: the planner valued it as tasked); the report's latencies equal the CommandEvent and
CommandAck times in the bag; every acknowledgement reaches the ground inside one of its
satellite's ground contacts; and the ROS engine's report equals the local engine's.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import msgspec
import pytest

from tests.run_messages import bag_messages as _messages
from tests.run_messages import comparable_report as _report

pytestmark = [pytest.mark.system]

_NS = 1_000_000_000
STATIONS = [{"name": "svalbard", "lat_deg": 78.2298, "lon_deg": 15.4078, "alt_m": 500.0},
            {"name": "troll", "lat_deg": -72.0117, "lon_deg": 2.535, "alt_m": 1270.0}]
COMMANDS = [
    {"sat": "sat_12", "kind": "task", "lat_deg": 32.7767, "lon_deg": -96.7970, "priority": 1, "at_s": 100.0,
     "by": "2000-01-01T12:24:28Z"},
    {"sat": "all", "kind": "task", "lat_deg": -22.9068, "lon_deg": -43.1729, "priority": 2, "at_s": 150.0,
     "by": "2000-01-01T12:29:28Z"},
]


def scenario(path: Path, commands=COMMANDS) -> Path:
    from bringup.scenario.config import load_scenario
    from bringup.scenario.toml_text import to_toml

    raw = msgspec.to_builtins(load_scenario("paper"))
    raw.pop("source_path", None)
    raw["commands"] = commands
    raw["ground"]["stations"] = STATIONS
    path.write_text(to_toml(raw))
    return path


def run(engine: str, out: Path, commands=COMMANDS) -> Path:
    sc = scenario(out.with_suffix(".toml"), commands)
    cmd = [sys.executable, "-m", "bringup.cli", "run", "--engine", engine, "--scenario", str(sc),
           "--sats", "12", "--hours", "0.5", "--out", str(out), "--no-plots", "--no-progress"]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=1200, check=False)
    assert r.returncode == 0, r.stderr[-3000:]
    return out


@pytest.fixture(scope="module")
def local(tmp_path_factory):
    return run("local", tmp_path_factory.mktemp("task") / "local")


def test_the_tasked_target_is_observed_in_time_by_a_tasked_satellite(local):
    rep = _report(local)["operations"]
    tasks = rep["tasks"]
    ev = _messages(local / "bag", lambda t: t.endswith("/ops/command"))
    done = {(e.command_id, e.sat): e for e in ev if e.stage == "executed"}
    # the constellation's task reaches the satellites its relays' ISL routes reach within the run
    assert ("c1", "sat_12") in done and len([k for k in done if k[0].startswith("c2.")]) >= 1
    obs = _messages(local / "bag", lambda t: t.endswith("/observations"))
    t1 = tasks["c1"]
    assert t1["sat"] == "sat_12" and t1["in_time"] and t1["observer_was_tasked"], t1
    look = [o for o in obs if o.gp == t1["gp"] and o.sat == t1["observed_by"] and o.t_ns == round(t1["observed_s"] * _NS)]
    assert len(look) == 1 and look[0].assumed_value > 256 * 1.4  # planned as tasked (1024, priority 1)
    assert look[0].t_ns <= done[("c1", "sat_12")].by_ns
    rio = [v for k, v in tasks.items() if k.startswith("c2.")]
    firsts = {(v["observed_by"], v["observed_s"]) for v in rio}
    assert len(firsts) == 1 and all(v["in_time"] and v["observer_was_tasked"] for v in rio), rio
    print("tasks:", {k: (v["observed_by"], v["observed_s"]) for k, v in tasks.items() if not k.startswith("c2.")},
          "constellation task first seen:", firsts)


def test_latencies_and_acks_against_the_bag(local):
    rep = _report(local)["operations"]["commands"]
    ev = _messages(local / "bag", lambda t: t.endswith("/ops/command"))
    acks = _messages(local / "bag", lambda t: t == "/ground/acks")
    contacts = {}
    for e in ev:
        if e.command_id == "c1" and e.stage in ("received", "executed"):
            key = "uplink_latency_s" if e.stage == "received" else "execution_latency_s"
            assert rep["by_command"]["c1"][key] == (e.t_ns - 100 * _NS) / _NS
    ack = [a for a in acks if a.command_id == "c1" and a.stage == "executed"]
    assert len(ack) == 1
    ex = next(e for e in ev if e.command_id == "c1" and e.stage == "executed")
    assert ack[0].event_ns == ex.t_ns and rep["by_command"]["c1"]["ack_latency_s"] == (ack[0].t_ns - ex.t_ns) / _NS
    # every acknowledgement reached the ground inside one of its satellite's ground contacts
    from bringup.scenario.config import load_scenario
    from bringup.scenario.world import World

    w = World.build(load_scenario(str(local.with_suffix(".toml"))).with_overrides(sats=12, hours=0.5))
    for c in w.ground_plan.contacts:
        contacts.setdefault((c.src, c.dst), []).append((round(c.start_s * _NS), round(c.end_s * _NS)))
    for a in acks:
        assert any(s <= a.t_ns < e for s, e in contacts[(a.sat, a.station)]), a
        assert a.t_ns >= a.event_ns
    # one executed ack per executed command whose satellite had a ground contact left
    assert rep["acks"]["received_on_ground"] == len(acks) > 0
    print("c1 latencies [s]:", {k: v for k, v in rep["by_command"]["c1"].items() if k.endswith("_s")})


def test_report_rebuilt_from_the_bag_has_the_same_operations(local):
    from bringup.analysis.report import report_from_bag

    assert report_from_bag(local / "bag")["operations"] == _report(local)["operations"]


@pytest.mark.ros
def test_ros_engine_gives_the_same_report(local, tmp_path):
    assert _report(run("ros", tmp_path / "ros")) == _report(local)
