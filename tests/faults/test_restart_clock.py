"""Clock restart (issue 7): the journal the restartable clock records into, and a toy run whose clock
is killed with SIGKILL.

Oracles:
* journal atomicity - a child process records messages and commits a checkpoint, records more and
  is killed before the next commit: the journal holds exactly the committed step, and its export
  reads back (BagReader, i.e. rosbags, and the independent ``mcap`` reader) message for message;
* toy run over DDS (tests/ros/toy_participants.py): the clock is killed mid-run, the launcher
  restarts it, the run completes and the bag's envelopes equal those of the in-process local
  engine (bringup/engine/local.py) for the same participants; every step is on /clock once and
  every host acked each step once (no duplicate execution);
* toy run whose clock is killed once more than ``max_restarts`` allows: the run fails, its message
  says where the partial bag is, and that bag (exported by the launcher from the clock's journal)
  opens with both readers and holds exactly what the local engine's run emits through the last
  step on its /clock, each step once.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
S = 10**9


@pytest.mark.faults
def test_journal_keeps_the_last_commit_under_sigkill_and_exports_a_bag(tmp_path):
    db = tmp_path / "clock.sqlite"
    code = f"""
import os, signal, sys
sys.path.insert(0, {str(REPO)!r})
from bringup.recording.bag import string_cdr
from bringup.recording.journal import BagJournal
j = BagJournal({str(db)!r})
j.k = 0
j.write_clock(5)
for i in range(3):
    j.write_keyed("/a", "std_msgs/msg/String", string_cdr("x"), 10 + i, "s", i)
j.commit(1, b"state-1")
j.k = 1
j.write_clock(20)
j.write_keyed("/a", "std_msgs/msg/String", string_cdr("y"), 21, "s", 3)
os.kill(os.getpid(), signal.SIGKILL)
"""
    r = subprocess.run([sys.executable, "-c", code], check=False, capture_output=True, timeout=60)
    assert r.returncode == -signal.SIGKILL, r.stderr
    from bringup.recording.bag import BagReader, string_cdr
    from bringup.recording.journal import BagJournal

    j = BagJournal(db)
    assert j.load() == (1, b"state-1")
    rows = list(j.keyed_rows(min_k=0))
    assert [(k, t, s, q) for k, t, s, q, _ in rows] == [(0, "/a", "s", 0), (0, "/a", "s", 1), (0, "/a", "s", 2)]
    assert rows[0][4] == string_cdr("x")
    assert all(cdr is None for *_, cdr in j.keyed_rows(min_k=1))
    assert j.counts == {"/clock": 1, "/a": 3}
    (tmp_path / "bag").mkdir()  # a cut-short earlier export is replaced
    assert j.export(tmp_path / "bag", custom={"engine": "ros"}) == 4
    j.close()
    with BagReader(tmp_path / "bag") as bag:
        got = [(m.topic, m.log_time_ns) for m in bag.messages()]
    assert got == [("/clock", 5), ("/a", 10), ("/a", 11), ("/a", 12)]
    from mcap.reader import make_reader

    with open(next((tmp_path / "bag").glob("*.mcap")), "rb") as fh:
        assert sorted(m.log_time for _s, _c, m in make_reader(fh).iter_messages()) == [5, 10, 11, 12]


def _run_with_clock_kill(tmp_path, kill_steps: list[int], max_restarts: int | None = None):
    from bringup.engine.ros.launcher import launch
    from bringup.engine.ros.run_spec import RunSpec
    from tests.ros import toy_participants as toy

    spec = RunSpec(factory="tests.ros.toy_participants:make", roles=toy.roles(3), horizon_ns=600 * S,
                   max_step_ns=10 * S, real_time_factor=40.0, bag_dir=str(tmp_path / "bag"), ack_timeout_s=5.0,
                   restart_wait_s=60.0,
                   max_restarts=len(kill_steps) if max_restarts is None else max_restarts,
                   state_dir=str(tmp_path / "state"),
                   progress_period_s=0.1, extra={"n_counters": 3})
    todo, killed = list(kill_steps), []

    def progress(p) -> None:
        if todo and p.steps >= todo[0]:
            pid = int((tmp_path / "run" / "logs" / "clock.pid").read_text())
            if killed and killed[-1][0] == pid:
                return  # the restarted clock has not written its pid yet
            os.kill(pid, signal.SIGKILL)
            killed.append((pid, p.steps))
            todo.pop(0)

    res = launch(spec, tmp_path / "run", progress=progress)
    return spec, res, killed


@pytest.mark.faults
@pytest.mark.ros
@pytest.mark.timeout(300)
# The at-start variant failed once in four full-suite runs (never alone, nor under 3 busy CPU loops;
# the assertion that failed was not captured): it is `slow` until that is understood. A likely cause
# has since been found and fixed: a process killed while FastDDS created its shared-memory port left
# an empty port file that hung later participants (bringup/engine/ros/shm_cleanup.py); after the fix it passed 6
# times in a row while the ros and system tests ran beside it. The clock kill mid-run of a real
# scenario (test_restart_ros.py[clock]) and the double kill stay in the default suite.
@pytest.mark.parametrize("kill_steps", [pytest.param([1], marks=pytest.mark.slow), [8, 20]],
                         ids=["at-start", "twice"])
def test_toy_run_survives_clock_kill9(tmp_path, kill_steps):
    from bringup.engine.local import run_local
    from bringup.recording.bag import BagReader, string_from_cdr
    from bringup.engine.lockstep import decode_ack
    from tests.ros import toy_participants as toy

    spec, res, killed = _run_with_clock_kill(tmp_path, kill_steps)
    logs = {p.name: p.read_text(errors="replace")[-1500:] for p in (tmp_path / "run" / "logs").glob("*.log")}
    assert len(killed) == len(kill_steps), (killed, logs)
    assert res.ok, (res.message, logs)
    assert res.restarts == {"clock": len(kill_steps)}, logs
    assert "restarted from its checkpoint" in logs["clock.log"]
    ref = run_local(toy.all_participants(spec), horizon_ns=spec.horizon_ns, max_step_ns=spec.max_step_ns)

    def key(e):
        return (e.t_ns, e.source, e.seq, e.topic, e.data)

    with BagReader(tmp_path / "bag") as bag:
        topics = {t.topic: t.count for t in bag.topics()}
        got = list(bag.envelopes([t for t in topics if t.startswith("/toy/")]))
        acks = [decode_ack(string_from_cdr(m.cdr))
                for m in bag.messages(["/sim/ack"])]
    assert len(ref.envelopes) > 100
    assert sorted(map(key, got)) == sorted(map(key, ref.envelopes))  # nothing lost, nothing twice
    assert topics["/clock"] == ref.steps == res.last.steps  # every step published (recorded) once
    pairs = [(a.participant, a.k) for a in acks if not a.hello]
    assert len(pairs) == len(set(pairs)) == len(spec.roles) * (ref.steps + 1)  # one ack per host per step
    assert res.last.t_ns == spec.horizon_ns


@pytest.mark.faults
@pytest.mark.ros
@pytest.mark.timeout(300)
def test_clock_killed_beyond_its_restarts_leaves_a_partial_bag(tmp_path):
    from bringup.engine.local import LocalEngine
    from bringup.recording.bag import BagReader
    from tests.ros import toy_participants as toy

    spec, res, killed = _run_with_clock_kill(tmp_path, [8, 20], max_restarts=1)
    logs = {p.name: p.read_text(errors="replace")[-1500:] for p in (tmp_path / "run" / "logs").glob("*.log")}
    assert len(killed) == 2, (killed, logs)
    assert not res.ok and res.restarts == {"clock": 1}, (res.message, logs)
    assert "clock" in res.failed_roles
    bag_dir = tmp_path / "bag"
    assert "\n" not in res.message
    assert "killed by SIGKILL" in res.message and "partial bag (steps before t = " in res.message, res.message
    assert res.message.endswith(f"in {bag_dir}"), res.message
    # the reference: what the local engine emits, tagged with the step (sim time) that emitted it
    cur, steps = [None], []
    tagged: list[tuple[int | None, tuple]] = []

    def key(e):
        return (e.t_ns, e.source, e.seq, e.topic, e.data)

    eng = LocalEngine(toy.all_participants(spec), horizon_ns=spec.horizon_ns, max_step_ns=spec.max_step_ns,
                      sink=lambda e: tagged.append((cur[0], key(e))),
                      on_step=lambda t: (cur.__setitem__(0, t), steps.append(t)))
    eng.run()
    with BagReader(bag_dir) as bag:
        topics = {t.topic: t.count for t in bag.topics()}
        clocks = [m.log_time_ns for m in bag.messages(["/clock"])]
        got = list(bag.envelopes([t for t in topics if t.startswith("/toy/")]))
    from mcap.reader import make_reader

    with open(next(bag_dir.glob("*.mcap")), "rb") as fh:
        n_mcap = sum(1 for _ in make_reader(fh).iter_messages(topics=[t for t in topics if t.startswith("/toy/")]))
    assert n_mcap == len(got)
    assert len(clocks) == len(set(clocks)) >= 8  # each step once; at least the steps before the first kill
    last = max(clocks)
    assert last < spec.horizon_ns
    nxt = steps[steps.index(last) + 1]  # the step the clock died in (its checkpoint)
    assert f"steps before t = {nxt / 1e9:g} s" in res.message, res.message
    want = [k for t, k in tagged if t is None or t <= last]  # start phase (untagged) and steps through `last`
    assert len(want) > 10 and len(want) < len(tagged)
    assert sorted(map(key, got)) == sorted(want)  # nothing lost, nothing twice, nothing later
