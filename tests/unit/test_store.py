"""The SQLite WAL bundle store survives a SIGKILL; an agent restarted on it resumes its bundles."""

import os
import signal
import subprocess
import sys
import textwrap

from orbit_clock.contact_plan import Contact, ContactPlan
from sat_node.dtn.agent import BundleAgent
from sat_node.dtn.store import BundleStore

PLAN = ContactPlan([Contact(100.0, 200.0, "sat_11", "sat_12", 1000.0, 0.0)])


def test_killed_process_resumes_with_its_bundles(tmp_path):
    db = tmp_path / "sat_11.sqlite"
    script = textwrap.dedent(f"""
        import os, sys
        from orbit_clock.contact_plan import Contact, ContactPlan
        from sat_node.dtn.agent import BundleAgent
        from sat_node.dtn.store import BundleStore
        plan = ContactPlan([Contact(100.0, 200.0, "sat_11", "sat_12", 1000.0, 0.0)])
        a = BundleAgent("sat_11", plan, store=BundleStore({str(db)!r}))
        for i in range(5):
            a.originate(b"obs %d" % i, "sat_12", 1 + i, now_ns=i * 10**9)
        print("ready", flush=True)
        sys.stdin.readline()
    """)
    p = subprocess.Popen([sys.executable, "-c", script], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
                         cwd=os.getcwd())
    assert p.stdout.readline().strip() == "ready"
    os.kill(p.pid, signal.SIGKILL)
    p.wait(timeout=30)
    store = BundleStore(db)
    assert store._db.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    assert len(store) == 5
    a = BundleAgent("sat_11", PLAN, store=store)
    assert a.held_count() == 5
    txs = a.transmissions_until(150 * 10**9)
    assert len(txs) == 5 and [t.start_ns for t in txs] == [100 * 10**9 + 2 * k * 10**9 for k in range(5)]
    # sequence numbers continue after the restart: no id reused
    new = a.originate(b"after", "sat_12", 1, now_ns=160 * 10**9)
    assert new not in {t.bundle_id for t in txs}


def test_store_put_delete(tmp_path):
    from sat_node.dtn.store import StoredBundle

    s = BundleStore(tmp_path / "x.sqlite")
    s.put(StoredBundle("a", b"\x01", 1, "sat_12", 5, 1))
    s.put(StoredBundle("b", b"\x02", 2, "sat_12", 5, 0))
    assert [x.bundle_id for x in s.load_all()] == ["b", "a"]
    s.delete("b")
    assert len(s) == 1


def test_killed_mid_transmission_keeps_the_bundle(tmp_path):
    """A bundle leaves the store only when its transmission has ended: SIGKILL while it is on the
    air, and the restarted agent still has it (and sends it again)."""
    db = tmp_path / "sat_11.sqlite"
    script = textwrap.dedent(f"""
        import sys
        from orbit_clock.contact_plan import Contact, ContactPlan
        from sat_node.dtn.agent import BundleAgent
        from sat_node.dtn.store import BundleStore
        plan = ContactPlan([Contact(100.0, 200.0, "sat_11", "sat_12", 1000.0, 0.0)])
        a = BundleAgent("sat_11", plan, store=BundleStore({str(db)!r}))
        a.originate(b"on the air", "sat_12", 1, now_ns=0)
        a.originate(b"sent", "sat_12", 1, now_ns=0)
        txs = a.transmissions_until(103 * 10**9)  # first 100-102 s (ended), second 102-104 s (on the air)
        assert [t.start_ns for t in txs] == [100 * 10**9, 102 * 10**9], txs
        a.receive(b"", "sat_12", 103 * 10**9)  # any later call settles what has ended
        print("ready", txs[1].bundle_id, flush=True)
        sys.stdin.readline()
    """)
    p = subprocess.Popen([sys.executable, "-c", script], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
                         cwd=os.getcwd())
    line = p.stdout.readline().split()
    assert line and line[0] == "ready", line
    os.kill(p.pid, signal.SIGKILL)
    p.wait(timeout=30)
    store = BundleStore(db)
    assert [b.bundle_id for b in store.load_all()] == [line[1]]  # the one on the air, only
    a = BundleAgent("sat_11", PLAN, store=store)
    assert a.held_count() == 1
    txs = a.transmissions_until(150 * 10**9)
    assert [t.bundle_id for t in txs] == [line[1]] and txs[0].start_ns == 100 * 10**9
    assert len(store) == 1  # still on the air
    a.transmissions_until(txs[0].end_ns)
    assert len(store) == 0
