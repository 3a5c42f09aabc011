"""rosbag2-compatible MCAP bags without rclpy: write and read back (docs/design.md section 6).

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

Time: ``t_ns`` (ns since the scenario epoch) is the project's time base and the envelopes' payload
field; the writer and the reader speak it. In the file, the bag is on the scenario's real clock:
every message's MCAP log and publish time is ``epoch_ns + t_ns`` (Unix ns, UTC) and ``/clock``
(``write_clock``; the ROS clock node writes its own) carries that instant, so Foxglove's timeline
and ``ros2 bag play --clock`` show the scenario's date (2000-01-01T11:59:28Z for the paper case).
``BagWriter(epoch_ns=...)`` adds the epoch; metadata.yaml's ``custom_data`` keeps it (``epoch_ns``,
``epoch_utc``; the MCAP file's ``rosbag2`` metadata record holds the same text) and
:class:`BagReader` subtracts it again, so its ``log_time_ns``, ``start_ns`` and ``end_ns`` are
``t_ns``; ``reader.epoch_ns`` gives it back. A bag without the key (written before, or with epoch 0:
toy runs) has epoch 0 and reads as before.

CRCs: every chunk's ``uncompressed_crc``, the DataEnd ``data_section_crc`` and the Footer's
``summary_crc`` are written (CRC-32, https://mcap.dev/spec; rosbags writes 0, "not computed"): the
chunk CRC as each chunk closes, the other two when the file is complete (mcap_file.py).

Crash safety: right after the MCAP header the writer puts a Metadata record named ``constellation``
(the epoch and the custom data) and flushes; every chunk is flushed to the file as it closes, and a
/clock message (a step's start) closes the open chunk first when it spans ``chunk_span_ns`` of sim
time (default :data:`CHUNK_SPAN_NS`, 2 min). So a writer killed at any instant leaves a file that
holds every chunk closed before (only the open chunk, at most 2 min of sim time or 1 MiB of
records, is lost), and the reader recovers it (bag_reader.py). Cost, measured on the paper run's
448,726 messages: 21.05 MB in 162 chunks (size only) -> 21.22 MB (2 min) vs 21.80 MB (1 min).

Envelopes are recorded as their wire text (msgs_json/wire.py) in std_msgs/msg/String, so
``BagReader.envelopes()`` gives back the exact envelopes. ``write_msg`` takes a message built
with rosbags' typestore (``TYPESTORE.types[msgtype](...)``; bringup/recording/viz_messages.py builds them).
QoS offered per topic (:func:`topic_qos`; ``constellation replay`` offers them again, and the ROS
engine's live visualisation publishes with them): reliable/volatile/keep_last(100) by default
(markers, fixes, /tf, the plotted series); envelopes (std_msgs/String) reliable, volatile, keep all,
as the ROS engine's data topics; ``/clock`` best effort depth 1 (what rclpy's TimeSource subscribes
with); ``/tf_static`` reliable, transient local, depth 1 (tf2's static broadcaster); ``/sim/step``
and ``/sim/ack`` reliable, transient local, keep all (docs/design.md section 7, lockstep traps 3-4). Override
with ``qos=`` on a topic's first write.

Reading: :class:`BagReader` (bag_reader.py, re-exported here): the ``.mcap`` is the truth,
metadata.yaml is checked against it, a cut file is read as far as it goes; ``offered_qos()``
gives each topic's recorded QoS offers (the replayer's).

Oracle: tests/unit/test_recording.py writes a bag in tmp_path and reads it back with BOTH the
``mcap`` reader (+ mcap-ros2-support decoding, an independent implementation, CRCs validated) and
``rosbags``, with and without an epoch; tests/system/test_foxglove_decode.py decodes a run's bag
with Foxglove's own JavaScript readers and checks its timeline starts at the scenario epoch;
the hand-written std_msgs/String CDR is checked byte for byte against rosbags' serializer.
The speed paths (one-call envelope writes, ``write_envelopes`` batches, and rosbags' own steps
made faster in rosbags_speedups.py) give byte-identical bags and the same messages as rosbags' own
paths, except the bag summary (metadata.yaml and the MCAP's rosbag2 record), which libyaml dumps:
the same YAML mapping in other bytes (tests/unit/test_speed_paths.py).
"""

from __future__ import annotations

import struct
from collections import defaultdict
from collections.abc import Iterable
from contextlib import nullcontext
from pathlib import Path
from typing import Any, Self

from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosbags.rosbag2 import Writer
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode, StoragePlugin
from rosbags.rosbag2.storage_mcap import McapWriter

from bringup.errors import UserError
from bringup.recording import rosbags_speedups
from bringup.recording.bag_format import (
    CDR_LE,
    CLOCK_TYPE,
    LEADING_METADATA,
    STRING,
    TYPESTORE,
    U32,
    RawMessage,
    TopicStats,
    clock_cdr,
    epoch_custom_data,
    string_cdr,
    string_from_cdr,
)
from bringup.recording.bag_reader import BagReader
from bringup.recording.mcap_file import metadata_record, with_chunk_crc, write_file_crcs
from msgs_json.envelope import Envelope
from msgs_json.wire import WireEncoder, encode_envelope, encode_envelope_bytes

__all__ = [
    "CLOCK_TYPE",
    "STRING",
    "TYPESTORE",
    "BagReader",
    "BagWriter",
    "RawMessage",
    "TopicStats",
    "clock_cdr",
    "epoch_custom_data",
    "make_qos",
    "topic_qos",
    "string_cdr",
    "string_from_cdr",
]

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
_ENVELOPE_QOS = make_qos(keep_all=True)
_TOPIC_QOS = {
    "/clock": make_qos(reliable=False, depth=1),
    "/tf_static": make_qos(transient_local=True, depth=1),
    "/sim/step": make_qos(transient_local=True, keep_all=True),
    "/sim/ack": make_qos(transient_local=True, keep_all=True),
}


def topic_qos(topic: str, msgtype: str) -> Qos:
    """The QoS a topic is recorded (and offered live) with when none is given (module docstring)."""
    q = _TOPIC_QOS.get(topic)
    if q is not None:
        return q
    return _ENVELOPE_QOS if msgtype == STRING else _DEFAULT_QOS


# -- speed (a paper run records ~450k messages) ------------------------------------------------------
# rosbags' Writer.write checks ``connection in self.connections`` (a linear scan of ~200 dataclass
# compares) and builds each MCAP Message record from five small writes; _fast_write appends the same
# bytes (MCAP Message record: opcode 0x05, uint64 length, uint16 channel, uint32 sequence 0, uint64
# log and publish time, data) and keeps the same chunk index/statistics, so the file is byte for byte
# what rosbags writes (tests/unit/test_speed_paths.py compares the two). The speed-ups of rosbags'
# own steps (chunk close, QoS YAML dump and parse, chunk reading, the summary's YAML) are in
# rosbags_speedups.py, applied to this module's writers and readers only.
_MSG_HEADER = struct.Struct("<BQHIQQ")
_CHUNK_LIMIT = 2**20
# Crash safety (module docstring): a chunk also closes at the first /clock (a step's start) 2 min of
# sim time after its first message
CHUNK_SPAN_NS = 120 * 1_000_000_000


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

class BagWriter:
    """Write a rosbag2 MCAP bag (see the module docstring)."""

    def __init__(self, path: str | Path, *, compress: bool = True, custom: dict[str, str] | None = None,
                 fast_off: bool = False, epoch_ns: int = 0, chunk_span_ns: int | None = CHUNK_SPAN_NS):
        """``epoch_ns``: the scenario epoch in Unix ns, added to every log time (module docstring);
        ``chunk_span_ns``: a /clock message closes the open chunk first when the chunk's first
        message is at least this much sim time older (None: chunks close on size only);
        ``fast_off``: write through rosbags' own code paths only (the speed paths' oracle)."""
        self.path = Path(path)
        if type(epoch_ns) is not int or epoch_ns < 0:
            raise ValueError(f"bag {self.path}: epoch_ns must be an int >= 0 (MCAP times are unsigned ns "
                             f"since 1970), got {epoch_ns!r}")
        if self.path.exists():
            raise UserError(f"bag {self.path}: already exists, not overwriting")
        self.epoch_ns = epoch_ns
        self._w = Writer(self.path, version=9, storage_plugin=StoragePlugin.MCAP)
        if compress:
            self._w.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
        for k, v in {**(custom or {}), **epoch_custom_data(epoch_ns)}.items():
            self._w.set_custom_data(str(k), str(v))
        self._w.open()
        st = self._w.storage
        if isinstance(st, McapWriter):  # the epoch and custom data where a cut file still has them
            st.bio.write(metadata_record(LEADING_METADATA, {**(custom or {}), **epoch_custom_data(epoch_ns),
                                                            "epoch_ns": str(epoch_ns)}))
            st.bio.flush()
        self._span = chunk_span_ns
        self._fast = st if (type(st) is McapWriter and not fast_off
                            and self._w.compression_mode != CompressionMode.MESSAGE) else None
        self._speedups = self._summary_yaml = nullcontext
        if self._fast is not None:
            rosbags_speedups.install()
            rosbags_speedups.speed_up_writer(st)
            self._speedups = rosbags_speedups.active
            self._summary_yaml = rosbags_speedups.metadata_yaml
        self._mcap_path = st.path if isinstance(st, McapWriter) else None
        if self._mcap_path is not None:
            with_chunk_crc(st)
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
            q = qos or topic_qos(topic, msgtype)
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
        if topic == "/clock" and self._span is not None and self._mcap_path is not None:
            ch = self._w.storage.chunk  # a step begins: close a chunk that spans chunk_span_ns
            if ch.bio.tell() and self.epoch_ns + int(log_time_ns) - ch.message_start_time >= self._span:
                self._w.storage.close_chunk()
        c = self._conn(topic, msgtype, qos)
        if self._fast is not None:  # byte-identical to self._w.write (see _fast_write)
            t = self.epoch_ns + int(log_time_ns)
            _fast_write(self._fast, c.id, t, cdr)
            self._w.counts[c.id] += 1
            if t < self._tmin:
                self._tmin = t
            if t > self._tmax:
                self._tmax = t
        else:
            self._w.write(c, self.epoch_ns + int(log_time_ns), cdr)
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
        t += self.epoch_ns
        _fast_write(self._fast, c.id, t, b"".join((CDR_LE, U32.pack(len(j) + 1), j, b"\x00")))
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
        off = self.epoch_ns
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
            t += off
            index[cid].append((t, pos))
            add(pack(0x05, 31 + n, cid, 0, t, t, CDR_LE, n + 1))
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
        """/clock at ``t_ns``: the instant epoch + t_ns (UTC), logged then."""
        self.write_raw("/clock", CLOCK_TYPE, clock_cdr(self.epoch_ns + t_ns), t_ns)

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
            # profiles as a YAML sequence; the memo gives the string form a channel's user data uses.
            # The summary itself (metadata.yaml and the MCAP's rosbag2 record) is dumped by libyaml
            # (rosbags_speedups.metadata_yaml: the same mapping, not ruamel's bytes)
            with self._summary_yaml():
                self._w.close()
            if self._mcap_path is not None:
                write_file_crcs(self._mcap_path)

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


