"""Hostile messages on a live ROS 2 run: forged, replayed and tampered traffic is rejected and counted.

A real ``constellation run --engine ros`` (one process per satellite, router, contact announcer and
clock; its own leased ROS_DOMAIN_ID, ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST; paced at 30x real
time so the attack lands while it runs) is started by the test; once its processes are up,
tests/faults/forger.py joins the same domain from its own rclpy process and publishes a fixed
corpus: forged observations (unsigned, and signed with another run's key), a forged step and a
forged stop on /sim/step, a forged hello and error ack on /sim/ack, envelopes posing as the DTN
router with bundles signed by the BPSec key the source used to hold, junk on every one of those
topics, and a genuine envelope of the run replayed, tampered with and moved to another topic.

Oracles:
* the run completes (exit 0: no node crashed, no host stopped, the run did not fail);
* its report equals the clean local-engine run's, key for key (runtime, engine, the security
  counters and the provenance's command line aside), and so do its observations and bundle deliveries: nothing forged was recorded or
  acted on;
* report.json ``security.rejected_by_process`` holds, topic by topic, exactly one rejection per
  forged message per subscription it reached (the forger counts what it published and how many
  subscriptions had matched), with the reason the forger expected; the clock got the forged
  observations and acks, every host the forged steps, sat_11 the envelopes posing as the router;
* the replayed genuine envelope is recorded once;
* repeated rejections are a few log lines, not one per message.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytestmark = [pytest.mark.faults, pytest.mark.system, pytest.mark.ros]

SATS, HOURS = 6, 0.5
HERE = Path(__file__).parent
SAT, OTHER = "sat_11", "sat_12"
HOSTS = SATS + 2  # the satellites, the router, the contact announcer


def _cmd(engine, out, *extra):
    return [sys.executable, "-m", "bringup.cli", "run", "--engine", engine, "--sats", str(SATS), "--hours",
            str(HOURS), "--out", str(out), "--no-plots", "--no-progress", *extra]


def _trace(bag):
    from bringup.recording.bag import BagReader
    from msgs_json import codec
    from msgs_json import schemas as S

    obs, dlv = [], []
    with BagReader(bag) as b:
        topics = [t.topic for t in b.topics() if t.topic.endswith(("/observations", "/dtn/events"))]
        for e in b.envelopes(topics):
            m = codec.decode(e.topic, e.data)
            if isinstance(m, S.Observation):
                obs.append((m.sat, m.gp, m.t_ns))
            elif isinstance(m, S.BundleDelivered):
                dlv.append((m.bundle_id, m.sat, m.t_ns))
    return sorted(obs), sorted(dlv)


def _comparable(rep: dict) -> dict:
    from bringup.analysis.report import flatten

    # (provenance: the same scenario; the command lines name another engine and folder)
    return {k: v for k, v in flatten(rep).items()
            if (not k.startswith(("runtime.", "security.", "provenance.")) and k != "engine")
            or k == "provenance.scenario_toml"}


def test_forged_messages_are_rejected_counted_and_change_nothing(tmp_path):
    clean = tmp_path / "clean"
    r = subprocess.run(_cmd("local", clean), capture_output=True, text=True, timeout=600, check=False)
    assert r.returncode == 0, r.stderr[-2000:]
    out = tmp_path / "attacked"
    run = subprocess.Popen(_cmd("ros", out, "--real-time-factor", "30"), stdout=subprocess.PIPE,
                           stderr=subprocess.PIPE, text=True)
    forger = None
    sent_file = tmp_path / "forged.json"
    try:
        pid_file = out / "logs" / f"{SAT}.pid"
        deadline = time.monotonic() + 180
        while not pid_file.exists() and run.poll() is None and time.monotonic() < deadline:
            time.sleep(0.2)
        assert pid_file.exists(), "the ROS run did not start its satellite processes"
        domain = json.loads((out / "run_spec.json").read_text())["domain_id"]
        env = dict(os.environ, ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
                   PYTHONPATH=str(HERE.parents[1]), FORGER_HOSTS=str(HOSTS))
        forger = subprocess.Popen([sys.executable, str(HERE / "forger.py"), SAT, OTHER, str(sent_file)],
                                  env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        _f_out, f_err = forger.communicate(timeout=600)
        still_running = run.poll() is None  # else the forgeries may have come after the final step
        _stdout, stderr = run.communicate(timeout=900)
    finally:
        for p in (run, forger):
            if p is not None and p.poll() is None:
                p.kill()
    assert forger.returncode == 0, f_err[-2000:]
    assert still_running, "the run ended before the forger was done: pace it slower"
    assert run.returncode == 0, stderr[-3000:]
    sent = json.loads(sent_file.read_text())

    attacked, reference = json.loads((out / "report.json").read_text()), json.loads((clean / "report.json").read_text())
    assert _comparable(attacked) == _comparable(reference)
    assert _trace(out / "bag") == _trace(clean / "bag")

    by = attacked["security"]["rejected_by_process"]
    for topic, what in sent.items():
        counted: dict[str, int] = {}
        for per_topic in by.values():
            for reason, n in per_topic.get(topic, {}).items():
                counted[reason] = counted.get(reason, 0) + n
        expected = {reason: n * what["matched"] for reason, n in what["reasons"].items()}
        assert counted == expected, (topic, counted, expected, what)
    assert by["clock"][f"/{SAT}/observations"] == {"unauthenticated": 20, "bad_mac": 5}
    assert by["clock"]["/sim/ack"] == {"unauthenticated": 5}
    assert all(by[h]["/sim/step"] == {"unauthenticated": 4} for h in by if h != "clock"), by
    assert len([h for h in by if h != "clock"]) == HOSTS
    assert by[SAT][f"/{SAT}/dtn/in"] == {"unauthenticated": 10, "malformed": 5}
    total = sum(n * w["matched"] for w in sent.values() for n in w["reasons"].values())
    assert sum(attacked["security"]["rejected"].values()) == total
    assert sent[f"/{SAT}/schedule"]["replays"] == 3

    # repeated rejections are rate-limited in the logs: a few lines, not one per message
    clock_log = (out / "logs" / "clock.log").read_text(errors="replace")
    assert len(re.findall(rf"rejected \(unauthenticated\).*{SAT}/observations", clock_log)) <= 3
    print(f"forged {total} rejections expected and counted: {attacked['security']['rejected']}")
