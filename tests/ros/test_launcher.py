"""The launcher: domain-id leases, child environment, run spec, a killed process named, Ctrl-C.

Oracles: the run spec round-trips; two leases never share an id; a participant process killed
mid-run (SIGKILL) is named in the result; SIGINT to a running launcher ends every process and
leaves a bag that both the `mcap` reader and `rosbags` (via BagReader) open.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from bringup.errors import UserError
from bringup.engine.ros.launcher import REPO, child_env, launch, lease_domain_id
from bringup.engine.local import run_local
from bringup.recording.bag import BagReader
from bringup.engine.ros.run_spec import RunSpec
from tests.ros import toy_participants as toy

pytestmark = [pytest.mark.ros, pytest.mark.timeout(180)]
S = 10**9


def test_run_spec_round_trip_and_errors(tmp_path):
    spec = RunSpec(factory="tests.ros.toy_participants:make", roles=["a", "b"], horizon_ns=5, max_step_ns=1,
                   extra={"n_counters": 2})
    spec.to_file(tmp_path / "s.json")
    assert RunSpec.from_file(tmp_path / "s.json") == spec
    (tmp_path / "bad.json").write_text('{"factory": "x:y", "roles": ["clock"]}')
    with pytest.raises(UserError, match="clock"):
        RunSpec.from_file(tmp_path / "bad.json")
    with pytest.raises(UserError, match="no such file"):
        RunSpec.from_file(tmp_path / "missing.json")


def test_domain_leases_are_exclusive():
    a = lease_domain_id(90, 91)
    b = lease_domain_id(90, 91)
    try:
        assert {a.domain_id, b.domain_id} == {90, 91}
        with pytest.raises(UserError, match="no free ROS_DOMAIN_ID"):
            lease_domain_id(90, 91)
    finally:
        a.release()
        b.release()
    lease_domain_id(90, 90).release()  # free again


def test_child_env_is_loopback_and_isolated():
    env = child_env(42)
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    assert env["ROS_DOMAIN_ID"] == "42"
    assert Path(env["FASTRTPS_DEFAULT_PROFILES_FILE"]).is_file()


def _pids_with(arg: str) -> list[int]:
    out = []
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                cmd = Path(f"/proc/{d}/cmdline").read_bytes().split(b"\0")
            except OSError:
                continue
            if arg.encode() in cmd and b"node" in cmd:
                out.append(int(d))
    return out


def test_killed_process_is_named(tmp_path):
    spec = RunSpec(factory="tests.ros.toy_participants:make", roles=toy.roles(3, pingpong=False),
                   horizon_ns=3600 * S, max_step_ns=10 * S, real_time_factor=50.0, ack_timeout_s=5.0,
                   progress_period_s=0.2, extra={"n_counters": 3})
    run_spec_path = str(tmp_path / "run_spec.json")
    killed: list[int] = []

    def on_progress(p):
        if p.steps >= 3 and not killed:
            pids = [pid for pid in _pids_with(run_spec_path) if str(pid) and
                    b"c2" in Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")]
            assert len(pids) == 1
            os.kill(pids[0], signal.SIGKILL)
            killed.append(pids[0])

    t0 = time.monotonic()
    res = launch(spec, tmp_path, progress=on_progress)
    assert killed
    assert not res.ok
    assert "process 'c2' killed by SIGKILL" in res.message, res.message
    assert "c2" in res.failed_roles
    assert time.monotonic() - t0 < 60


def test_slow_start_is_waited_for_and_named_not_fatal(tmp_path):
    """Ready is not a step: a host that takes longer to get ready (its prepare hook: 8 s) than the
    per-step ack deadline (3 s) is waited for; the clock names it while it waits (the progress's
    status and not_ready, and the clock's log), and the run completes. The launcher's own prepare
    call runs once, before any process starts."""
    spec = RunSpec(factory="tests.ros.toy_participants:make", prepare="tests.ros.toy_participants:slow_prepare",
                   roles=toy.roles(3, pingpong=False), horizon_ns=60 * S, max_step_ns=10 * S,
                   bag_dir=str(tmp_path / "bag"), ack_timeout_s=3.0, startup_timeout_s=None,
                   extra={"n_counters": 3, "prepare_s": {"c1": 8.0, "run": 0.5}})
    seen = []
    res = launch(spec, tmp_path / "run", progress=seen.append)
    assert res.ok, res.message
    assert res.last.t_ns == spec.horizon_ns
    statuses = [p for p in seen if p.status]
    assert statuses[0].status.startswith("preparing the run")
    done = [p.status for p in statuses if p.status.startswith("prepared in ")]  # the prepare time, told once
    assert len(done) == 1 and float(done[0].split()[2]) >= 0.5, done
    waiting = [p for p in statuses if p.not_ready]
    assert waiting and all(p.not_ready == ("c1",) for p in waiting), [p.status for p in statuses]
    assert "c1" in waiting[0].status and waiting[0].wall_s >= 5.0
    log = (tmp_path / "run" / "logs" / "clock.log").read_text()
    assert "waiting for 1 of 3 processes to be ready after 5 s: c1" in log
    assert "node prepare: ready" in (tmp_path / "run" / "logs" / "prepare.log").read_text()
    assert "node c1: ready" in (tmp_path / "run" / "logs" / "c1.log").read_text()


def test_failed_prepare_is_named_and_starts_nothing(tmp_path):
    spec = RunSpec(factory="tests.ros.toy_participants:make", prepare="tests.ros.toy_participants:slow_prepare",
                   roles=toy.roles(2, pingpong=False), horizon_ns=60 * S, max_step_ns=10 * S,
                   extra={"n_counters": 2, "prepare_fail": "run"})
    res = launch(spec, tmp_path / "run")
    assert not res.ok and res.failed_roles == ["prepare"]
    assert "preparing the run" in res.message and "cannot get ready" in res.message, res.message
    assert not (tmp_path / "run" / "logs" / "clock.log").exists()


def test_host_that_does_not_exit_after_a_clean_run_is_killed_and_the_run_stands(tmp_path):
    """Seen under load (full suite, 2 cores): after the clock's stop, one host hung in rclpy's
    destroy_node (SIGTERM unhandled, blocked in C) and the launcher's SIGKILL turned a complete run
    into "process 'sat_12' failed (exit code -9): no message". The run stands (every host acked the
    final step: its envelopes are in the bag), the host is named in ``lingered``, its log says why
    it was killed and holds its Python stacks (SIGUSR1, faulthandler)."""
    spec = RunSpec(factory="tests.ros.toy_participants:make", roles=toy.roles(3, pingpong=False),
                   horizon_ns=120 * S, max_step_ns=10 * S, bag_dir=str(tmp_path / "bag"), ack_timeout_s=10.0,
                   progress_period_s=0.2, extra={"n_counters": 3, "linger": "c1"})
    t0 = time.monotonic()
    res = launch(spec, tmp_path / "run")
    logs = {p.name: p.read_text(errors="replace") for p in (tmp_path / "run" / "logs").glob("*.log")}
    assert res.ok, (res.message, logs)
    assert res.last.t_ns == spec.horizon_ns
    assert len(res.lingered) == 1 and "'c1'" in res.lingered[0], res.lingered
    assert "c1 still running 5 s after SIGTERM" in logs["c1.log"], logs["c1.log"]
    assert "linger" in logs["c1.log"]  # its stack, written on SIGUSR1
    assert "still running" not in logs["c0.log"] + logs["c2.log"]
    assert time.monotonic() - t0 < 90
    ref = run_local(toy.all_participants(spec), horizon_ns=spec.horizon_ns, max_step_ns=spec.max_step_ns)
    with BagReader(tmp_path / "bag") as bag:
        got = list(bag.envelopes([t.topic for t in bag.topics() if t.topic.startswith("/toy/")]))

    def key(e):
        return (e.t_ns, e.source, e.seq, e.topic, e.data)

    assert sorted(map(key, got)) == sorted(map(key, ref.envelopes)) and got


def test_sigint_leaves_readable_bag(tmp_path):
    # Python installs its KeyboardInterrupt handler only if SIGINT is not ignored at start, and a
    # pytest started as a background job of a non-interactive shell passes SIGINT on ignored:
    # the launcher would then run to its end (seen: "rc 0"). The script restores the handler.
    script = f"""
import signal, sys
signal.signal(signal.SIGINT, signal.default_int_handler)
from bringup.engine.ros.launcher import launch
from bringup.engine.ros.run_spec import RunSpec
spec = RunSpec(factory="tests.ros.toy_participants:make", roles=["pingpong", "c0", "c1"],
               horizon_ns=3600 * 10**9, max_step_ns=10**10, real_time_factor=100.0,
               bag_dir={str(tmp_path / "bag")!r}, progress_period_s=0.2, extra={{"n_counters": 2}})
res = launch(spec, {str(tmp_path / "run")!r}, progress=lambda p: print("steps", p.steps, flush=True))
print("rc", res.returncode, res.message, flush=True)
sys.exit(0 if res.returncode == 130 else 1)
"""
    env = child_env(0)  # the launcher picks its own domain for the children
    proc = subprocess.Popen([sys.executable, "-c", script], cwd=str(REPO), env=env, stdout=subprocess.PIPE, text=True)
    try:
        for line in proc.stdout:  # wait until it is stepping (bounded by the test timeout)
            if line.startswith("steps") and int(line.split()[1]) >= 5:
                break
        proc.send_signal(signal.SIGINT)
        rest = proc.communicate(timeout=60)[0]
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, rest
    assert "interrupted" in rest
    with BagReader(tmp_path / "bag") as bag:
        topics = {t.topic: t.count for t in bag.topics()}
        assert topics["/clock"] >= 5
        assert topics["/toy/ping"] >= 1
        n_env = sum(1 for _ in bag.envelopes(["/toy/ping", "/toy/pong"]))
    from mcap.reader import make_reader

    mcap_file = next((tmp_path / "bag").glob("*.mcap"))
    with open(mcap_file, "rb") as fh:
        n = sum(1 for _ in make_reader(fh).iter_messages(topics=["/toy/ping", "/toy/pong"]))
    assert n == n_env > 0
    assert not _pids_with(str(tmp_path / "run" / "run_spec.json"))  # every child is gone


def test_empty_shared_memory_port_of_a_killed_process_does_not_hang_the_next_run(tmp_path):
    """Seen in CI: a process SIGKILLed while FastDDS was creating its shared-memory port left
    /dev/shm/fastrtps_port7013 empty; every later run's participant that reached port 7013 waited on
    it forever (boost open_or_create spins until the creator finishes) and the clock reported
    "hosts not up". The launcher removes the leftovers no live process holds before it starts a run
    (bringup/engine/ros/shm_cleanup.py). Here empty port files stand where a run's participants look first."""
    shm = Path("/dev/shm")
    planted = []
    for n in range(7000, 7040):
        f = shm / f"fastrtps_port{n}"
        if not f.exists():
            f.touch()
            planted.append(f)
    try:
        assert planted
        spec = RunSpec(factory="tests.ros.toy_participants:make", roles=toy.roles(3, pingpong=False),
                       horizon_ns=60 * S, max_step_ns=10 * S, bag_dir=str(tmp_path / "bag"), ack_timeout_s=10.0,
                       startup_timeout_s=30.0, extra={"n_counters": 3})
        res = launch(spec, tmp_path / "run")
        logs = {p.name: p.read_text(errors="replace")[-500:] for p in (tmp_path / "run" / "logs").glob("*.log")}
        assert res.ok, (res.message, logs)
        assert res.last.t_ns == spec.horizon_ns
        assert all(not f.exists() or f.stat().st_size > 0 for f in planted)  # gone, or a real port now
    finally:
        for f in planted:
            if f.exists() and f.stat().st_size == 0:
                f.unlink()
