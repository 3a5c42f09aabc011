"""Per-step checkpoints of a ROS-engine host, so a process killed with SIGKILL resumes.

Pure module (no rclpy). After every wire step a host (bringup/engine/ros/host.py) writes one row: the wire
step ``k`` it finished, its own lockstep state (seq counters, inbox counts, the ack it sent) and
each participant's state (:func:`snapshot_participant`). The row goes into SQLite in WAL mode
(https://sqlite.org/wal.html) inside the *same transaction* as everything the step wrote to the
participant's own persistent store (a satellite's bundle store, sat_node/dtn/store.py): the host
runs ``BEGIN`` before the step and ``COMMIT`` after the row, so a kill at any instant leaves the
file at the end of one step - bundles held and the scheduler's knowledge always agree. Envelopes
published before the kill are re-published identically by the re-run (same source and seq) and
dropped as duplicates by receivers (bringup/engine/lockstep.py TopicInbox).

Participant state: ``p.snapshot() -> bytes`` / ``p.restore(bytes)`` when the participant has them
(the satellite does: sat_node/persist.py - known observations, plan, last executed time, event
cursor, agent routing state), else a pickle of its attributes minus the shared read-only inputs
(``world``, ``sc``), which every process rebuilds from the world pickle. A participant with a
persistent store of its own gives its SQLite connection with ``p.persistent_connection()``; the
checkpoint row then goes into that file, in the step's transaction. The engine knows no participant
class: these three methods are the whole interface.

How we know it is right: tests/faults/test_restart_unit.py kills a writer between BEGIN and COMMIT
(SIGKILL in a child process) and finds the previous step's row and store rows, never a mix; and
the fault system tests (tests/faults/test_restart_ros.py) kill -9 a satellite, the router mid-run
and compare the finished run with an uninterrupted one.
"""

from __future__ import annotations

import pickle
import sqlite3
from pathlib import Path

__all__ = ["CheckpointDB", "persistent_connection", "restore_participant", "snapshot_participant"]

_SHARED = ("world", "sc")


def persistent_connection(p) -> sqlite3.Connection | None:
    """The participant's own SQLite connection, if its state has one (the checkpoint joins it)."""
    fn = getattr(p, "persistent_connection", None)
    return fn() if callable(fn) else None


def snapshot_participant(p) -> bytes:
    fn = getattr(p, "snapshot", None)
    if callable(fn):
        return fn()
    state = {k: v for k, v in vars(p).items() if k not in _SHARED}
    return pickle.dumps(state, protocol=pickle.HIGHEST_PROTOCOL)


def restore_participant(p, blob: bytes) -> None:
    fn = getattr(p, "restore", None)
    if callable(fn):
        fn(blob)
        return
    vars(p).update(pickle.loads(blob))


class CheckpointDB:
    """One checkpoint row in a SQLite file, or in a participant's open connection (shared transaction)."""

    def __init__(self, path: str | Path | None = None, *, conn: sqlite3.Connection | None = None):
        if (path is None) == (conn is None):
            raise ValueError("CheckpointDB: give exactly one of path and conn")
        if conn is None:
            Path(path).parent.mkdir(parents=True, exist_ok=True)
            conn = sqlite3.connect(str(path), isolation_level=None)
            mode = conn.execute("PRAGMA journal_mode=WAL").fetchone()[0]
            if mode.lower() != "wal":
                raise RuntimeError(f"{path}: SQLite refused WAL mode (got {mode})")
            conn.execute("PRAGMA synchronous=NORMAL")
            self._own = True
        else:
            if conn.isolation_level is not None:
                raise ValueError("CheckpointDB: the shared connection must be in autocommit mode")
            self._own = False
        self.db = conn
        self.db.execute("CREATE TABLE IF NOT EXISTS lockstep_checkpoint (id INTEGER PRIMARY KEY CHECK (id = 0), "
                        "k INTEGER NOT NULL, host BLOB NOT NULL, parts BLOB NOT NULL)")

    def begin(self) -> None:
        if not self.db.in_transaction:
            self.db.execute("BEGIN IMMEDIATE")

    def commit(self, k: int, host_state: dict, parts: list[bytes]) -> None:
        """Write the row for wire step ``k`` and commit everything since :meth:`begin`."""
        self.begin()
        self.db.execute("INSERT OR REPLACE INTO lockstep_checkpoint VALUES (0, ?, ?, ?)",
                        (int(k), pickle.dumps(host_state, protocol=pickle.HIGHEST_PROTOCOL),
                         pickle.dumps(parts, protocol=pickle.HIGHEST_PROTOCOL)))
        self.db.execute("COMMIT")

    def load(self) -> tuple[int, dict, list[bytes]] | None:
        row = self.db.execute("SELECT k, host, parts FROM lockstep_checkpoint WHERE id = 0").fetchone()
        if row is None:
            return None
        return int(row[0]), pickle.loads(row[1]), pickle.loads(row[2])

    def close(self) -> None:
        if self._own:
            self.db.close()
