"""The compose file run for real, one container per process (podman + runc; marker ``containers``).

A 12-satellite, 1-h distributed run of the paper scenario, written by `constellation compose` and
run by `constellation containers up` (podman driven directly) and by podman-compose 1.6.0 as
written. Oracles:

* the local engine's run of the same scenario and seed (one process, in-memory bus): identical
  observations (sat, gp, t_ns) and bundle deliveries (bundle id, receiver, t_ns);
* the bag opens with two independent readers (mcap, rosbags) with the same topics as a host run's
  bag, and ``constellation report BAG`` of it equals the report.json the clock container wrote; the
  report's science sections equal the host run's;
* the container run's report.json has a local run's keys, and its bag's globe view (constellation czml)
  the local run's entities;
* the globe page on a container run's bag, in headless Chromium (also marker ``browser``: .ci/run
  installs chromium before the container tests): Cesium counts the bag's entities on the bag's UTC
  clock (tests/globe_page.py), screenshot kept as build/test-artifacts/globe-container-run.png;
* nothing labelled with the test's projects is left afterwards (the ``lab`` fixture), nor when a
  run cannot even start (a missing image).
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import REPO, SATS, traces
from globe_page import check_globe_page

pytestmark = [pytest.mark.containers, pytest.mark.system, pytest.mark.timeout(1800)]

_SCIENCE = ("value", "observations", "coverage", "dtn", "consensus")


def _cli(*args: str, timeout: float = 1200) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "bringup.cli", *args], capture_output=True, text=True,
                          timeout=timeout, check=False, cwd=REPO)


def _bag_topics(bag: Path) -> tuple[set, set, int]:
    from mcap.reader import make_reader
    from rosbags.highlevel import AnyReader

    mcaps = sorted(bag.glob("*.mcap"))
    assert mcaps and (bag / "metadata.yaml").exists()
    with open(mcaps[0], "rb") as fh:
        mcap_topics = {c.topic for c in make_reader(fh).get_summary().channels.values()}
    with AnyReader([bag]) as reader:
        ros_topics = {c.topic for c in reader.connections}
        n_clock = sum(1 for _ in reader.messages(connections=[c for c in reader.connections if c.topic == "/clock"]))
    return mcap_topics, ros_topics, n_clock


def test_containers_up_equals_local_engine_and_bag_reads_as_host(lab, local_ref, tmp_path):
    from bringup.analysis.report import report_from_bag

    compose = lab.compose("plain")
    out = tmp_path / "run"
    t0 = time.monotonic()
    r = _cli("containers", "up", str(compose), "--out", str(out), "--no-progress")
    wall = time.monotonic() - t0
    assert r.returncode == 0, r.stderr[-3000:]
    obs_ref, dl_ref = traces(local_ref)
    obs, dl = traces(out)
    print(f"CONTAINERS run sats=12 hours=1 containers={len(json.loads((compose.parent / 'run_spec.json').read_text())['roles']) + 1} "
          f"wall_s={wall:.1f} observations={len(obs)} deliveries={len(dl)}")
    assert len(obs_ref) > 50 and len(dl_ref) > 10
    assert obs == obs_ref
    assert dl == dl_ref

    mcap_topics, ros_topics, n_clock = _bag_topics(out / "bag")
    _, host_ros, _ = _bag_topics(local_ref / "bag")
    assert mcap_topics == ros_topics and n_clock > 100
    lockstep = {t for t in ros_topics if t.startswith(("/sim/", "/_lockstep"))}  # the ROS engine's own
    assert ros_topics - lockstep == host_ros - {t for t in host_ros if t.startswith(("/sim/", "/_lockstep"))}

    rep = json.loads((out / "report.json").read_text())
    again = json.loads(json.dumps(report_from_bag(out / "bag")))
    assert rep == again
    ref = json.loads(json.dumps(report_from_bag(local_ref / "bag")))
    for key in _SCIENCE:
        if key in ref:
            assert rep[key] == ref[key], key
    assert (out / "report.md").stat().st_size > 0
    # the container run's report has the keys a local run's has (its /run/meta is made as `run` makes
    # it: the knowledge model and the OSSE figures were once lost), down to the sections' own keys
    assert set(rep) == set(ref)
    for key in ("osse", "knowledge", "value", "coverage"):
        assert set(rep[key]) == set(ref[key]), key
    # and its globe view (bringup/analysis/czml.py, from the bag alone) holds what the local run's does
    from bringup.cli.czml import write_globe

    assert write_globe(out / "bag", tmp_path / "globe") == write_globe(local_ref / "bag", tmp_path / "globe-ref")


@pytest.mark.browser
@pytest.mark.timeout(3600)  # a container run, `npm ci` of CesiumJS and two page loads in software WebGL
def test_globe_page_shows_a_container_runs_bag(lab, tmp_path, chromium, cesium_modules):
    compose = lab.compose("czml")  # its folder: tmp_path/czml; the page goes to tmp_path/globe
    out = tmp_path / "run"
    t0 = time.monotonic()
    r = _cli("containers", "up", str(compose), "--out", str(out), "--no-progress")
    run_s = time.monotonic() - t0
    assert r.returncode == 0, r.stderr[-3000:]
    t0 = time.monotonic()
    counts, status = check_globe_page(out / "bag", tmp_path, chromium, cesium_modules, "globe-container-run.png")
    rep = json.loads((out / "report.json").read_text())
    print(f"GLOBE container counts={json.dumps(counts)} entities={status['entities']} span={status['start']}.."
          f"{status['stop']} webgl={status['webgl']} run_wall_s={run_s:.1f} page_s={time.monotonic() - t0:.1f}")
    assert counts["looks"] == rep["observations"]["count"] > 50 and counts["satellites"] == SATS
    assert counts["stations"] > 0 and counts["links"] > 0 and counts["transfers"] > 0


def test_podman_compose_runs_the_file_as_written(lab, local_ref, tmp_path):
    from bringup.deploy.podman import podman_json

    compose = lab.compose("pc")
    project = compose.parent.name and json.loads((compose.parent / "run_spec.json").read_text())["bag_dir"].split("/")[2]
    pc = [str(Path(sys.executable).parent / "podman-compose"), "--podman-args=--runtime /usr/bin/runc", "-f", str(compose)]
    try:
        t0 = time.monotonic()
        r = subprocess.run([*pc, "up", "--abort-on-container-exit", "--exit-code-from", "clock"], capture_output=True,
                           text=True, timeout=1200, check=False, cwd=compose.parent)
        wall = time.monotonic() - t0
        assert r.returncode == 0, (r.stdout[-2000:], r.stderr[-2000:])
        vol = podman_json("volume", "inspect", f"{project}_runs")[0]["Mountpoint"]
        run_dir = Path(vol) / project
        obs_ref, dl_ref = traces(local_ref)
        obs, dl = traces(run_dir)
        print(f"CONTAINERS podman-compose wall_s={wall:.1f} observations={len(obs)} deliveries={len(dl)}")
        assert obs == obs_ref
        assert dl == dl_ref
        assert (run_dir / "report.json").exists()
    finally:
        d = subprocess.run([*pc, "down", "-v"], capture_output=True, text=True, timeout=300, check=False,
                           cwd=compose.parent)
    assert d.returncode == 0, d.stderr[-2000:]


def test_a_run_that_cannot_start_leaves_nothing(lab):
    from bringup.deploy.containers import leftovers

    compose = lab.compose("noimage", sats=3, hours=0.1)
    text = compose.read_text().replace(lab.image, "localhost/cdtn-no-such-image:none")
    compose.write_text(text)
    r = _cli("containers", "up", str(compose), "--no-progress", timeout=300)
    assert r.returncode == 2
    err = [ln for ln in r.stderr.splitlines() if "error" in ln]
    assert len(err) == 1 and "podman create" in err[0] and "cdtn-no-such-image" in err[0], r.stderr
    assert not any(leftovers(lab.projects[-1]).values())
