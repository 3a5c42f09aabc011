"""rosbag2-compatible MCAP bags without rclpy: write and read back (DESIGN.md section 6).

A bag is a directory holding ``metadata.yaml`` and ``<name>.mcap`` (rosbag2 format version 9,
storage ``mcap``, ROS 2 CDR messages, ``ros2msg`` schemas, an ``offered_qos_profiles`` entry per
channel, zstd chunk compression), written with ``rosbags`` (StoragePlugin.MCAP) so that
``ros2 bag info/play``, Foxglove, ``mcap`` and ``rosbags`` open it.

Writer API (used by both engines)::

    with BagWriter(path, custom={"scenario": "paper"}) as bag:     # path must not exist yet
        bag.write_envelope(env)                                   # std_msgs/msg/String, log time = env.t_ns
        bag.write_envelopes(envs)                                 # the same for each, in one call
        bag.write_raw("/clock", "rosgraph_msgs/msg/Clock", cdr_bytes, log_time_ns)   # raw CDR as is
        bag.write_msg("/viz/constellation", "visualization_msgs/msg/MarkerArray", msg, log_time_ns)
        bag.write_clock(t_ns)                                     # rosgraph_msgs/Clock at t_ns
    # .counts -> {topic: n}; close() is idempotent; an exception inside ``with`` still closes the
    # bag so it stays readable (Ctrl-C).

Envelopes are recorded as their wire text (msgs_json/wire.py) in std_msgs/msg/String, so
``BagReader.envelopes()`` gives back the exact envelopes. ``write_msg`` takes a message built
with rosbags' typestore (``TYPESTORE.types[msgtype](...)``; bringup/recording/viz_messages.py builds them).
QoS offered per topic: reliable/volatile/keep_last(100) by default; ``/clock`` best effort depth 1
(what rclpy's TimeSource subscribes with); ``/sim/step`` and ``/sim/ack`` reliable, transient local,
keep all (ROS2_NOTES.md lockstep traps 3-4). Override with ``qos=`` on a topic's first write.

Reader API::

    with BagReader(path) as bag:               # UserError (one line) if missing/truncated/not a bag
        bag.topics() -> list[TopicStats(topic, msgtype, count)]; bag.start_ns, bag.end_ns, bag.count
        bag.messages(topics=None) -> iter of RawMessage(topic, msgtype, log_time_ns, cdr)
        bag.envelopes(topics=None) -> iter of Envelope (String topics carrying wire envelopes)
        bag.typed(topics=None) -> iter of (topic, log_time_ns, rosbags message object)

Oracle: tests/unit/test_recording.py writes a bag in tmp_path and reads it back with BOTH the
``mcap`` reader (+ mcap-ros2-support decoding, an independent implementation) and ``rosbags``;
the hand-written std_msgs/String CDR is checked byte for byte against rosbags' serializer.
The speed paths (one-call envelope writes, ``write_envelopes`` batches, and rosbags' own steps
made faster in rosbags_speedups.py) give byte-identical bags and the same messages as rosbags' own
paths (tests/unit/test_speed_paths.py).
"""

from __future__ import annotations

import shutil
import sqlite3
import struct
from collections import defaultdict
from collections.abc import Iterable, Iterator
from contextlib import nullcontext
from pathlib import Path
from typing import Any, NamedTuple, Self

from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosbags.rosbag2 import Reader, Writer
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode, StoragePlugin
from rosbags.rosbag2.storage_mcap import McapWriter
from rosbags.typesys import Stores, get_typestore

from bringup.errors import UserError
from bringup.recording import rosbags_speedups
from msgs_json.envelope import Envelope
from msgs_json.wire import WireEncoder, WireError, decode_envelope, encode_envelope, encode_envelope_bytes

__all__ = [
    "CLOCK_TYPE",
    "STRING",
    "TYPESTORE",
    "BagJournal",
    "BagReader",
    "BagWriter",
    "RawMessage",
    "TopicStats",
    "clock_cdr",
    "make_qos",
    "string_cdr",
    "string_from_cdr",
]

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
STRING = "std_msgs/msg/String"
CLOCK_TYPE = "rosgraph_msgs/msg/Clock"
_CDR_LE = b"\x00\x01\x00\x00"  # CDR little-endian encapsulation header
_U32 = struct.Struct("<I")
_CLOCK = struct.Struct("<4siI")


def make_qos(*, reliable: bool = True, transient_local: bool = False, keep_all: bool = False,
             depth: int = 100) -> Qos:
    """A rosbags Qos record for ``offered_qos_profiles``."""
    zero = QosTime(0, 0)
    return Qos(
        QosHistory.KEEP_ALL if keep_all else QosHistory.KEEP_LAST,
        0 if keep_all else depth,
        QosReliability.RELIABLE if reliable else QosReliability.BEST_EFFORT,
        QosDurability.TRANSIENT_LOCAL if transient_local else QosDurability.VOLATILE,
        zero,
        zero,
        QosLiveliness.AUTOMATIC,
        zero,
        False,
    )


_DEFAULT_QOS = make_qos()
_TOPIC_QOS = {
    "/clock": make_qos(reliable=False, depth=1),
    "/sim/step": make_qos(transient_local=True, keep_all=True),
    "/sim/ack": make_qos(transient_local=True, keep_all=True),
}


# -- speed (a paper run records ~450k messages) ------------------------------------------------------
# rosbags' Writer.write checks ``connection in self.connections`` (a linear scan of ~200 dataclass
# compares) and builds each MCAP Message record from five small writes; _fast_write appends the same
# bytes (MCAP Message record: opcode 0x05, uint64 length, uint16 channel, uint32 sequence 0, uint64
# log and publish time, data) and keeps the same chunk index/statistics, so the file is byte for byte
# what rosbags writes (tests/unit/test_speed_paths.py compares the two). The speed-ups of rosbags'
# own steps (chunk close, QoS YAML dump and parse, chunk reading) are in rosbags_speedups.py, applied
# to this module's writers and readers only.
_MSG_HEADER = struct.Struct("<BQHIQQ")
_CHUNK_LIMIT = 2**20


def _fast_write(st: McapWriter, cid: int, ts: int, data) -> None:
    if ts < st.message_start_time:
        st.message_start_time = ts
    if ts > st.message_end_time:
        st.message_end_time = ts
    st.channel_stats[cid] += 1
    ch = st.chunk
    if ts < ch.message_start_time:
        ch.message_start_time = ts
    if ts > ch.message_end_time:
        ch.message_end_time = ts
    bio = ch.bio
    pos = bio.tell()
    ch.msgs[cid].append((ts, pos))
    bio.write(_MSG_HEADER.pack(0x05, 22 + len(data), cid, 0, ts, ts))
    bio.write(data)
    if pos + 31 + len(data) > _CHUNK_LIMIT:
        st.close_chunk()


# A Message record whose data is a std_msgs/String CDR: the record header above, then the CDR
# encapsulation and the string length (the text and its NUL follow). write_envelopes writes it.
_ENV_HEADER = struct.Struct("<BQHIQQ4sI")
_NUL = b"\x00"

def string_cdr(text: str) -> bytes:
    """CDR (little endian) of std_msgs/msg/String(data=text), as rclpy serializes it."""
    b = text.encode("utf-8")
    return _CDR_LE + _U32.pack(len(b) + 1) + b + b"\x00"


def string_from_cdr(cdr: bytes | memoryview) -> str:
    """Inverse of :func:`string_cdr` (little- or big-endian encapsulation)."""
    cdr = bytes(cdr)
    if len(cdr) < 9 or cdr[0] != 0 or cdr[1] not in (0, 1):
        raise ValueError("not a CDR std_msgs/String")
    n = struct.unpack("<I" if cdr[1] == 1 else ">I", cdr[4:8])[0]
    if n < 1 or 8 + n > len(cdr) or cdr[8 + n - 1] != 0:
        raise ValueError("CDR std_msgs/String length out of range")
    return cdr[8:8 + n - 1].decode("utf-8")


def clock_cdr(t_ns: int) -> bytes:
    """CDR of rosgraph_msgs/msg/Clock at ``t_ns`` (builtin_interfaces/Time sec, nanosec)."""
    sec, nsec = divmod(int(t_ns), 1_000_000_000)
    return _CLOCK.pack(_CDR_LE, sec, nsec)


class RawMessage(NamedTuple):
    topic: str
    msgtype: str
    log_time_ns: int
    cdr: bytes


class TopicStats(NamedTuple):
    topic: str
    msgtype: str
    count: int


class BagWriter:
    """Write a rosbag2 MCAP bag (see the module docstring)."""

    def __init__(self, path: str | Path, *, compress: bool = True, custom: dict[str, str] | None = None,
                 fast_off: bool = False):
        """``fast_off``: write through rosbags' own code paths only (the speed paths' oracle)."""
        self.path = Path(path)
        if self.path.exists():
            raise UserError(f"bag {self.path}: already exists, not overwriting")
        self._w = Writer(self.path, version=9, storage_plugin=StoragePlugin.MCAP)
        if compress:
            self._w.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
        for k, v in (custom or {}).items():
            self._w.set_custom_data(str(k), str(v))
        self._w.open()
        st = self._w.storage
        self._fast = st if (type(st) is McapWriter and not fast_off
                            and self._w.compression_mode != CompressionMode.MESSAGE) else None
        self._speedups = nullcontext
        if self._fast is not None:
            rosbags_speedups.install()
            rosbags_speedups.speed_up_writer(st)
            self._speedups = rosbags_speedups.active
        self._tmin, self._tmax = 2**63 - 1, 0  # the Writer's own bounds (metadata.yaml), kept here
        self._conns: dict[tuple[str, str], Any] = {}
        self._env_conns: dict[str, Any] = {}  # topic -> its std_msgs/String connection (write_envelope)
        self.counts: dict[str, int] = {}
        self._ncid: defaultdict[int, int] = defaultdict(int)  # per channel, added to the writer's at close
        self._wire = WireEncoder()
        self._closed = False

    # -- connections ---------------------------------------------------------------------------------
    def _conn(self, topic: str, msgtype: str, qos: Qos | None):
        key = (topic, msgtype)
        c = self._conns.get(key)
        if c is None:
            if msgtype not in TYPESTORE.types:
                raise ValueError(f"bag {self.path}: unknown message type {msgtype!r} for {topic}")
            q = qos or _TOPIC_QOS.get(topic, _DEFAULT_QOS)
            with self._speedups():
                c = self._w.add_connection(topic, msgtype, typestore=TYPESTORE, offered_qos_profiles=[q])
            self._conns[key] = c
            self.counts.setdefault(topic, 0)
        return c

    # -- writing -------------------------------------------------------------------------------------
    def write_raw(self, topic: str, msgtype: str, cdr: bytes | memoryview, log_time_ns: int,
                  *, qos: Qos | None = None) -> None:
        """Record already-serialized CDR bytes of ``msgtype`` on ``topic`` at ``log_time_ns``."""
        if self._closed:
            raise ValueError(f"bag {self.path}: closed")
        if log_time_ns < 0:
            raise ValueError(f"bag {self.path}: {topic}: log time must be >= 0, got {log_time_ns}")
        c = self._conn(topic, msgtype, qos)
        if self._fast is not None:  # byte-identical to self._w.write (see _fast_write)
            t = int(log_time_ns)
            _fast_write(self._fast, c.id, t, cdr)
            self._w.counts[c.id] += 1
            if t < self._tmin:
                self._tmin = t
            if t > self._tmax:
                self._tmax = t
        else:
            self._w.write(c, int(log_time_ns), cdr)
        self.counts[topic] += 1

    def write_msg(self, topic: str, msgtype: str, msg: Any, log_time_ns: int, *, qos: Qos | None = None) -> None:
        """Serialize a rosbags typestore message and record it."""
        self.write_raw(topic, msgtype, TYPESTORE.serialize_cdr(msg, msgtype), log_time_ns, qos=qos)

    def write_envelope(self, env: Envelope) -> None:
        """Record an envelope's wire text as std_msgs/String on its topic at log time ``env.t_ns``."""
        t = env.t_ns
        c = self._env_conns.get(env.topic) if self._fast is not None else None
        if c is None or type(t) is not int or t < 0 or self._closed:
            self.write_raw(env.topic, STRING, string_cdr(encode_envelope(env)), t)
            if self._fast is not None and not self._closed:
                self._env_conns[env.topic] = self._conns[(env.topic, STRING)]
            return
        # what write_raw(topic, STRING, string_cdr(encode_envelope(env)), t) does, in one call
        j = encode_envelope_bytes(env)
        _fast_write(self._fast, c.id, t, b"".join((_CDR_LE, _U32.pack(len(j) + 1), j, b"\x00")))
        self._w.counts[c.id] += 1
        if t < self._tmin:
            self._tmin = t
        if t > self._tmax:
            self._tmax = t
        self.counts[env.topic] += 1

    def write_envelopes(self, envs: Iterable[Envelope]) -> None:
        """``write_envelope`` of each, in order, in one call (the local engine hands over each step's
        envelopes so; same file as one call per envelope): the records are collected in a list and
        written to the chunk once per call or chunk, times and counts kept in locals."""
        st = self._fast
        if st is None or self._closed:
            for e in envs:
                self.write_envelope(e)
            return
        conns = self._env_conns
        counts = self.counts
        ncid = self._ncid
        wire = self._wire
        pack = _ENV_HEADER.pack
        limit = _CHUNK_LIMIT
        ch = st.chunk
        index = ch.msgs
        pos = ch.bio.tell()
        lo, hi = ch.message_start_time, ch.message_end_time
        parts: list[bytes] = []
        add = parts.append
        for e in envs:
            t = e.t_ns
            topic = e.topic
            c = conns.get(topic)
            if c is None or type(t) is not int or t < 0:
                # first envelope on a topic, or bad input: the one-envelope path (its errors)
                self._sync_chunk(st, parts, lo, hi)
                self.write_envelope(e)
                ch = st.chunk
                index = ch.msgs
                pos = ch.bio.tell()
                lo, hi = ch.message_start_time, ch.message_end_time
                continue
            j = wire(e)
            n = len(j)
            cid = c.id
            index[cid].append((t, pos))
            add(pack(0x05, 31 + n, cid, 0, t, t, _CDR_LE, n + 1))
            add(j)
            add(_NUL)
            pos += 40 + n
            if t < lo:
                lo = t
            if t > hi:
                hi = t
            ncid[cid] += 1
            counts[topic] += 1
            if pos > limit:
                self._sync_chunk(st, parts, lo, hi)
                st.close_chunk()
                ch = st.chunk
                index = ch.msgs
                pos = ch.bio.tell()
                lo, hi = ch.message_start_time, ch.message_end_time
        self._sync_chunk(st, parts, lo, hi)

    def _sync_chunk(self, st: McapWriter, parts: list[bytes], lo: int, hi: int) -> None:
        """Hand write_envelopes' pending records and time bounds to the open chunk and the writer."""
        ch = st.chunk
        if parts:
            ch.bio.write(b"".join(parts))
            parts.clear()
        ch.message_start_time, ch.message_end_time = lo, hi
        if lo < st.message_start_time:
            st.message_start_time = lo
        if hi > st.message_end_time:
            st.message_end_time = hi
        if lo < self._tmin:
            self._tmin = lo
        if hi > self._tmax:
            self._tmax = hi

    def write_clock(self, t_ns: int) -> None:
        self.write_raw("/clock", CLOCK_TYPE, clock_cdr(t_ns), t_ns)

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            if self._fast is not None:
                for cid, k in self._ncid.items():  # write_envelopes' message counts
                    self._fast.channel_stats[cid] += k
                    self._w.counts[cid] += k
                self._ncid.clear()
                self._w.min_timestamp = min(self._w.min_timestamp, self._tmin)
                self._w.max_timestamp = max(self._w.max_timestamp, self._tmax)
            # rosbags' own QoS dump here: metadata.yaml (version 9) lists each topic's offered
            # profiles as a YAML sequence; the memo gives the string form a channel's user data uses
            self._w.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _bag_dir(path: Path) -> Path:
    if path.is_file() and path.suffix == ".mcap" and (path.parent / "metadata.yaml").exists():
        return path.parent
    return path


class BagReader:
    """Read a rosbag2 bag (MCAP or sqlite3) back; every failure is a one-line UserError."""

    def __init__(self, path: str | Path, *, fast: bool = True):
        """``fast=False``: read through rosbags' own code paths only (the speed paths' oracle)."""
        self.path = _bag_dir(Path(path))
        if not self.path.exists():
            raise UserError(f"bag {self.path}: not found")
        if not (self.path / "metadata.yaml").is_file():
            raise UserError(f"bag {self.path}: not a rosbag2 bag (no metadata.yaml)")
        self._speedups = nullcontext
        if fast:
            rosbags_speedups.install()
            self._speedups = rosbags_speedups.active
        try:
            self._r = Reader(self.path)
            with self._speedups():
                self._r.open()
            if fast:
                rosbags_speedups.speed_up_reader(self._r)
        except Exception as exc:  # noqa: BLE001 - rosbags raises ReaderError, YAML, struct errors...
            raise UserError(f"bag {self.path}: cannot open: {_line(exc)}") from None

    def close(self) -> None:
        self._r.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    @property
    def start_ns(self) -> int:
        return int(self._r.start_time) if self.count else 0

    @property
    def end_ns(self) -> int:
        return max(int(self._r.end_time) - 1, self.start_ns) if self.count else 0  # rosbags end is +1

    @property
    def count(self) -> int:
        return int(self._r.message_count)

    def topics(self) -> list[TopicStats]:
        out: dict[tuple[str, str], int] = {}
        for c in self._r.connections:
            out[(c.topic, c.msgtype)] = out.get((c.topic, c.msgtype), 0) + int(c.msgcount)
        return [TopicStats(t, m, n) for (t, m), n in sorted(out.items())]

    def messages(self, topics: Iterable[str] | None = None) -> Iterator[RawMessage]:
        """Raw CDR in log-time order."""
        conns = self._r.connections
        if topics is not None:
            want = set(topics)
            conns = [c for c in conns if c.topic in want]
            if not conns:
                return
        try:
            for c, t, raw in self._r.messages(connections=conns):
                yield RawMessage(c.topic, c.msgtype, int(t), bytes(raw))
        except UserError:
            raise
        except Exception as exc:  # noqa: BLE001 - a damaged file fails in many ways: one line for all
            raise UserError(f"bag {self.path}: unreadable: {_line(exc)}") from None

    def envelopes(self, topics: Iterable[str] | None = None) -> Iterator[Envelope]:
        """Wire envelopes recorded on std_msgs/String topics (other String topics are an error)."""
        for m in self.messages(topics):
            if m.msgtype != STRING:
                continue
            try:
                yield decode_envelope(string_from_cdr(m.cdr), m.topic)
            except (WireError, ValueError) as exc:
                raise UserError(f"bag {self.path}: {m.topic} at {m.log_time_ns} ns: {_line(exc)}") from None

    def typed(self, topics: Iterable[str] | None = None) -> Iterator[tuple[str, int, Any]]:
        """(topic, log_time_ns, rosbags message object) in log-time order."""
        for m in self.messages(topics):
            try:
                yield m.topic, m.log_time_ns, TYPESTORE.deserialize_cdr(m.cdr, m.msgtype)
            except Exception as exc:  # noqa: BLE001 - any decoding failure is the bag's fault
                raise UserError(f"bag {self.path}: {m.topic}: cannot decode {m.msgtype}: {_line(exc)}") from None


def _line(exc: BaseException) -> str:
    s = " ".join(str(exc).split()) or type(exc).__name__
    return s[:300]


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

    def __init__(self, path: str | Path):
        self.path = Path(path)
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
        self.write_raw("/clock", CLOCK_TYPE, clock_cdr(t_ns), t_ns)

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

    # -- the bag -----------------------------------------------------------------------------------
    def export(self, bag_dir: str | Path, *, custom: dict[str, str] | None = None) -> int:
        """Write every recorded message (arrival order) into a new bag at ``bag_dir`` (replaced if a
        previous export was cut short); returns the number written."""
        bag_dir = Path(bag_dir)
        if bag_dir.exists():
            shutil.rmtree(bag_dir)
        n = 0
        with BagWriter(bag_dir, custom=custom) as bag:
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
