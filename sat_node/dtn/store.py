"""Persistent bundle store: SQLite in WAL mode (https://sqlite.org/wal.html).

Each accepted bundle is one row (id, encoded bytes, priority, destination, expiry); it is deleted when
the bundle is dropped or when its transmission has ended (not when it starts: a process killed
mid-transmission keeps it). A process killed and restarted opens the same file and gets every bundle
back (:meth:`BundleStore.load_all`), so the agent re-routes them. ``path=None`` keeps the store in
memory (the DTN-alone runs of ``constellation dtn``, where persistence buys nothing).

Durability guarantee (what a kill can cost): the unit is the lockstep step.

* The satellite opens a batch per step (:meth:`begin` ... :meth:`commit`, sat_node/satellite.py). Inside
  it puts, deletes and meta writes are collected in memory, the last write of a key winning (a bundle
  put and deleted in the same step never reaches the file), and :meth:`commit` writes them in one
  SQLite transaction. A process killed during a step therefore finds the file as it was at the end
  of the previous step - exactly what an open, uncommitted SQLite transaction would leave - and a
  process killed after :meth:`commit` returned finds every bundle the step accepted: a restarted
  process always finds a step boundary, never half a step.
* When a caller already has a transaction open on the connection (the ROS host's per-step checkpoint,
  bringup/engine/checkpoint.py, which commits the checkpoint row with the step's bundle rows), writes go
  straight into it and the caller's COMMIT makes them durable together with the checkpoint.
* A local run (one process, no resume) opens one batch for many steps (bringup/engine/store_batches.py):
  the satellite's ``begin`` then joins it, and the file advances every 50 steps instead of every step.
* Outside a batch every write is its own autocommitted transaction.

``synchronous=NORMAL`` in WAL mode: a committed transaction survives a process kill - its frames are
in the WAL file, which the OS has even when they were not fsynced - and that is the failure we model.
A power cut may roll back the transactions since the last checkpoint (the file stays consistent).
Checkpoints run every ``_WAL_CHECKPOINT_PAGES`` WAL pages. The connection is used by one thread at a
time, not always the one that opened it (``check_same_thread=False``): the local run closes its
satellites' stores side by side at the end (bringup/cli/run.py). The bundles table is ``WITHOUT ROWID``
(one B-tree keyed by the bundle id instead of a rowid table plus its index: fewer pages per commit);
a file made by an earlier version (a rowid table) is read and written the same way. Reads
(:meth:`load_all`, ``len``, :meth:`get_meta`) see the batch's pending writes (they are written into
the open transaction first).

How we know it is right: tests/unit/test_store.py writes bundles in one process, kills it with
SIGKILL, reopens the file in another and finds every bundle it had committed, including one killed
while on the air; a process killed inside a batch leaves exactly the previous commit's rows; a batch's
net effect equals the same writes made one by one.
"""

from __future__ import annotations

import contextlib
import sqlite3
from collections.abc import Iterator
from pathlib import Path
from typing import NamedTuple

__all__ = ["BundleStore", "StoredBundle"]


class StoredBundle(NamedTuple):
    bundle_id: str
    data: bytes
    priority: int
    dest: str
    expiry_ns: int
    received_ns: int


_PUT = "INSERT OR REPLACE INTO bundles VALUES (?, ?, ?, ?, ?, ?)"
_DEL = "DELETE FROM bundles WHERE id = ?"
_META = "INSERT OR REPLACE INTO meta VALUES (?, ?)"
# WAL pages between automatic checkpoints (SQLite's default is 1000). Each checkpoint fsyncs the WAL
# and the database; a satellite commits a few pages per step, so the default checkpointed every ~300
# steps. 4000 pages bounds the WAL at ~16 MB per satellite and cut the paper run's store time in half
# (replay of its 245k store calls: 2.2-3.2 s -> 1.1-1.9 s wall).
_WAL_CHECKPOINT_PAGES = 4000


class BundleStore:
    def __init__(self, path: str | Path | None = None):
        self.path = None if path is None else Path(path)
        if self.path is not None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
        self._db = sqlite3.connect(":memory:" if self.path is None else str(self.path), isolation_level=None,
                                   check_same_thread=False)
        try:
            self._setup()
        except BaseException:  # (a full disk: the file is not left open by a half-made store)
            self._db.close()
            raise
        self._batch = False
        self._rows: dict[str, tuple | None] = {}  # batch: bundle id -> row to put, None = delete
        self._meta: dict[str, int] = {}  # batch: meta key -> value

    def _setup(self) -> None:
        if self.path is not None:
            mode = self._db.execute("PRAGMA journal_mode=WAL").fetchone()[0]
            if mode.lower() != "wal":
                raise RuntimeError(f"{self.path}: SQLite refused WAL mode (got {mode})")
            self._db.execute("PRAGMA synchronous=NORMAL")
            self._db.execute(f"PRAGMA wal_autocheckpoint={_WAL_CHECKPOINT_PAGES}")
        self._db.execute("CREATE TABLE IF NOT EXISTS bundles (id TEXT PRIMARY KEY, data BLOB NOT NULL, "
                         "priority INTEGER NOT NULL, dest TEXT NOT NULL, expiry_ns INTEGER NOT NULL, "
                         "received_ns INTEGER NOT NULL) WITHOUT ROWID")
        self._db.execute("CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value INTEGER NOT NULL)")

    @property
    def in_transaction(self) -> bool:
        return self._db.in_transaction or bool(self._rows or self._meta)

    def begin(self) -> bool:
        """Open a batch unless a transaction or batch is open already (a caller's, e.g. the ROS host's
        per-step checkpoint); returns True when this call opened it (then the caller commits it).
        Writes inside it reach the file together at :meth:`commit` (see the module docstring)."""
        if self._db.in_transaction or self._batch:
            return False
        self._batch = True
        return True

    def commit(self) -> None:
        """Write the batch in one transaction (nothing when it is empty) and close it."""
        try:
            self._flush()
            if self._db.in_transaction:
                self._db.execute("COMMIT")
        finally:
            self._batch = False

    @contextlib.contextmanager
    def step_batch(self) -> Iterator[None]:
        """One batch around a lockstep step: :meth:`begin` on entry, and :meth:`commit` on the way out
        when this call opened it (a caller's open transaction or batch is left to its owner)."""
        own = self.begin()
        try:
            yield
        finally:
            if own:
                self.commit()

    def rollback(self) -> None:
        """Drop the batch's pending writes (and roll back the open transaction) and close the batch:
        the file stays at the last commit."""
        self._rows = {}
        self._meta = {}
        try:
            if self._db.in_transaction:
                self._db.execute("ROLLBACK")
        finally:
            self._batch = False

    def _flush(self) -> None:
        """Write the batch's pending rows into the (then open) transaction."""
        rows, meta = self._rows, self._meta
        if not rows and not meta:
            return
        db = self._db
        if not db.in_transaction:
            db.execute("BEGIN")
        dels = [(k,) for k, r in rows.items() if r is None]
        if dels:
            db.executemany(_DEL, dels)
        puts = [r for r in rows.values() if r is not None]
        if puts:
            db.executemany(_PUT, puts)
        if meta:
            db.executemany(_META, meta.items())
        self._rows = {}
        self._meta = {}

    def put(self, b: StoredBundle) -> None:
        row = (b.bundle_id, b.data, b.priority, b.dest, b.expiry_ns, b.received_ns)
        if self._batch:
            self._rows.pop(b.bundle_id, None)  # keep the write order of distinct ids
            self._rows[b.bundle_id] = row
        else:
            self._db.execute(_PUT, row)

    def delete(self, bundle_id: str) -> None:
        if self._batch:
            self._rows.pop(bundle_id, None)
            self._rows[bundle_id] = None
        else:
            self._db.execute(_DEL, (bundle_id,))

    def load_all(self) -> list[StoredBundle]:
        self._flush()
        rows = self._db.execute("SELECT id, data, priority, dest, expiry_ns, received_ns FROM bundles "
                                "ORDER BY received_ns, id").fetchall()
        return [StoredBundle(*r) for r in rows]

    def __len__(self) -> int:
        self._flush()
        return self._db.execute("SELECT COUNT(*) FROM bundles").fetchone()[0]

    def get_meta(self, key: str, default: int = 0) -> int:
        if key in self._meta:
            return self._meta[key]
        row = self._db.execute("SELECT value FROM meta WHERE key = ?", (key,)).fetchone()
        return default if row is None else int(row[0])

    def set_meta(self, key: str, value: int) -> None:
        if self._batch:
            self._meta[key] = int(value)
        else:
            self._db.execute(_META, (key, int(value)))

    def close(self) -> None:
        self._db.close()
