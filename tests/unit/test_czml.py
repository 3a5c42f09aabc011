"""The globe view's CZML document (bringup/analysis/czml.py) against what the run itself says.

Oracles, each independent of the document's own reading of the bag: the run's world (its scenario's
satellites and stations, the GPs' geodetic coordinates, the contact plans' node pairs), report.json
(how many observations), the bag's summary (its UTC span), and the bag's NavSatFix fixes read with
the mcap library's own ROS 2 decoder.
"""

from __future__ import annotations

import datetime as dt
import json
import subprocess
import sys

import pytest

from bringup.analysis.czml import czml_counts, read_czml_inputs
from bringup.cli.czml import write_globe


@pytest.fixture(scope="module")
def run12(tmp_path_factory):
    out = tmp_path_factory.mktemp("czml") / "run"
    r = subprocess.run([sys.executable, "-m", "bringup.cli", "run", "--engine", "local", "--sats", "12", "--hours",
                        "1", "--out", str(out), "--no-plots", "--no-progress"], capture_output=True, text=True,
                       timeout=600, check=False)
    assert r.returncode == 0, r.stderr
    return out


def _utc(s: str) -> dt.datetime:
    return dt.datetime.fromisoformat(s)


def test_document_holds_the_run(run12, tmp_path):
    from bringup.cli.bag_info import bag_summary
    from bringup.scenario.config import load_scenario
    from bringup.scenario.world import World

    counts = write_globe(run12 / "bag", tmp_path / "globe")
    doc = json.loads((tmp_path / "globe" / "run.czml").read_text())
    assert {f.name for f in (tmp_path / "globe").iterdir()} >= {"run.czml", "index.html", "package.json",
                                                                 "package-lock.json"}
    rep = json.loads((run12 / "report.json").read_text())
    world = World.build(load_scenario("paper").with_overrides(sats=12, hours=1))
    kinds: dict[str, list] = {}
    for p in doc[1:]:
        kinds.setdefault(p["id"].split("/")[0], []).append(p)
    assert {k: len(v) for k, v in kinds.items() if v} == {
        "sat": len(world.sat_names), "gs": len(world.scenario.ground.stations),
        "look": rep["observations"]["count"], "link": counts["links"], "xfer": counts["transfers"]}
    assert len(doc) - 1 == sum(counts.values())
    assert {p["id"] for p in kinds["sat"]} == {f"sat/{n}" for n in world.sat_names}
    # every link is a node pair of the world's contact plans that has a window within the horizon
    pairs = {tuple(sorted((c.src, c.dst))) for c in [*world.isl_plan, *world.ground_plan]
             if c.start_s < world.scenario.scenario.horizon_s}
    assert {tuple(p["id"].split("/")[1:]) for p in kinds["link"]} == pairs
    assert counts["transfers"] > 0  # 12 satellites in 3 planes deliver bundles within the hour

    # the clock spans the bag, in UTC
    summ = bag_summary(run12 / "bag")
    start, stop = doc[0]["clock"]["interval"].split("/")
    epoch = _utc(summ["epoch_utc"])
    assert _utc(start) == epoch + dt.timedelta(microseconds=summ["start_ns"] // 1000)
    assert _utc(stop) == epoch + dt.timedelta(microseconds=summ["end_ns"] // 1000)

    # a look sits on its ground point (the world's geodetic GP coordinates)
    gps = world.ctx.gps
    for p in kinds["look"][:20]:
        gp = int(p["id"].split("/")[2])
        lon, lat, _ = p["position"]["cartographicDegrees"]
        assert lat == pytest.approx(float(gps.lat_deg[gp]), abs=1e-6)
        assert lon == pytest.approx(float(gps.lon_deg[gp]), abs=1e-6)


def test_satellite_samples_are_the_bags_fixes(run12):
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    inp = read_czml_inputs(run12 / "bag")
    mcap_file = next((run12 / "bag").glob("*.mcap"))
    fixes = []
    with open(mcap_file, "rb") as f:
        for _s, ch, msg, ros in make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages(
                topics=["/sat_11/fix"]):
            fixes.append((msg.log_time, ros.longitude, ros.latitude, ros.altitude))
    assert len(fixes) == len(inp.fixes["sat_11"]) > 10
    for (log_ns, lon, lat, alt), (t_ns, lon2, lat2, alt2) in zip(fixes, sorted(inp.fixes["sat_11"]), strict=True):
        assert (log_ns - inp.epoch_ns, lon, lat, alt) == (t_ns, lon2, lat2, alt2)
    assert czml_counts(inp)["satellites"] == 12


def test_a_bag_without_fixes_is_one_line(tmp_path):
    from bringup.errors import UserError
    from bringup.recording.bag import BagWriter

    with BagWriter(tmp_path / "bag"):
        pass
    with pytest.raises(UserError, match="no /<sat>/fix topics"):
        read_czml_inputs(tmp_path / "bag")
