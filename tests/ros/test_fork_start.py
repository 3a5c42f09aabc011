"""Hosts forked from the launcher (bringup/engine/ros/fork_start.py).

Oracles: a forked `constellation node` gives the launcher its exit code (2 for a missing run spec,
its one-line error in the role's log) and a signal as ``-signum``, as Popen does; ``wait`` times out
with subprocess.TimeoutExpired; a toy run whose hosts are forked records exactly the envelopes of
the local engine for the same participants, its hosts being children of the launcher's process (the
pid files) that loaded nothing of their own (the prepare hook ran once, in the launcher); a forked
host killed with SIGKILL is named by its signal; a prepare hook that fails in the launcher is named and
no process is started.
"""

from __future__ import annotations

import os
import signal
import subprocess
import time

import pytest

from bringup.cli.main import main
from bringup.engine.keys import ENV_KEYS_DIGEST, KEYS_FILE_NAME, RunKeys
from bringup.engine.local import run_local
from bringup.engine.ros.fork_start import fork_node
from bringup.engine.ros.launcher import REPO, child_env, launch, lease_domain_id
from bringup.engine.ros.run_spec import RunSpec
from bringup.recording.bag import BagReader
from tests.ros import toy_participants as toy

pytestmark = [pytest.mark.ros, pytest.mark.timeout(180)]
S = 10**9


def test_forked_node_exit_code_and_log(tmp_path):
    log = tmp_path / "x.log"
    p = fork_node(["node", "--run-spec", str(tmp_path / "missing.json"), "--role", "x"], dict(os.environ),
                  log, str(REPO), main)
    assert p.wait(timeout=60) == 2
    text = log.read_text()
    assert "constellation node: error:" in text and "missing.json" in text, text
    assert p.poll() == 2 and p.returncode == 2


def test_forked_node_wait_times_out_and_a_signal_is_negative(tmp_path):
    keys = RunKeys.generate()
    spec = RunSpec(factory="tests.ros.toy_participants:make", roles=toy.roles(2, pingpong=False),
                   horizon_ns=60 * S, max_step_ns=10 * S, extra={"n_counters": 2},
                   keys_file=str(keys.write(tmp_path / KEYS_FILE_NAME)))
    spec.to_file(tmp_path / "run_spec.json")
    with lease_domain_id() as lease:  # no clock: the host waits for its lifecycle manager
        env = child_env(lease.domain_id)
        env[ENV_KEYS_DIGEST] = keys.digest()
        p = fork_node(["node", "--run-spec", str(tmp_path / "run_spec.json"), "--role", "c0"], env,
                      tmp_path / "c0.log", str(REPO), main)
        try:
            with pytest.raises(subprocess.TimeoutExpired):
                p.wait(timeout=1.0)
            assert p.poll() is None
            p.kill()
            assert p.wait(timeout=30) == -signal.SIGKILL
        finally:
            if p.poll() is None:
                os.kill(p.pid, signal.SIGKILL)
                p.wait()


def test_forked_run_equals_local_engine(tmp_path):
    spec = RunSpec(factory="tests.ros.toy_participants:make", prepare="tests.ros.toy_participants:slow_prepare",
                   roles=toy.roles(3), horizon_ns=120 * S, max_step_ns=10 * S,
                   bag_dir=str(tmp_path / "bag"), progress_period_s=0.2,
                   extra={"n_counters": 3, "prepare_s": {"run": 0.0}})
    parents: dict[str, int] = {}

    def on_progress(p):
        for f in (tmp_path / "run" / "logs").glob("*.pid"):
            pid = int(f.read_text())
            try:
                with open(f"/proc/{pid}/stat") as fh:
                    parents.setdefault(f.stem, int(fh.read().rsplit(")", 1)[1].split()[1]))
            except OSError:
                pass

    res = launch(spec, tmp_path / "run", progress=on_progress, fork=main)
    assert res.ok, res.message
    assert res.last.t_ns == spec.horizon_ns
    hosts = set(spec.roles)
    assert hosts <= set(parents) and all(parents[r] == os.getpid() for r in hosts), parents
    assert "hosts forked from it" in (tmp_path / "run" / "logs" / "prepare.log").read_text()
    ref = run_local(toy.all_participants(spec), horizon_ns=spec.horizon_ns, max_step_ns=spec.max_step_ns)
    with BagReader(tmp_path / "bag") as bag:
        got = list(bag.envelopes([t.topic for t in bag.topics() if t.topic.startswith("/toy/")]))

    def key(e):
        return (e.t_ns, e.source, e.seq, e.topic, e.data)

    assert got and sorted(map(key, got)) == sorted(map(key, ref.envelopes))


def test_killed_forked_host_is_named(tmp_path):
    spec = RunSpec(factory="tests.ros.toy_participants:make", roles=toy.roles(3, pingpong=False),
                   horizon_ns=3600 * S, max_step_ns=10 * S, real_time_factor=50.0, ack_timeout_s=5.0,
                   progress_period_s=0.2, extra={"n_counters": 3})
    killed: list[int] = []

    def on_progress(p):
        if p.steps >= 3 and not killed:
            pid = int((tmp_path / "logs" / "c2.pid").read_text())
            os.kill(pid, signal.SIGKILL)
            killed.append(pid)

    t0 = time.monotonic()
    res = launch(spec, tmp_path, progress=on_progress, fork=main)
    assert killed and not res.ok
    assert "process 'c2' killed by SIGKILL" in res.message, res.message
    assert "c2" in res.failed_roles
    assert time.monotonic() - t0 < 60


def test_failed_preload_is_named_and_starts_nothing(tmp_path):
    spec = RunSpec(factory="tests.ros.toy_participants:make", prepare="tests.ros.toy_participants:slow_prepare",
                   roles=toy.roles(2, pingpong=False), horizon_ns=60 * S, max_step_ns=10 * S,
                   extra={"n_counters": 2, "prepare_fail": "run"})
    res = launch(spec, tmp_path / "run", fork=main)
    assert not res.ok and res.failed_roles == ["prepare"]
    assert "preparing the run" in res.message and "cannot get ready" in res.message, res.message
    assert not (tmp_path / "run" / "logs" / "clock.log").exists()
