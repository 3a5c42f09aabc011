"""The recorder journal of a restartable clock: messages into SQLite, one ordinary bag at the end.

Written with the :class:`bringup.recording.bag.BagWriter` write API (so the clock records into either
the same way) and exported into a BagWriter bag, on the same clock (``epoch_ns``). Oracle:
tests/faults/test_restart_clock.py (a child killed between writes finds the last commit, the export
reads back identical through BagReader) and tests/faults/test_restart_ros.py (the bag of a run
whose clock was killed equals the uninterrupted run's).
"""

from __future__ import annotations

import shutil
import sqlite3
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from rosbags.interfaces import Qos

from bringup.recording.bag import CLOCK_TYPE, STRING, TYPESTORE, BagWriter, clock_cdr, string_cdr
from msgs_json.envelope import Envelope
from msgs_json.wire import encode_envelope

__all__ = ["BagJournal"]


class BagJournal:
    """The recorder of a restartable clock: messages go into SQLite, the bag is exported at the end.

    rosbags' Writer cannot reopen a bag, and an MCAP file cut by SIGKILL has no summary and loses
    its unflushed chunk. So a clock that may be restarted records into ``path`` (SQLite, WAL mode,
    https://sqlite.org/wal.html) with the :class:`BagWriter` write API, inside one open transaction
    per lockstep step; :meth:`commit` writes the clock's checkpoint row and commits that step's
    messages with it, so a kill at any instant leaves the journal exactly at the end of one step.
    :meth:`load` gives the restarted clock its checkpoint back; :meth:`keyed_rows` the envelopes it
    recorded (dedupe keys, re-send buffer). :meth:`export` writes everything committed (plus the open
    transaction) in arrival order into a normal bag (:class:`BagWriter`), which every reader opens.

    ``k`` is the wire step the clock is in; each row carries it. Envelope rows written with
    :meth:`write_keyed` carry their (source, seq), so the recorder counts unique envelopes.

    Oracle: tests/faults/test_restart_unit.py (a child killed between writes finds the last commit,
    export reads back identical through :class:`BagReader`) and the clock-kill system test
    (tests/faults/test_restart_ros.py: bag of a run whose clock was killed == uninterrupted run).
    """

    def __init__(self, path: str | Path, *, epoch_ns: int = 0):
        """``epoch_ns``: the bag's epoch (:class:`BagWriter`): /clock content and the export's clock."""
        self.path = Path(path)
        self.epoch_ns = epoch_ns
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.db = sqlite3.connect(str(self.path), isolation_level=None)
        mode = self.db.execute("PRAGMA journal_mode=WAL").fetchone()[0]
        if mode.lower() != "wal":
            raise RuntimeError(f"{self.path}: SQLite refused WAL mode (got {mode})")
        self.db.execute("PRAGMA synchronous=NORMAL")
        self.db.execute("CREATE TABLE IF NOT EXISTS clock_checkpoint (id INTEGER PRIMARY KEY CHECK (id = 0), "
                        "k INTEGER NOT NULL, state BLOB NOT NULL)")
        self.db.execute("CREATE TABLE IF NOT EXISTS recorded (k INTEGER NOT NULL, topic TEXT NOT NULL, "
                        "msgtype TEXT NOT NULL, t_ns INTEGER NOT NULL, cdr BLOB NOT NULL, source TEXT, seq INTEGER)")
        self.k = -1
        self.counts: dict[str, int] = {}
        for topic, n in self.db.execute("SELECT topic, COUNT(*) FROM recorded GROUP BY topic"):
            self.counts[topic] = int(n)
        self._closed = False
        self.db.execute("BEGIN IMMEDIATE")

    # -- the BagWriter write API -------------------------------------------------------------------
    def write_raw(self, topic: str, msgtype: str, cdr: bytes | memoryview, log_time_ns: int,
                  *, qos: Qos | None = None) -> None:
        self.write_keyed(topic, msgtype, cdr, log_time_ns, None, None)

    def write_keyed(self, topic: str, msgtype: str, cdr: bytes | memoryview, log_time_ns: int,
                    source: str | None, seq: int | None) -> None:
        if self._closed:
            raise ValueError(f"journal {self.path}: closed")
        if log_time_ns < 0:
            raise ValueError(f"journal {self.path}: {topic}: log time must be >= 0, got {log_time_ns}")
        self.db.execute("INSERT INTO recorded VALUES (?, ?, ?, ?, ?, ?, ?)",
                        (self.k, topic, msgtype, int(log_time_ns), bytes(cdr), source, seq))
        self.counts[topic] = self.counts.get(topic, 0) + 1

    def write_msg(self, topic: str, msgtype: str, msg: Any, log_time_ns: int, *, qos: Qos | None = None) -> None:
        self.write_raw(topic, msgtype, TYPESTORE.serialize_cdr(msg, msgtype), log_time_ns, qos=qos)

    def write_envelope(self, env: Envelope) -> None:
        self.write_raw(env.topic, STRING, string_cdr(encode_envelope(env)), env.t_ns)

    def write_clock(self, t_ns: int) -> None:
        self.write_raw("/clock", CLOCK_TYPE, clock_cdr(self.epoch_ns + t_ns), t_ns)

    # -- checkpoint --------------------------------------------------------------------------------
    def commit(self, k: int, state: bytes) -> None:
        """Write the checkpoint row for wire step ``k`` and commit it with every message since the last."""
        self.db.execute("INSERT OR REPLACE INTO clock_checkpoint VALUES (0, ?, ?)", (int(k), bytes(state)))
        self.db.execute("COMMIT")
        self.db.execute("BEGIN IMMEDIATE")

    def load(self) -> tuple[int, bytes] | None:
        row = self.db.execute("SELECT k, state FROM clock_checkpoint WHERE id = 0").fetchone()
        return None if row is None else (int(row[0]), bytes(row[1]))

    def keyed_rows(self, min_k: int | None = None) -> Iterator[tuple[int, str, str, int, bytes | None]]:
        """(k, topic, source, seq, cdr) of the envelopes recorded with a key; ``cdr`` only for ``k >= min_k``."""
        lo = -(1 << 62) if min_k is None else int(min_k)
        for k, topic, source, seq, cdr in self.db.execute(
                "SELECT k, topic, source, seq, CASE WHEN k >= ? THEN cdr END FROM recorded "
                "WHERE source IS NOT NULL ORDER BY rowid", (lo,)):
            yield int(k), topic, source, int(seq), cdr

    def rows_on(self, suffix: str) -> Iterator[tuple[str, bytes]]:
        """(topic, cdr) of every row recorded on a topic ending with ``suffix``, in arrival order."""
        for topic, cdr in self.db.execute("SELECT topic, cdr FROM recorded WHERE topic LIKE ? ORDER BY rowid",
                                          ("%" + suffix,)):
            if topic.endswith(suffix):
                yield topic, bytes(cdr)

    # -- the bag -----------------------------------------------------------------------------------
    def export(self, bag_dir: str | Path, *, custom: dict[str, str] | None = None) -> int:
        """Write every recorded message (arrival order) into a new bag at ``bag_dir`` (replaced if a
        previous export was cut short) on the journal's clock (``epoch_ns``, :class:`BagWriter`);
        returns the number written. Rows hold t_ns."""
        bag_dir = Path(bag_dir)
        if bag_dir.exists():
            shutil.rmtree(bag_dir)
        n = 0
        with BagWriter(bag_dir, custom=custom, epoch_ns=self.epoch_ns) as bag:
            for topic, msgtype, t_ns, cdr in self.db.execute(
                    "SELECT topic, msgtype, t_ns, cdr FROM recorded ORDER BY rowid"):
                bag.write_raw(topic, msgtype, cdr, t_ns)
                n += 1
        return n

    def close(self, *, commit: bool = False) -> None:
        """Close the file; the open transaction (the unfinished step) is rolled back unless ``commit``:
        a restarted clock re-runs that step and records it again."""
        if not self._closed:
            self._closed = True
            if self.db.in_transaction:
                self.db.execute("COMMIT" if commit else "ROLLBACK")
            self.db.close()
