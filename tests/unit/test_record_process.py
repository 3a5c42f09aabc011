"""The local engine's recorder process (bringup/recording/recorder_process.py).

Oracles: the same calls made in-process on a BagWriter + VizFeed write the same MCAP bytes, and
build_report over the same envelopes gives the same report; a failing child, a SIGINT to the child
and a parent killed mid-run each end as the module docstring says (error named / ignored / bag
closed and readable with what was handed over).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest

from bringup.recording.recorder_process import Recorder, RecorderError
from bringup.recording.bag import BagReader, BagWriter
from bringup.analysis.report import ReportBuilder, RunMeta, build_report
from bringup.recording.metrics_feed import MetricsFeed
from bringup.recording.viz_feed import VizFeed
from bringup.scenario.world import World
from msgs_json import codec
from msgs_json import schemas as S
from msgs_json.envelope import Envelope
from msgs_json.topics import VIZ_MARKERS, VIZ_VALUE, fix_topic

S_NS = 1_000_000_000


@pytest.fixture(scope="module")
def world(paper_scenario):
    return World.build(paper_scenario.with_overrides(sats=6, hours=1))


def _steps(world, n_steps: int = 360):
    """(t_ns, envelopes) per 10 s step: observations (text), schedules, bundles on the air (bytes)."""
    seq: dict[str, int] = {}
    for k in range(n_steps):
        t = k * 10 * S_NS
        envs = []
        for i, sat in enumerate(world.sat_names):
            if (k + i) % 7 == 0:
                obs = S.Observation(sat=sat, gp=(k * 13 + i) % world.n_gp, t_ns=t, assumed_value=1.5 + i,
                                    recorded_value=2.0 + k % 5, schedule_version=1)
                envs.append((f"/{sat}/observations", codec.encode(obs), sat))
            if (k + i) % 3 == 0:
                envs.append((f"/{sat}/dtn/out", bytes([k % 256, i]) * 40, sat))
        out = []
        for topic, data, src in envs:
            s = seq.get(src, 0)
            seq[src] = s + 1
            out.append(Envelope(t, src, s, topic, data))
        yield t, out


def _meta(world) -> RunMeta:
    return RunMeta(scenario="paper", mode="distributed", engine="local", seed=1, horizon_s=3600.0,
                   n_sats=len(world.sat_names), n_gp=world.n_gp)


def test_same_bag_and_report_as_in_process(world, tmp_path):
    meta = _meta(world)
    kept = []
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    with BagWriter(tmp_path / "a" / "bag", epoch_ns=world.scenario.epoch_ns) as bag:  # the recorder's clock
        viz = VizFeed(world)
        metrics = MetricsFeed(world.scenario.value.revisit_zero_s)
        for t, envs in _steps(world):
            bag.write_envelopes(envs)
            for e in envs:
                metrics.observe(e)
            bag.write_clock(t)
            viz.write(bag, t)
            metrics.write(bag, t)
            kept += envs
        metrics.write(bag, t, final=True)
    with Recorder(tmp_path / "b" / "bag", world, report=ReportBuilder) as rec:
        for t, envs in _steps(world):
            rec.write_envelopes(envs)
            rec.step(t)
        rep = rec.finish(meta, {"wall_s": 1.0})
    for name in ("bag.mcap", "metadata.yaml"):
        assert (tmp_path / "a" / "bag" / name).read_bytes() == (tmp_path / "b" / "bag" / name).read_bytes(), name
    assert rep == build_report(kept, meta, {"wall_s": 1.0})
    assert rep["observations"]["count"] > 100
    with BagReader(tmp_path / "b" / "bag") as r:
        assert {t.topic for t in r.topics()} >= {"/clock", VIZ_MARKERS, VIZ_VALUE, fix_topic(world.sat_names[0])}
        *_, (_, _, last) = r.typed([VIZ_VALUE])
    assert last.data == rep["value"]["cumulative"] and last.data > 0  # the plotted series ends at the report's value


def test_child_failure_is_named(world, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    rec = Recorder(blocker / "bag", None, report=ReportBuilder)  # the child cannot make its bag under a file
    with pytest.raises(RecorderError, match=r"recorder for .*file/bag failed: .*") as ei:
        for t, envs in _steps(world, 200):
            rec.write_envelopes(envs)
            rec.step(t)
        rec.finish()
    assert "\n" not in str(ei.value)
    rec.close()  # idempotent after a failure
    assert rec._proc.exitcode == 1


def test_child_ignores_sigint_and_parent_closes_the_bag(world, tmp_path):
    with Recorder(tmp_path / "bag", None) as rec:
        steps = list(_steps(world, 50))
        for t, envs in steps[:25]:
            rec.write_envelopes(envs)
            rec.step(t)
        os.kill(rec._proc.pid, signal.SIGINT)  # Ctrl-C reaches the whole process group
        time.sleep(0.3)
        assert rec._proc.is_alive()
        for t, envs in steps[25:]:
            rec.write_envelopes(envs)
            rec.step(t)
        assert rec.finish() is None
    n = sum(len(e) + 1 for _, e in steps)  # envelopes and one /clock per step
    with BagReader(tmp_path / "bag") as r:
        assert r.count == n


def test_parent_killed_leaves_a_readable_bag(tmp_path):
    """A parent SIGKILLed after handing over 3 batches: the child closes the bag with all of them."""
    bag = tmp_path / "bag"
    code = textwrap.dedent(f"""
        import os, signal
        from bringup.recording.recorder_process import Recorder, _BATCH
        from msgs_json.envelope import Envelope
        rec = Recorder({str(bag)!r}, None)
        k = 0
        for b in range(3):
            rec.write_envelopes([Envelope(k + i, "sat_11", k + i, "/sat_11/dtn/out", b"x" * 50)
                                 for i in range(_BATCH)])  # one batch: handed over at once
            k += _BATCH
        rec.write_envelopes([Envelope(k, "sat_11", k, "/sat_11/dtn/out", b"y")])  # still buffered
        print(rec._proc.pid, flush=True)
        os.kill(os.getpid(), signal.SIGKILL)
    """)
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert p.returncode == -signal.SIGKILL, p.stderr
    child = int(p.stdout.split()[0])
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline and os.path.exists(f"/proc/{child}") and \
            "zombie" not in open(f"/proc/{child}/status").read():
        time.sleep(0.05)
    from bringup.recording.recorder_process import _BATCH

    with BagReader(bag) as r:
        assert r.count == 3 * _BATCH
