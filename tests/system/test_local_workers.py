"""`constellation run --engine local --workers N`: satellites stepped in worker processes
(bringup/worker_group.py). Oracle: the one-process run (--workers 0) of the same scenario and seed -
the same report, the same envelopes in the same order (but for the scheduler's measured CPU time in
its schedule messages), the same store rows; and a run stopped by Ctrl-C or a SIGKILL of its main
process leaves a readable bag and no process behind."""

from __future__ import annotations

import json
import os
import signal
import sqlite3
import subprocess
import sys
import time

import pytest

from bringup.recording import BagReader

SATS, HOURS = "12", "2"


def _run(out, workers: int) -> None:
    from bringup.cli import main

    assert main(["run", "--engine", "local", "--sats", SATS, "--hours", HOURS, "--no-plots", "--no-progress",
                 "--workers", str(workers), "--out", str(out)]) == 0


def _envelopes(bag):
    with BagReader(bag) as r:
        topics = [t.topic for t in r.topics()]
        out = []
        for e in r.envelopes(topics):
            if e.topic == "/run/meta":  # (holds the run's wall time)
                continue
            data = e.data
            if e.topic.endswith("/schedule"):
                msg = json.loads(data)
                msg.pop("solve_cpu_s", None)  # measured, differs run to run
                data = json.dumps(msg, sort_keys=True)
            out.append((e.t_ns, e.source, e.seq, e.topic, data))
        return out


def _rows(path):
    with sqlite3.connect(path) as c:
        return [sorted(c.execute(f"SELECT * FROM {t}").fetchall())
                for (t,) in c.execute("SELECT name FROM sqlite_master WHERE type='table' ORDER BY name")]


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    base = tmp_path_factory.mktemp("workers")
    for w in (0, 1, 2):
        _run(base / f"w{w}", w)
    return base


@pytest.mark.parametrize("workers", [1, 2])
def test_workers_change_nothing_the_run_produces(runs, workers):
    ref, got = runs / "w0", runs / f"w{workers}"
    a, b = json.loads((ref / "report.json").read_text()), json.loads((got / "report.json").read_text())
    a.pop("runtime"), b.pop("runtime")
    assert a == b
    assert a["dtn"]["bundles_delivered"] > 0 and a["observations"]["count"] > 0
    ea, eb = _envelopes(ref / "bag"), _envelopes(got / "bag")
    assert len(ea) > 1000 and ea == eb
    stores = sorted(p.name for p in (ref / "store").glob("*.sqlite"))
    assert len(stores) == int(SATS)
    for name in stores:
        assert _rows(ref / "store" / name) == _rows(got / "store" / name), name


def _children(pid: int) -> list[int]:
    try:
        with open(f"/proc/{pid}/task/{pid}/children") as fh:
            return [int(x) for x in fh.read().split()]
    except FileNotFoundError:
        return []


def _start(out):
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    cmd = [sys.executable, "-m", "bringup.cli", "run", "--engine", "local", "--sats", "12", "--hours", "6",
           "--no-plots", "--no-progress", "--workers", "1", "--out", str(out)]
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                         start_new_session=True)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:  # running: the recorder and the worker are up, the bag grows
        kids = _children(p.pid)
        bag = out / "bag" / "bag.mcap"
        if len(kids) >= 2 and bag.exists() and bag.stat().st_size > 200_000:
            return p, kids
        assert p.poll() is None, p.communicate()
        time.sleep(0.1)
    p.kill()
    pytest.fail("the run did not get going within 120 s")


def _gone(pids, timeout=60.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        alive = []
        for q in pids:
            try:
                os.kill(q, 0)
                with open(f"/proc/{q}/stat") as fh:
                    if fh.read().split(")")[-1].split()[0] != "Z":
                        alive.append(q)
            except (ProcessLookupError, FileNotFoundError):
                pass
        if not alive:
            return True
        time.sleep(0.1)
    return False


def test_ctrl_c_closes_bag_and_workers(tmp_path):
    out = tmp_path / "run"
    p, kids = _start(out)
    os.killpg(p.pid, signal.SIGINT)  # as a terminal's Ctrl-C: the whole group
    _, err = p.communicate(timeout=120)
    assert p.returncode != 0
    assert "Traceback" not in err, err
    assert _gone(kids)
    with BagReader(out / "bag") as r:
        assert r.count > 1000


def test_main_process_killed_leaves_readable_bag_and_no_worker(tmp_path):
    out = tmp_path / "run"
    p, kids = _start(out)
    os.kill(p.pid, signal.SIGKILL)
    p.communicate(timeout=60)
    assert _gone(kids), "a child of the killed run is still alive"
    with BagReader(out / "bag") as r:
        assert r.count > 1000
