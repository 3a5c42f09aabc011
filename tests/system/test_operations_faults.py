"""An injected ACS fault through whole runs (sat_node/operations/, issue 34 item 2), on both engines.

Scenario: the paper's, 12 satellites, 0.5 h, with ``sat_24``'s ACS stuck from 400 s to 900 s - in
the middle of its pass (it images from about 250 s to 550 s without the fault) and while it has an
ISL route to its plane neighbour ``sat_23`` (its observation bundles reach sat_23 within seconds
then), so its mode notice can arrive somewhere.

Oracles:
* the rule (sat_node/operations/modes.py): an ACS fault is SAFE, entered in the step the fault
  starts in (ModeChange stamped at the fault's time), left for NOMINAL when it clears (900 s);
* in SAFE nothing is imaged: no observation of sat_24 in [400 s, 900 s), while the same run
  without the fault has some there (so the check can fail);
* the neighbours replan: every satellite the notice reached (BundleDelivered of sat_24's notice
  bundle) emits, after the notice's arrival and before its next periodic replan, a schedule the
  run without the fault does not have;
* report.json: time in mode adds up to the horizon (500 s SAFE), and the value-lost estimate is
  positive;
* engines: the ROS engine's report (runtime aside) and observations equal the local engine's.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import msgspec
import pytest

pytestmark = [pytest.mark.system]

SATS, HOURS = 12, 0.5
SAT, AT_S, UNTIL_S = "sat_24", 400.0, 900.0
_NS = 1_000_000_000


def _scenario(path: Path, faults: bool) -> Path:
    from bringup.scenario.config import load_scenario
    from bringup.scenario.toml_text import to_toml

    raw = msgspec.to_builtins(load_scenario("paper"))
    raw.pop("source_path", None)
    if faults:
        raw["faults"] = [{"sat": SAT, "kind": "acs_stuck", "at_s": AT_S, "until_s": UNTIL_S}]
    path.write_text(to_toml(raw))
    return path


def _run(engine: str, scenario: Path, out: Path) -> Path:
    cmd = [sys.executable, "-m", "bringup.cli", "run", "--engine", engine, "--scenario", str(scenario),
           "--sats", str(SATS), "--hours", str(HOURS), "--out", str(out), "--no-plots", "--no-progress"]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=900, check=False)
    assert r.returncode == 0, r.stderr[-3000:]
    return out


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    base = tmp_path_factory.mktemp("ops")
    fault, clean = _scenario(base / "fault.toml", True), _scenario(base / "clean.toml", False)
    return {"fault": _run("local", fault, base / "fault"), "clean": _run("local", clean, base / "clean")}


def _messages(bag: Path, suffix: str):
    from bringup.recording.bag import BagReader
    from msgs_json import codec

    with BagReader(bag) as b:
        topics = [t.topic for t in b.topics() if t.topic.endswith(suffix)]
        return [(env.t_ns, codec.decode(env.topic, env.data)) for env in b.envelopes(topics)] if topics else []


def _report(run: Path) -> dict:
    rep = json.loads((run / "report.json").read_text())
    rep.pop("runtime", None)
    rep.pop("provenance", None)  # the command line and where the scenario came from
    return rep


def test_acs_fault_is_safe_within_the_step_and_recovers(runs):
    changes = [m for _t, m in _messages(runs["fault"] / "bag", "/ops/mode")]
    assert [(m.sat, m.t_ns, m.previous, m.mode, m.reason) for m in changes] == [
        (SAT, int(AT_S * _NS), "NOMINAL", "SAFE", "acs_fault"),
        (SAT, int(UNTIL_S * _NS), "SAFE", "NOMINAL", "")]
    assert changes[0].imaging is False and changes[1].imaging is True
    assert changes[0].plan_value_dropped > 0  # it had looks planned when the fault came
    assert _messages(runs["clean"] / "bag", "/ops/mode") == []


def test_nothing_imaged_while_safe(runs):
    def looks(run):
        return [m.t_ns for _t, m in _messages(run / "bag", "/observations")
                if m.sat == SAT and AT_S * _NS <= m.t_ns < UNTIL_S * _NS]

    assert looks(runs["clean"]), "the run without the fault images in the window (else this test tests nothing)"
    assert looks(runs["fault"]) == []


def test_neighbours_replan_on_the_notice(runs):
    events = _messages(runs["fault"] / "bag", "/dtn/events")
    notice = {m.bundle_id for _t, m in events if type(m).__name__ == "BundleCreated" and m.src == SAT
              and m.creation_ns == int(AT_S * _NS)}
    got = {}
    for t, m in events:
        if type(m).__name__ == "BundleDelivered" and m.bundle_id in notice and m.sat not in got:
            got[m.sat] = t
    assert got, "the notice reached no neighbour"
    print("notice delivered:", {s: t / _NS for s, t in sorted(got.items())})

    def planned(run):
        return {(m.sat, m.planned_ns) for _t, m in _messages(run / "bag", "/schedule")}

    with_fault, without = planned(runs["fault"]), planned(runs["clean"])
    # the receiver reads the copy some lockstep steps after its arrival (the medium relays it at its next
    # step); a replan for the notice comes before the next periodic replan (paper: every 600 s from 0)
    period_ns = 600 * _NS
    for sat, t in got.items():
        nxt = (t // period_ns + 1) * period_ns
        new = [p for s, p in with_fault - without if s == sat and t <= p < nxt]
        assert new, f"{sat} got the notice at {t / _NS:.1f} s but did not replan"


def test_report_time_in_mode_and_value_lost(runs):
    rep, clean = _report(runs["fault"]), _report(runs["clean"])
    ops = rep["operations"]
    assert ops["time_in_mode_s"] == {SAT: {"NOMINAL": HOURS * 3600 - (UNTIL_S - AT_S), "DEGRADED": 0.0,
                                           "SAFE": UNTIL_S - AT_S}}
    assert ops["transitions"] == 2 and ops["value_lost_estimate"] > 0
    assert "operations" not in clean
    print(f"value lost: estimate {ops['value_lost_estimate']:.0f}, against the run without the fault "
          f"{clean['value']['cumulative'] - rep['value']['cumulative']:.0f}")


@pytest.mark.ros
def test_ros_engine_gives_the_same_report(runs, tmp_path):
    ros = _run("ros", _scenario(tmp_path / "fault.toml", True), tmp_path / "ros")
    rep_l, rep_r = _report(runs["fault"]), _report(ros)
    for r in (rep_l, rep_r):
        r.pop("engine", None)
        r.pop("security", None)
    assert rep_r == rep_l
    obs = [(m.sat, m.gp, m.t_ns) for _t, m in _messages(ros / "bag", "/observations")]
    assert sorted(obs) == sorted((m.sat, m.gp, m.t_ns) for _t, m in _messages(runs["fault"] / "bag", "/observations"))
