"""Faster equivalents of five rosbags internals, applied only to the project's own bags.

rosbags (https://gitlab.com/ternaris/rosbags) writes and reads rosbag2 MCAP bags in pure Python;
five of its steps cost most of a run's recording and of ``constellation report BAG``. Four
replacements compute exactly what rosbags computes (same bytes written, same messages read); the
fifth writes the same YAML mapping in other bytes:

* closing a chunk (``McapWriter.close_chunk``): rosbags writes the message index with two
  ``write_uint64`` calls per message; :func:`_fast_close_chunk` packs each channel's index in one
  struct call and writes the same records in the same order (MCAP Chunk 0x06, MessageIndex 0x07 per
  channel, the ChunkIndex kept for the summary, https://mcap.dev/spec);
* dumping a new connection's QoS profiles to the YAML text of its MCAP channel (``Writer.add_connection``
  through ``writer.dump_qos_v9`` and ruamel.yaml, ~20 ms each): the dump of an equal profile list is
  equal, so it is made once per distinct list, by ruamel as rosbags makes it. Only there: the bag's
  metadata.yaml keeps rosbags' own version-9 form (a YAML sequence per topic, as rosbag2 writes it);
* reading a chunk's records (``storage_mcap.msgsrc``): rosbags parses them through a BytesIO with
  four small reads per message; :func:`_fast_msgsrc` walks the decompressed chunk with
  ``struct.unpack_from`` and yields the same ``Msg`` tuples in the same order;
* parsing a connection's QoS YAML (``parse_qos``, ~7 ms each, ~400 connections in a paper bag): a
  pure function of the text giving immutable tuples, so each distinct text is parsed once (a
  failure is not remembered: it raises again);
* the bag summary (rosbag2 metadata format version 9, the ``rosbag2_bagfile_information``
  mapping, one entry per topic): ``Writer.close`` dumps it with ruamel.yaml twice, to metadata.yaml
  and to the MCAP's ``rosbag2`` Metadata record (~2.2 s each for the ~940 KB summary of 240
  satellites), and rosbags' folder reader loads metadata.yaml with ruamel (~3 s). Inside
  :func:`metadata_yaml`, the ``YAML(typ="safe")`` those calls make is a libyaml dumper / loader
  (bringup/recording/metadata_yaml.py, ~0.3 s each). Not the same bytes: libyaml keeps a plain
  scalar longer than the line on its key's line where ruamel moves it to the next one (the
  ``type_description_hash: RIHS01_...`` of every topic), and quotes strings such as ``on`` or
  ``1:20`` that ruamel leaves plain (YAML 1.1 readers take those for a boolean and a number). The
  same mapping: ruamel (rosbags), PyYAML's YAML 1.1 rules and yaml-cpp (rosbag2; untyped scalars)
  read what was dumped. Without libyaml it is ruamel, as before.

Scope: nothing happens on import. :func:`speed_up_writer` gives one ``McapWriter`` instance the fast
chunk close (an instance attribute; the class is untouched). The three module-level functions and
the ``YAML`` name of rosbags' writer and reader modules are looked up by name inside rosbags, so
:func:`install` (idempotent, called when a BagWriter or BagReader is made) replaces each with a
dispatcher that runs the fast version only for the project's own bags - the QoS dump and parse
inside ``with active():``, which bringup/recording/bag.py enters around its calls into rosbags, the
summary YAML inside ``with metadata_yaml():``, which BagWriter.close enters around rosbags' close
(outside ``active()``: there the QoS memo would give the string form) and BagReader around its
opening (:func:`reading`: both), the chunk reader for the files of a reader passed to
:func:`speed_up_reader` (it runs once per chunk while messages are iterated) - and rosbags' own
function everywhere else, so any other user of rosbags in the process (the tests' independent
reading, for one) gets rosbags' own code paths.

How we know it is right: tests/unit/test_speed_paths.py writes the same bag with and without the
speed-ups and compares the bytes (the summary dumped by libyaml in both), compares the summary with
rosbags' own ruamel dump (metadata.yaml and the MCAP record load to the same mapping with ruamel,
PyYAML and metadata_yaml.load; the file is rosbags' byte for byte up to that record; rosbags' Reader
and the mcap reader open both bags alike), reads a multi-chunk bag both ways and compares every
message and every connection's QoS, and checks that outside ``active()`` and ``metadata_yaml()``
rosbags' own functions run; tests/unit/test_metadata_yaml.py checks the YAML itself.
"""

from __future__ import annotations

import struct
import weakref
from collections import defaultdict
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from io import BytesIO, StringIO
from types import MethodType

import rosbags.rosbag2.metadata as _rosbags_metadata
import rosbags.rosbag2.reader as _rosbags_reader
import rosbags.rosbag2.storage_mcap as _rosbags_mcap
import rosbags.rosbag2.writer as _rosbags_writer
from rosbags.rosbag2.storage_mcap import McapWriter
from ruamel.yaml import YAML as _RuamelYAML

from bringup.recording import metadata_yaml as _metadata_yaml

__all__ = ["active", "install", "metadata_yaml", "reading", "speed_up_reader", "speed_up_writer"]

_ACTIVE: ContextVar[bool] = ContextVar("rosbags_speedups_active", default=False)
_METADATA_YAML: ContextVar[bool] = ContextVar("rosbags_speedups_metadata_yaml", default=False)
_FAST_FILES: weakref.WeakSet = weakref.WeakSet()  # the open MCAP files of speed_up_reader's readers

_U32 = struct.Struct("<I")
_U64 = struct.Struct("<Q")
_CHUNK_HEAD = struct.Struct("<BQQQQI")
_IDX_HEAD = struct.Struct("<BQHI")
_CHUNK_INDEX = struct.Struct("<QQQQI")
_HIQQ = struct.Struct("<HIQQ")


@contextmanager
def active() -> Iterator[None]:
    """Inside: rosbags' QoS dump and parse run the fast versions (this thread / context only)."""
    token = _ACTIVE.set(True)
    try:
        yield
    finally:
        _ACTIVE.reset(token)


@contextmanager
def metadata_yaml() -> Iterator[None]:
    """Inside: rosbags' ``YAML(typ="safe")`` dumps and loads through libyaml (metadata_yaml.py) -
    the bag summary that ``Writer.close`` writes twice and a folder reader loads (this thread /
    context only)."""
    token = _METADATA_YAML.set(True)
    try:
        yield
    finally:
        _METADATA_YAML.reset(token)


@contextmanager
def reading() -> Iterator[None]:
    """``active()`` and ``metadata_yaml()`` together: what a BagReader's calls into rosbags run in."""
    with active(), metadata_yaml():
        yield


# -- writing -------------------------------------------------------------------------------------------
def speed_up_writer(storage: McapWriter) -> None:
    """Give this one ``McapWriter`` the fast chunk close."""
    storage.close_chunk = MethodType(_fast_close_chunk, storage)


def _fast_close_chunk(self: McapWriter) -> None:
    ch = self.chunk
    usize = ch.bio.tell()
    compressed = self.compressor(ch.bio.getvalue())
    comp = self.compression.encode()
    out = self.bio
    chunk_start = out.tell()
    reclen = 8 + 8 + 8 + 4 + 4 + len(comp) + 8 + len(compressed)
    out.write(_CHUNK_HEAD.pack(0x06, reclen, ch.message_start_time, ch.message_end_time, usize, 0)
              + _U32.pack(len(comp)) + comp + _U64.pack(len(compressed)))
    out.write(compressed)
    chunk_end = out.tell()
    offsets = []
    for cid, msgs in ch.msgs.items():
        offsets.append((cid, out.tell()))
        k = len(msgs)
        out.write(_IDX_HEAD.pack(0x07, 6 + 16 * k, cid, 16 * k))
        out.write(struct.pack(f"<{2 * k}Q", *[x for m in msgs for x in m]))
    rec = BytesIO()
    rec.write(_CHUNK_INDEX.pack(ch.message_start_time, ch.message_end_time, chunk_start, chunk_end - chunk_start,
                                len(offsets) * 10))
    for cid, offset in offsets:
        rec.write(struct.pack("<HQ", cid, offset))
    rec.write(_U64.pack(out.tell() - chunk_end) + _U32.pack(len(comp)) + comp
              + _U64.pack(len(compressed)) + _U64.pack(usize))
    self.chunks.append(rec)
    self.chunk = _rosbags_mcap.PendingChunk(2**63 - 1, 0, BytesIO(), defaultdict(list))


_QOS_DUMPS: dict = {}


def _dump_qos_v9_memo(orig: Callable, profiles):
    key = tuple(profiles)
    out = _QOS_DUMPS.get(key)
    if out is None:
        dumped = orig(list(profiles))
        if not isinstance(dumped, str):  # what rosbags' Writer.add_connection does with it
            stream = StringIO()
            yaml = _RuamelYAML(typ="safe")  # ruamel's text, as rosbags' add_connection makes it
            yaml.default_flow_style = False
            yaml.dump(dumped, stream)
            dumped = stream.getvalue().strip()
        out = _QOS_DUMPS[key] = dumped
    return out


# -- reading -------------------------------------------------------------------------------------------
def speed_up_reader(reader) -> None:
    """Read the chunks of this open rosbags ``Reader``'s MCAP files with the fast chunk reader."""
    storage = reader.storage
    for st in getattr(storage, "storages", [storage]):
        bio = getattr(st, "bio", None)
        if isinstance(st, _rosbags_mcap.McapReader) and bio is not None:
            _FAST_FILES.add(bio)


def _fast_msgsrc(orig: Callable, chunk, channel_map, start, stop, bio):
    Msg = _rosbags_mcap.Msg
    yield Msg(chunk.message_start_time, 0, None, None)
    bio.seek(chunk.chunk_start_offset + 9 + 24)
    crc = _rosbags_mcap.deserialize_uint32(_rosbags_mcap.read_exact(bio, 4))[0]
    bio.seek(chunk.chunk_start_offset + 9 + 40 + len(chunk.compression))
    compressed = _rosbags_mcap.read_exact(bio, chunk.compressed_size)
    raw = _rosbags_mcap.decompress(compressed, chunk.compression, chunk.uncompressed_size, crc)
    n = chunk.uncompressed_size
    offset = chunk.chunk_start_offset
    hiqq = _HIQQ.unpack_from
    u64 = _U64.unpack_from
    messages = []
    pos = 0
    while pos < n:
        if pos + 9 > n:
            raise _rosbags_mcap.ReaderError("Unexpected end of chunk record.")
        op = raw[pos]
        end = pos + 9 + u64(raw, pos + 1)[0]
        if end > n:
            raise _rosbags_mcap.ReaderError("Chunk record runs past the chunk's end.")
        if op == 0x05:
            if end - pos - 9 < 22:
                raise _rosbags_mcap.ReaderError("Message record too short.")
            channel_id, _, log_time, _ = hiqq(raw, pos + 9)
            if start <= log_time < stop and channel_id in channel_map:
                messages.append(Msg(log_time, offset, channel_map[channel_id], raw[pos + 31:end]))
        pos = end
    messages.sort(key=_timestamp)
    yield from messages


def _timestamp(m):
    return m.timestamp


_QOS_PARSED: dict[str, tuple] = {}


def _parse_qos_memo(orig: Callable, dcts):
    if type(dcts) is not str:
        return orig(dcts)
    got = _QOS_PARSED.get(dcts)
    if got is None:
        got = _QOS_PARSED[dcts] = tuple(orig(dcts))
    return list(got)


# -- the metadata YAML ---------------------------------------------------------------------------------
class _LibyamlSafe:
    """What rosbags does with a ``YAML(typ="safe")`` - set ``default_flow_style``, ``dump(data,
    stream)``, ``load(text)`` - through metadata_yaml.py (libyaml, ruamel's reading)."""

    def __init__(self) -> None:
        self.default_flow_style = False

    def dump(self, data, stream) -> None:
        if self.default_flow_style is False:
            _metadata_yaml.dump(data, stream)
            return
        y = _RuamelYAML(typ="safe")
        y.default_flow_style = self.default_flow_style
        y.dump(data, stream)

    def load(self, stream):
        if isinstance(stream, str):
            return _metadata_yaml.load(stream)
        return _RuamelYAML(typ="safe").load(stream)


def _yaml_factory(orig: Callable) -> Callable:
    def YAML(*args, **kw):  # (stands in for the class name rosbags calls)
        if _METADATA_YAML.get() and _metadata_yaml.LIBYAML and not args and kw == {"typ": "safe"}:
            return _LibyamlSafe()
        return orig(*args, **kw)

    YAML.rosbags_original = orig
    return YAML


# -- the dispatchers -----------------------------------------------------------------------------------
def _in_scope(*_args) -> bool:
    return _ACTIVE.get()


def _our_file(chunk, channel_map, start, stop, bio) -> bool:
    return bio in _FAST_FILES


def _dispatcher(fast: Callable, ours: Callable) -> Callable[[Callable], Callable]:
    def make(orig: Callable) -> Callable:
        def dispatch(*args):
            return fast(orig, *args) if ours(*args) else orig(*args)

        dispatch.rosbags_original = orig
        dispatch.__name__ = dispatch.__qualname__ = getattr(orig, "__name__", "dispatch")
        return dispatch

    return make


_PATCHES = (
    ((_rosbags_writer,), "dump_qos_v9", _dispatcher(_dump_qos_v9_memo, _in_scope)),
    ((_rosbags_mcap,), "msgsrc", _dispatcher(_fast_msgsrc, _our_file)),
    ((_rosbags_metadata, _rosbags_reader, _rosbags_mcap), "parse_qos", _dispatcher(_parse_qos_memo, _in_scope)),
    ((_rosbags_writer, _rosbags_reader), "YAML", _yaml_factory),
)


def install() -> None:
    """Put the dispatchers in place of rosbags' three module-level functions and of the ``YAML``
    name its writer and reader modules call (idempotent)."""
    for modules, name, make in _PATCHES:
        for mod in modules:
            current = getattr(mod, name)
            if not hasattr(current, "rosbags_original"):
                setattr(mod, name, make(current))
