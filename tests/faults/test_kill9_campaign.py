"""A kill -9 campaign through the CLI: ``constellation run --engine ros --restart 1``, one process of the run
killed at a random instant, ten times over; every report equals the clean run's, deliveries included.

The scenario carries DTN traffic across planes (12 satellites in 3 planes, 1 h, distributed: the
engine-equivalence test's; bundles are delivered over the ISLs), so a lost or doubled bundle shows.

Oracles:

* a clean run of the same command (no kill) is the reference; it equals the local engine's run in
  observations and deliveries (tests/system/test_engines_equal.py checks the same), and delivers
  more than 10 bundles;
* each of ``AGILE_DTN_KILL_RUNS`` (default 10) runs has one process - a satellite, the router, the
  ground station or the clock, drawn at random (seeded) - killed with SIGKILL at a random instant
  while it steps; it exits 0, restarted that process once, and its report.json equals the clean
  run's key for key (runtime aside), its observations (sat, gp, t) and bundle deliveries (bundle,
  receiver, t) equal the clean run's, and its bag is sealed and verified.

One ``KILL9`` line per run gives the victim, the instant and what was compared. Long (about a minute
and a half per run on 2 free cores): ``slow``.
"""

from __future__ import annotations

import json
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytestmark = [pytest.mark.faults, pytest.mark.ros, pytest.mark.system, pytest.mark.slow]

REPO = Path(__file__).resolve().parents[2]
SATS, HOURS = 12, 1.0
RUNS = int(os.environ.get("AGILE_DTN_KILL_RUNS", "10"))


def _cmd(engine: str, out: Path, *extra: str) -> list[str]:
    return [sys.executable, "-m", "bringup.cli", "run", "--engine", engine, "--sats", str(SATS), "--hours", str(HOURS),
            "--out", str(out), "--no-plots", "--no-progress", *extra]


def _env() -> dict[str, str]:
    return dict(os.environ, PYTHONPATH=str(REPO), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")


def _traces(bag: Path):
    from bringup.analysis.trace import deliveries_from_bag, observations_from_bag

    return observations_from_bag(bag), deliveries_from_bag(bag)


def _report(out: Path) -> dict:
    rep = json.loads((out / "report.json").read_text())
    rep.pop("runtime")
    rep["provenance"].pop("command")  # (names each run's own --out folder; everything else must be equal)
    return rep


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    base = tmp_path_factory.mktemp("kill9")
    local = base / "local"
    r = subprocess.run(_cmd("local", local), cwd=REPO, env=_env(), capture_output=True, text=True, timeout=900, check=False)
    assert r.returncode == 0, r.stderr[-3000:]
    out = base / "clean"
    proc = subprocess.Popen(_cmd("ros", out, "--restart", "1"), cwd=REPO, env=_env(), stderr=subprocess.PIPE,
                            text=True)
    try:
        _up(out, proc)
        t0 = time.monotonic()  # (from the instant the campaign's runs draw their kill times from)
        err = proc.communicate(timeout=1800)[1]
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, err[-3000:]
    obs, dl = _traces(out / "bag")
    assert (obs, dl) == _traces(local / "bag")
    assert len(dl) > 10, "the scenario must deliver bundles over the ISLs"
    return out, time.monotonic() - t0


def _up(out: Path, proc: subprocess.Popen, timeout_s: float = 600.0) -> dict[str, int]:
    """Wait until every process of the run has started (its pid file) and the clock has its journal;
    their pids."""
    deadline = time.monotonic() + timeout_s
    roles: list[str] = []
    while time.monotonic() < deadline:
        assert proc.poll() is None, proc.stderr.read()[-3000:]
        if not roles and (out / "run_spec.json").exists():
            try:
                roles = json.loads((out / "run_spec.json").read_text())["roles"]
            except ValueError:
                pass
        pids = {p.stem: int(p.read_text() or 0) for p in (out / "logs").glob("*.pid")} if (out / "logs").exists() else {}
        if roles and set(pids) >= {*roles, "clock"} and (out / "state" / "clock.sqlite").exists():
            return pids
        time.sleep(0.2)
    raise AssertionError("the run did not start stepping")


def test_kill9_campaign_every_report_equals_the_clean_run(clean, tmp_path):
    ref_out, ref_wall = clean
    ref_rep = _report(ref_out)
    ref_obs, ref_dl = _traces(ref_out / "bag")
    rng = random.Random(31)
    lines = []
    i = 0
    while sum("killed=True" in ln for ln in lines) < RUNS:
        # (a run that ends before its kill instant - the machine got faster - is drawn again, a few times)
        assert i < RUNS + 5, "\n".join(lines)
        i += 1
        out = tmp_path / f"run{i}"
        proc = subprocess.Popen(_cmd("ros", out, "--restart", "1"), cwd=REPO, env=_env(), stderr=subprocess.PIPE,
                                text=True)
        try:
            pids = _up(out, proc)
            t_start = time.monotonic()
            victim = rng.choice(sorted(pids))
            # an instant while the run goes on (the clean run took ref_wall from the same point to its end)
            delay = rng.uniform(0.5, max(1.0, 0.85 * ref_wall))
            time.sleep(delay)
            killed = False
            if proc.poll() is None:
                try:
                    os.kill(int((out / "logs" / f"{victim}.pid").read_text()), signal.SIGKILL)
                    killed = True
                except ProcessLookupError:  # (the victim had already finished: the run is ending; drawn again)
                    pass
            err = proc.communicate(timeout=1800)[1]
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        wall = time.monotonic() - t_start
        assert proc.returncode == 0, (victim, err[-3000:])
        restarts = json.loads((out / "report.json").read_text())["runtime"].get("process_restarts")
        rep = _report(out)
        obs, dl = _traces(out / "bag")
        same = rep == ref_rep and obs == ref_obs and dl == ref_dl
        line = (f"KILL9 run={i} victim={victim} at={delay:.1f}s killed={killed} restarts={restarts} "
                f"observations={len(obs)}/{len(ref_obs)} deliveries={len(dl)}/{len(ref_dl)} "
                f"report_equal={rep == ref_rep} integrity={rep['integrity']['status']} wall_s={wall:.0f}")
        print(line, flush=True)
        lines.append(line)
        if not killed:
            continue
        assert restarts == 1, line
        assert rep["integrity"]["status"] == "verified", line
        assert same, (line, {k: (rep.get(k), ref_rep.get(k)) for k in set(rep) | set(ref_rep)
                             if rep.get(k) != ref_rep.get(k)})
    print("\n".join(lines))
