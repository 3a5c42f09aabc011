"""Whole runs through the CLI: the ROS engine equals the local engine; the bag is sound (issue 5).

Reduced paper scenario (12 satellites in 3 planes, 1 h: enough for DTN traffic to cross planes).
Oracles:
* equivalence - the local engine (one process, in-memory bus) is the reference: the ROS run (14
  processes over DDS) must give identical observations (sat, gp, t_ns) and bundle deliveries
  (bundle id, receiver, t_ns), and so must a ROS run with 4 satellites per process;
* the bag opens with the ``mcap`` reader and with ``rosbags`` (independent readers), has /clock and
  every satellite's topics; ``constellation report BAG`` equals report.json (runtime aside);
* physics of the medium - every copy on /sat_YY/dtn/in matches a transmission on /sat_XX/dtn/out
  with arrival = start + bits / rate + light time (bits: the bundle size plus a multicast copy's
  recipient list), inside a contact XX -> YY of the truth plan.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = [pytest.mark.system, pytest.mark.ros]

SATS, HOURS = 12, 1.0


def _run(engine: str, out: Path, *extra: str) -> Path:
    cmd = [sys.executable, "-m", "bringup.cli", "run", "--engine", engine, "--sats", str(SATS), "--hours",
           str(HOURS), "--out", str(out), "--no-plots", "--no-progress", *extra]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=600, check=False)
    assert r.returncode == 0, r.stderr[-3000:]
    return out


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    base = tmp_path_factory.mktemp("engines")
    return {"local": _run("local", base / "local"), "ros": _run("ros", base / "ros"),
            "ros4": _run("ros", base / "ros4", "--sats-per-process", "4")}


def _observations(bag: Path):
    from bringup.analysis.trace import observations_from_bag

    return observations_from_bag(bag)


def _deliveries(bag: Path):
    from bringup.analysis.trace import deliveries_from_bag

    return deliveries_from_bag(bag)


def test_ros_engine_equals_local_engine(runs):
    obs_l, obs_r = _observations(runs["local"] / "bag"), _observations(runs["ros"] / "bag")
    assert len(obs_l) > 50
    assert obs_r == obs_l
    del_l, del_r = _deliveries(runs["local"] / "bag"), _deliveries(runs["ros"] / "bag")
    assert len(del_l) > 10, "the reduced scenario must carry DTN traffic"
    assert del_r == del_l


def test_satellites_grouped_in_processes_equal_one_per_process(runs):
    """--sats-per-process 4: three processes of four satellites give the runs above."""
    assert _observations(runs["ros4"] / "bag") == _observations(runs["ros"] / "bag")
    assert _deliveries(runs["ros4"] / "bag") == _deliveries(runs["ros"] / "bag")
    assert sorted(p.name for p in (runs["ros4"] / "logs").glob("sats_*.log")) == ["sats_1.log", "sats_2.log",
                                                                                 "sats_3.log"]
    rep, rep1 = (json.loads((runs[k] / "report.json").read_text()) for k in ("ros4", "ros"))
    rep.pop("runtime"), rep1.pop("runtime")
    prov, prov1 = rep.pop("provenance"), rep1.pop("provenance")  # (the command lines differ)
    assert prov["scenario_toml"] == prov1["scenario_toml"] and "--sats-per-process 4" in prov["command"]
    assert rep == rep1


@pytest.mark.parametrize("engine", ["local", "ros"])
def test_bag_opens_with_independent_readers(runs, engine):
    from mcap.reader import make_reader
    from rosbags.highlevel import AnyReader

    bag = runs[engine] / "bag"
    mcaps = sorted(bag.glob("*.mcap"))
    assert mcaps and (bag / "metadata.yaml").exists()
    with open(mcaps[0], "rb") as fh:
        summary = make_reader(fh).get_summary()
    mcap_topics = {c.topic for c in summary.channels.values()}
    with AnyReader([bag]) as reader:
        ros_topics = {c.topic for c in reader.connections}
        n_clock = sum(1 for _ in reader.messages(connections=[c for c in reader.connections if c.topic == "/clock"]))
    assert mcap_topics == ros_topics
    assert n_clock > 100
    from bringup.scenario.config import sat_names

    for s in sat_names(3, SATS // 3):  # every satellite publishes its plan, counters and position
        for leaf in ("schedule", "dtn/counters", "fix"):
            assert f"/{s}/{leaf}" in ros_topics, (s, leaf)
    assert "/sat_11/observations" in ros_topics and "/sat_11/acs/state" in ros_topics
    assert "/viz/constellation" in ros_topics and "/orbit/contacts" in ros_topics


@pytest.mark.parametrize("engine", ["local", "ros"])
def test_report_from_bag_equals_run_report(runs, engine):
    run_rep = json.loads((runs[engine] / "report.json").read_text())
    r = subprocess.run([sys.executable, "-m", "bringup.cli", "report", str(runs[engine] / "bag")],
                       capture_output=True, text=True, timeout=300, check=False)
    assert r.returncode == 0, r.stderr
    bag_rep = json.loads(r.stdout)
    run_rep.pop("runtime")
    bag_rep.pop("runtime")
    assert bag_rep == run_rep
    assert run_rep["engine"] == engine and run_rep["n_sats"] == SATS


@pytest.mark.parametrize("engine", ["local", "ros"])
def test_bundles_cross_only_inside_contacts_with_link_delay(runs, engine):
    from bringup.recording.bag import BagReader
    from bringup.scenario.config import load_scenario
    from bringup.scenario.world import World

    sc = load_scenario("paper").with_overrides(sats=SATS, hours=HOURS)
    world = World.build(sc)
    bits = sc.isl.bundle_bits
    sent: dict[bytes, list[tuple[str, int]]] = {}
    with BagReader(runs[engine] / "bag") as b:
        names = [t.topic for t in b.topics()]
        for e in b.envelopes([t for t in names if t.endswith("/dtn/out")]):
            sent.setdefault(e.data, []).append((e.topic.split("/")[1], e.t_ns))
        arrivals = [(e.topic.split("/")[1], e.t_ns, e.data) for e in b.envelopes([t for t in names if t.endswith("/dtn/in")])]
    assert arrivals, "no bundle crossed"
    by_pair: dict[tuple[str, str], list] = {}
    for c in world.isl_plan.contacts:
        by_pair.setdefault((c.src, c.dst), []).append(c)
    from sat_node.dtn.routing_blocks import overhead_bits

    for receiver, t_arr, data in arrivals:
        ok = False
        for sender, t_start in sent.get(data, []):
            for c in by_pair.get((sender, receiver), []):
                tx_ns = (bits + overhead_bits(data)) / c.rate_bps * 1e9  # a multicast copy's recipient list too
                expect = t_start + tx_ns + c.range_light_s * 1e9
                inside = c.start_s * 1e9 <= t_start and t_start + tx_ns <= c.end_s * 1e9 + 1
                if inside and abs(t_arr - expect) <= 2:
                    ok = True
        assert ok, f"copy to {receiver} at {t_arr} ns matches no transmission inside a contact"
