"""Checkpoint and restore without ROS (issue 7 part B): the oracles behind the kill -9 system tests.

* atomicity - a child process writes store rows and a checkpoint inside one transaction and is
  killed with SIGKILL before COMMIT: the file holds the previous step's row and rows, never a mix;
* exact resumption - in the local engine, every satellite is thrown away at a random step and
  rebuilt from its snapshot plus its SQLite bundle store (sat_node/persist.py); the rest of the run
  must emit exactly the envelopes of the uninterrupted run (observations, bundles, events);
* a toy participant without snapshot methods round-trips through the generic pickle.
"""

from __future__ import annotations

import json
import random
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from tests.keys import TEST_BPSEC_KEY

pytestmark = pytest.mark.faults

REPO = Path(__file__).resolve().parents[2]
SATS, HOURS = 12, 1.0


def test_checkpoint_is_atomic_under_sigkill(tmp_path):
    db = tmp_path / "sat.sqlite"
    code = f"""
import os, signal, sys
sys.path.insert(0, {str(REPO)!r})
from sat_node.dtn.store import BundleStore, StoredBundle
from bringup.engine.checkpoint import CheckpointDB
st = BundleStore({str(db)!r})
ck = CheckpointDB(conn=st._db)
ck.begin(); st.put(StoredBundle("a", b"x", 1, "sat_12", 10, 0)); ck.commit(1, {{"step": 1}}, [b"one"])
ck.begin(); st.put(StoredBundle("b", b"y", 1, "sat_12", 10, 0)); st.delete("a")
os.kill(os.getpid(), signal.SIGKILL)
"""
    r = subprocess.run([sys.executable, "-c", code], check=False, capture_output=True, timeout=60)
    assert r.returncode == -signal.SIGKILL, r.stderr
    from bringup.engine.checkpoint import CheckpointDB
    from sat_node.dtn.store import BundleStore

    st = BundleStore(db)
    assert [b.bundle_id for b in st.load_all()] == ["a"]
    k, host, parts = CheckpointDB(conn=st._db).load()
    assert (k, host, parts) == (1, {"step": 1}, [b"one"])


class _Toy:
    def __init__(self):
        self.name, self.n, self.world = "toy", 0, object()


def test_generic_snapshot_skips_shared_inputs():
    from bringup.engine.checkpoint import restore_participant, snapshot_participant

    a = _Toy()
    a.n = 7
    b = _Toy()
    w = b.world
    restore_participant(b, snapshot_participant(a))
    assert b.n == 7 and b.world is w


def _data(e):
    """Payload without the scheduler's measured CPU time (the only field that is not deterministic)."""
    if e.topic.endswith("/schedule"):
        d = json.loads(e.data)
        d.pop("solve_cpu_s", None)
        return d
    return e.data


class _Restarting:
    """Wraps a satellite; at ``t_kill`` drops it and rebuilds it from snapshot + store, like a restart."""

    def __init__(self, make, t_kill_ns: int):
        self.make, self.t_kill = make, t_kill_ns
        self.p = make()
        self.name = self.p.name
        self.restored = None

    def subscriptions(self):
        return self.p.subscriptions()

    def start(self, t0):
        return self.p.start(t0)

    def step(self, t, inbox):
        if self.restored is None and t >= self.t_kill:
            from sat_node import persist

            blob = persist.snapshot(self.p)
            self.p.agent.store.close()
            self.p = self.make()
            persist.restore(self.p, blob)
            self.restored = self.p.restore_report
        return self.p.step(t, inbox)

    def finish(self, t):
        return self.p.finish(t)


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    from bringup.scenario.config import load_scenario
    from bringup.scenario.world import World

    sc = load_scenario("paper").with_overrides(sats=SATS, hours=HOURS)
    return World.cached(sc, tmp_path_factory.mktemp("world"))


def test_satellites_rebuilt_from_snapshot_and_store_continue_exactly(world, tmp_path):
    from bringup.engine.local import run_local
    from bringup.scenario.participants import all_participants
    from sat_node.satellite import SatelliteLogic

    horizon, max_step = world.scenario.horizon_ns, int(world.scenario.scenario.lockstep_max_step_s * 1e9)
    ref = run_local(all_participants(world, "distributed", store_dir=tmp_path / "ref", bpsec_key=TEST_BPSEC_KEY),
                    horizon_ns=horizon, max_step_ns=max_step)
    rng = random.Random(7)
    parts = []
    store = tmp_path / "crash"
    store.mkdir()
    for p in all_participants(world, "distributed", store_dir=tmp_path / "unused", bpsec_key=TEST_BPSEC_KEY):
        if isinstance(p, SatelliteLogic):
            path = str(store / f"{p.name}.sqlite")
            t_kill = rng.randrange(horizon // 10, horizon)
            parts.append(_Restarting(lambda n=p.name, s=path: SatelliteLogic(world, n, "distributed", store_path=s,
                                                                                   bpsec_key=TEST_BPSEC_KEY),
                                     t_kill))
        else:
            parts.append(p)
    got = run_local(parts, horizon_ns=horizon, max_step_ns=max_step)
    assert all(p.restored is not None for p in parts if isinstance(p, _Restarting))
    assert all(p.restored["store_rows_added"] == p.restored["store_rows_removed"] == 0
               for p in parts if isinstance(p, _Restarting))
    key = lambda e: (e.t_ns, e.source, e.seq, e.topic)
    want = sorted(ref.envelopes, key=key)
    have = sorted(got.envelopes, key=key)
    assert sum(e.topic.endswith("/dtn/out") for e in want) > 10
    assert len(have) == len(want)
    diffs = [(a.topic, a.t_ns) for a, b in zip(have, want) if (a.topic, a.t_ns, a.source, a.seq, _data(a)) !=
             (b.topic, b.t_ns, b.source, b.seq, _data(b))]
    assert not diffs, diffs[:5]


def test_partially_served_multicast_bundle_survives_sigkill(tmp_path):
    """A multicast bundle for sat_12 (in view now) and sat_13 (contact from 100 s): the transmission to
    sat_12 has ended and settled, sat_13's recipient waits. A second bundle is on the air at the kill.
    After SIGKILL the restarted agent holds exactly sat_13's recipient of the first bundle (sent alone
    at 100 s) and every recipient of the second (sent again): no recipient is lost or served twice."""
    import os
    import textwrap

    from orbit_clock.contact_plan import Contact, ContactPlan
    from sat_node.dtn.agent import AgentConfig
    from sat_node.dtn.bpv7 import decode_bundle
    from sat_node.dtn.multicast import MulticastAgent
    from sat_node.dtn.routing_blocks import next_hops_of
    from sat_node.dtn.store import BundleStore

    db = tmp_path / "sat_11.sqlite"
    plan_src = ('ContactPlan([Contact(0.0, 100.0, "sat_11", "sat_12", 1000.0, 0.0), '
                'Contact(100.0, 200.0, "sat_11", "sat_13", 1000.0, 0.0)])')
    script = textwrap.dedent(f"""
        import sys
        from orbit_clock.contact_plan import Contact, ContactPlan
        from sat_node.dtn.agent import AgentConfig
        from sat_node.dtn.multicast import MulticastAgent
        from sat_node.dtn.store import BundleStore
        from tests.keys import TEST_BPSEC_KEY
        a = MulticastAgent("sat_11", {plan_src}, AgentConfig(key=TEST_BPSEC_KEY), store=BundleStore({str(db)!r}))
        first = a.originate_many(b"partly served", [("sat_12", 1), ("sat_13", 2)], 10 * 10**9)
        tx = a.transmissions_until(10 * 10**9)
        assert [t.next_hops for t in tx] == [("sat_12",)], tx
        a.receive(b"", "sat_12", 20 * 10**9)  # a later call: the ended transmission is settled
        second = a.originate_many(b"on the air", [("sat_12", 3)], 30 * 10**9)
        tx2 = a.transmissions_until(31 * 10**9)  # 30 s to 32 s+: on the air at the kill
        assert [t.start_ns for t in tx2] == [30 * 10**9], tx2
        print("ready", first, second, flush=True)
        sys.stdin.readline()
    """)
    p = subprocess.Popen([sys.executable, "-c", script], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
                         cwd=str(REPO), env=dict(os.environ, PYTHONPATH=str(REPO)))
    line = p.stdout.readline().split()
    assert line and line[0] == "ready", line
    first, second = line[1], line[2]
    os.kill(p.pid, signal.SIGKILL)
    p.wait(timeout=30)
    a = MulticastAgent("sat_11", ContactPlan([Contact(0.0, 100.0, "sat_11", "sat_12", 1000.0, 0.0),
                                              Contact(100.0, 200.0, "sat_11", "sat_13", 1000.0, 0.0)]),
                       AgentConfig(key=TEST_BPSEC_KEY), store=BundleStore(db))
    assert a.held_pairs() == {(first, "sat_13"), (second, "sat_12")}
    txs = a.transmissions_until(150 * 10**9)
    sent = {(t.bundle_id, t.next_hops): next_hops_of(decode_bundle(t.bundle_bytes)) for t in txs}
    assert sent == {(second, ("sat_12",)): {12: (12,)}, (first, ("sat_13",)): {13: (13,)}}
    assert next(t for t in txs if t.bundle_id == first).start_ns == 100 * 10**9
