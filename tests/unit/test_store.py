"""The SQLite WAL bundle store survives a SIGKILL; an agent restarted on it resumes its bundles."""

import os
import signal
import subprocess
import sys
import textwrap

from orbit_clock.contact_plan import Contact, ContactPlan
from sat_node.dtn.agent import AgentConfig, BundleAgent
from sat_node.dtn.store import BundleStore

PLAN = ContactPlan([Contact(100.0, 200.0, "sat_11", "sat_12", 1000.0, 0.0)])


def test_killed_process_resumes_with_its_bundles(tmp_path):
    db = tmp_path / "sat_11.sqlite"
    script = textwrap.dedent(f"""
        import os, sys
        from orbit_clock.contact_plan import Contact, ContactPlan
        from sat_node.dtn.agent import AgentConfig, BundleAgent
        from sat_node.dtn.store import BundleStore
        plan = ContactPlan([Contact(100.0, 200.0, "sat_11", "sat_12", 1000.0, 0.0)])
        a = BundleAgent("sat_11", plan, AgentConfig(key=bytes(16)), store=BundleStore({str(db)!r}))
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
    a = BundleAgent("sat_11", PLAN, AgentConfig(key=bytes(16)), store=store)
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
        from sat_node.dtn.agent import AgentConfig, BundleAgent
        from sat_node.dtn.store import BundleStore
        plan = ContactPlan([Contact(100.0, 200.0, "sat_11", "sat_12", 1000.0, 0.0)])
        a = BundleAgent("sat_11", plan, AgentConfig(key=bytes(16)), store=BundleStore({str(db)!r}))
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
    a = BundleAgent("sat_11", PLAN, AgentConfig(key=bytes(16)), store=store)
    assert a.held_count() == 1
    txs = a.transmissions_until(150 * 10**9)
    assert [t.bundle_id for t in txs] == [line[1]] and txs[0].start_ns == 100 * 10**9
    assert len(store) == 1  # still on the air
    a.transmissions_until(txs[0].end_ns)
    assert len(store) == 0


def _rows(s):
    return [(b.bundle_id, b.data, b.priority, b.dest, b.expiry_ns, b.received_ns) for b in s.load_all()]


def test_batch_equals_writes_one_by_one(tmp_path):
    """Random puts/deletes/meta writes in per-step batches leave the same rows and meta as the same
    writes made one at a time (autocommit), after every step."""
    import random

    from sat_node.dtn.store import StoredBundle

    rng = random.Random(7)
    a, b = BundleStore(tmp_path / "a.sqlite"), BundleStore(tmp_path / "b.sqlite")
    for step in range(200):
        assert a.begin() is True
        assert a.begin() is False  # already open
        for _ in range(rng.randrange(0, 8)):
            op, bid = rng.random(), f"ipn:11.{rng.randrange(12)}"
            if op < 0.5:
                sb = StoredBundle(bid, rng.randbytes(rng.randrange(1, 300)), rng.randrange(1, 16), "sat_12",
                                  rng.randrange(10**12), step)
                a.put(sb)
                b.put(sb)
            elif op < 0.85:
                a.delete(bid)
                b.delete(bid)
            else:
                a.set_meta("seq", step)
                b.set_meta("seq", step)
                assert a.get_meta("seq") == step  # the batch's own write is seen before the commit
        a.commit()
        assert not a.in_transaction
        assert _rows(a) == _rows(b) and a.get_meta("seq", -1) == b.get_meta("seq", -1)
    assert len(a) > 0


def test_put_then_delete_in_one_batch_writes_nothing(tmp_path):
    from sat_node.dtn.store import StoredBundle

    s = BundleStore(tmp_path / "x.sqlite")
    s.put(StoredBundle("kept", b"\x01", 1, "sat_12", 5, 0))
    wal = tmp_path / "x.sqlite-wal"
    size = wal.stat().st_size
    assert s.begin()
    s.put(StoredBundle("gone", b"\x02" * 200, 1, "sat_12", 5, 1))
    s.delete("gone")
    s.commit()
    assert wal.stat().st_size == size  # no WAL frame appended
    assert [x.bundle_id for x in s.load_all()] == ["kept"]


def test_killed_inside_a_batch_keeps_the_previous_commit(tmp_path):
    """SIGKILL while a batch is open (its writes pending in memory, or already written into the open
    transaction by a read): the file holds exactly what the last commit left."""
    db = tmp_path / "s.sqlite"
    script = textwrap.dedent(f"""
        import sys
        from sat_node.dtn.store import BundleStore, StoredBundle
        s = BundleStore({str(db)!r})
        s.begin()
        for i in range(3):
            s.put(StoredBundle("c%d" % i, b"x" * 100, 1, "sat_12", 10, i))
        s.set_meta("seq", 3)
        s.commit()
        s.begin()
        s.delete("c0")
        s.put(StoredBundle("p0", b"y", 1, "sat_12", 10, 5))
        s.set_meta("seq", 4)
        if sys.argv[1] == "flushed":
            assert len(s) == 3  # the pending writes go into the open transaction
        print("ready", flush=True)
        sys.stdin.readline()
    """)
    for how in ("pending", "flushed"):
        if db.exists():
            for f in tmp_path.glob("s.sqlite*"):
                f.unlink()
        p = subprocess.Popen([sys.executable, "-c", script, how], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                             text=True, cwd=os.getcwd())
        assert p.stdout.readline().strip() == "ready", how
        os.kill(p.pid, signal.SIGKILL)
        p.wait(timeout=30)
        s = BundleStore(db)
        assert [b.bundle_id for b in s.load_all()] == ["c0", "c1", "c2"], how
        assert s.get_meta("seq") == 3, how
        s.close()


def test_opens_a_store_made_with_a_rowid_table(tmp_path):
    """A file written before the table became WITHOUT ROWID is read and written the same way."""
    import sqlite3

    from sat_node.dtn.store import StoredBundle

    db = tmp_path / "old.sqlite"
    c = sqlite3.connect(str(db))
    c.execute("CREATE TABLE bundles (id TEXT PRIMARY KEY, data BLOB NOT NULL, priority INTEGER NOT NULL, "
              "dest TEXT NOT NULL, expiry_ns INTEGER NOT NULL, received_ns INTEGER NOT NULL)")
    c.execute("INSERT INTO bundles VALUES ('a', x'01', 1, 'sat_12', 5, 1)")
    c.commit()
    c.close()
    s = BundleStore(db)
    assert s.begin()
    s.put(StoredBundle("b", b"\x02", 2, "sat_12", 5, 0))
    s.delete("a")
    s.commit()
    assert _rows(s) == [("b", b"\x02", 2, "sat_12", 5, 0)]
