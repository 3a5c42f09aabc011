"""Read a bag back: the ``.mcap`` file is the truth, a cut file is read as far as it goes.

A bag folder (or its ``.mcap`` file) is opened through the MCAP file itself, with rosbags'
McapReader (its summary: channels, statistics, chunk indexes), not through metadata.yaml: a
metadata.yaml from another run, edited or stale, is checked against the file
(bringup/recording/bag_metadata.py) and any difference becomes a warning naming the file's numbers,
which are the ones used (:attr:`BagReader.warnings`). A folder without a single ``.mcap`` (sqlite3
bags, split bags) is read through rosbags' folder reader as rosbag2 does.

A ``.mcap`` its writer never closed (the process was killed; the disk filled) has no summary and no
footer. Then the reader scans the file (bringup/recording/mcap_file.py ``scan_mcap``) and reads every
whole chunk: :attr:`BagReader.complete` is False and :attr:`BagReader.recovery` says in one line what
was recovered (messages, chunks, the last log time) and what was lost (the bytes after the last whole
record; the messages the writer still held). The epoch comes from the file's own leading Metadata
record (bag.py writes it first), so a cut bag keeps its clock.

API::

    with BagReader(path) as bag:               # UserError (one line) if missing/not a bag
        bag.topics() -> list[TopicStats(topic, msgtype, count)]; bag.start_ns, bag.end_ns, bag.count
        bag.offered_qos() -> {topic: [rosbags Qos, ...]} (the recorded offered_qos_profiles)
        bag.messages(topics=None) -> iter of RawMessage(topic, msgtype, log_time_ns, cdr)
        bag.envelopes(topics=None) -> iter of Envelope (String topics carrying wire envelopes)
        bag.typed(topics=None) -> iter of (topic, log_time_ns, rosbags message object)
        bag.complete, bag.recovery, bag.warnings, bag.epoch_ns

Times are ``t_ns``: the log times less the epoch (bringup/recording/bag.py, "Time").

How we know it is right: tests/unit/test_recording.py (round trips against the ``mcap`` reader and
rosbags), tests/unit/test_bag_recovery.py (bags cut at every chunk boundary and at random bytes read
back exactly up to the cut; metadata.yaml renamed, foreign, multiplied: warnings with the file's
numbers) and tests/faults/test_recorder_kill.py (a recorder killed mid-run leaves a readable bag).
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from contextlib import nullcontext
from pathlib import Path
from typing import Any, Self

from rosbags.rosbag2 import Reader
from rosbags.interfaces import Qos

from bringup.errors import UserError
from bringup.recording import rosbags_speedups
from bringup.recording.bag_format import (
    LEADING_METADATA,
    STRING,
    TYPESTORE,
    RawMessage,
    TopicStats,
    string_from_cdr,
)
from bringup.recording.bag_metadata import BagTruth, disagreements, read_metadata_yaml
from bringup.recording.mcap_file import McapScanError, iter_messages, read_leading_metadata, scan_mcap
from msgs_json.envelope import Envelope
from msgs_json.wire import WireError, decode_envelope

__all__ = ["BagReader"]


def _locate(path: Path) -> tuple[Path, Path | None]:
    """(bag folder, its one .mcap file or None: read through rosbags' folder reader)."""
    if path.is_file():
        return path.parent, path
    mcaps = sorted(path.glob("*.mcap"))
    if len(mcaps) == 1:
        return path, mcaps[0]
    return path, None


class BagReader:
    """Read a bag back; every failure is a one-line UserError (module docstring, "Reading").

    ``warnings``: what the reader found wrong but read past (metadata.yaml disagreeing with the
    .mcap, a missing metadata.yaml); ``complete``: the .mcap was closed by its writer;
    ``recovery``: for an incomplete one, one line saying what was recovered and what was lost."""

    def __init__(self, path: str | Path, *, fast: bool = True):
        """``fast=False``: read through rosbags' own code paths only (the speed paths' oracle)."""
        path = Path(path)
        if not path.exists():
            raise UserError(f"bag {path}: not found")
        self.path, self.mcap = _locate(path)
        self.warnings: list[str] = []
        self.complete = True
        self.lost_data = False  # records of the data section were lost (a cut file, a damaged chunk)
        self.recovery: str | None = None
        self._scan = None
        self._speedups = nullcontext
        if fast:
            rosbags_speedups.install()
            self._speedups = rosbags_speedups.reading
        info, why = read_metadata_yaml(self.path / "metadata.yaml", fast=fast)
        if self.mcap is None:
            if info is None:
                raise UserError(f"bag {self.path}: not a rosbag2 bag ({why}, no .mcap file)")
            self._open_rosbags(self.path, fast)
            custom = getattr(getattr(self._r.storage, "metadata", None), "custom", None) or {}
            self.epoch_ns = self._epoch(custom.get("epoch_ns"), "metadata.yaml custom_data")
            return
        try:
            lead = read_leading_metadata(self.mcap, LEADING_METADATA)
        except OSError as exc:
            raise UserError(f"bag {self.path}: cannot read {self.mcap.name}: {exc.strerror or exc}") from None
        self._r = None
        try:
            self._open_rosbags(self.mcap, fast)
        except UserError as exc:
            self._recover(exc)
        if lead is not None:
            self.epoch_ns = self._epoch(lead.get("epoch_ns"), f"{self.mcap.name}'s {LEADING_METADATA} record")
        else:  # bags written before the leading record: the epoch lives in metadata.yaml only
            custom = (info or {}).get("custom_data") if isinstance((info or {}).get("custom_data"), dict) else {}
            self.epoch_ns = self._epoch((custom or {}).get("epoch_ns"), "metadata.yaml custom_data")
        self._check_metadata(info, why, lead)

    def _open_rosbags(self, where: Path, fast: bool) -> None:
        try:
            r = Reader(where)
            with self._speedups():
                r.open()
            if fast:
                rosbags_speedups.speed_up_reader(r)
        except Exception as exc:  # noqa: BLE001 - rosbags raises ReaderError, YAML, struct errors...
            raise UserError(f"bag {self.path}: cannot open: {_line(exc)}") from None
        self._r = r

    def _recover(self, exc: UserError) -> None:
        """The .mcap did not open as a whole file: keep what its whole records hold."""
        try:
            scan = scan_mcap(self.mcap)
        except (McapScanError, OSError) as err:
            raise UserError(f"{exc} ({_line(err)})") from None
        self._scan = scan
        self.complete = False
        self.lost_data = not scan.data_end or bool(scan.bad_chunks)
        held = f"{scan.message_count} messages in {len(scan.chunks)} chunks"
        if scan.message_count:
            held += f", log times up to {scan.end_time} ns"
        if scan.data_end:
            lost = "its data section is whole; its summary or footer is damaged"
        else:
            cut = f"the last {scan.lost_bytes} bytes (a record cut short) and " if scan.lost_bytes else ""
            lost = f"{scan.stop_reason}: {cut}the messages the writer had not yet written are lost"
        bad = f"; damaged chunks skipped: {'; '.join(scan.bad_chunks[:3])}" if scan.bad_chunks else ""
        self.recovery = f"{self.mcap.name} was not closed by its writer; recovered {held}; {lost}{bad}"

    def _epoch(self, value, where: str) -> int:
        if value is None:
            return 0
        try:
            epoch = int(str(value))
        except ValueError:
            raise UserError(f"bag {self.path}: {where} epoch_ns {value!r} is not an integer") from None
        if epoch < 0:
            raise UserError(f"bag {self.path}: {where} epoch_ns {value!r} is negative")
        return epoch

    def _check_metadata(self, info: dict | None, why: str | None, lead: dict | None) -> None:
        if info is None:
            if self.complete:
                self.warnings.append(f"{why}: reading {self.mcap.name} alone")
            return
        truth = BagTruth(self.mcap.name, {(t.topic, t.msgtype): t.count for t in self.topics()}, self.count,
                         self._log_bounds()[0], self._log_bounds()[1],
                         None if lead is None else self.epoch_ns)
        diff = disagreements(info, truth, counts=self.complete)
        if diff:
            self.warnings.append(f"metadata.yaml disagrees with {self.mcap.name}: {'; '.join(diff)}; "
                                 f"using {self.mcap.name}'s ({self.count} messages, {len(truth.topics)} topics)")
        if not self.complete and type(info.get("message_count")) is int:
            self.recovery += f" (metadata.yaml lists {info['message_count']} messages)"

    def _log_bounds(self) -> tuple[int | None, int | None]:
        if self._scan is not None:
            return self._scan.start_time, self._scan.end_time
        if not self._r.message_count:
            return None, None
        return int(self._r.start_time), int(self._r.end_time) - 1

    def close(self) -> None:
        if self._r is not None:
            self._r.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    @property
    def start_ns(self) -> int:
        """The first message's t_ns (its log time less the epoch)."""
        lo, _hi = self._log_bounds()
        return lo - self.epoch_ns if lo is not None else 0

    @property
    def end_ns(self) -> int:
        _lo, hi = self._log_bounds()
        return max(hi - self.epoch_ns, self.start_ns) if hi is not None else 0

    @property
    def count(self) -> int:
        return self._scan.message_count if self._scan is not None else int(self._r.message_count)

    def topics(self) -> list[TopicStats]:
        out: dict[tuple[str, str], int] = {}
        if self._scan is not None:
            sc = self._scan
            for cid, (topic, _sid, _enc) in sc.channels.items():
                key = (topic, sc.msgtype(cid))
                out[key] = out.get(key, 0) + sc.counts.get(cid, 0)
        else:
            for c in self._r.connections:
                out[(c.topic, c.msgtype)] = out.get((c.topic, c.msgtype), 0) + int(c.msgcount)
        return [TopicStats(t, m, n) for (t, m), n in sorted(out.items())]

    def offered_qos(self) -> dict[str, list[Qos]]:
        """Each topic's recorded ``offered_qos_profiles``, one list per topic: from the .mcap's
        channel metadata (rosbags reads them there; metadata.yaml holds a copy), or metadata.yaml
        for a folder read through rosbags. A recovered (cut) file gives none: the channels a scan
        keeps carry no metadata, so a replayer falls back to its default offer."""
        if self._r is None:
            return {t.topic: [] for t in self.topics()}
        out: dict[str, list[Qos]] = {}
        for c in self._r.connections:
            out.setdefault(c.topic, []).extend(getattr(c.ext, "offered_qos_profiles", None) or [])
        return out

    def messages(self, topics: Iterable[str] | None = None) -> Iterator[RawMessage]:
        """Raw CDR in log-time order; ``log_time_ns`` is t_ns (the log time less the epoch)."""
        if self._scan is not None:
            yield from self._recovered_messages(topics)
            return
        conns = self._r.connections
        if topics is not None:
            want = set(topics)
            conns = [c for c in conns if c.topic in want]
            if not conns:
                return
        off = self.epoch_ns
        try:
            for c, t, raw in self._r.messages(connections=conns):
                yield RawMessage(c.topic, c.msgtype, int(t) - off, bytes(raw))
        except UserError:
            raise
        except Exception as exc:  # noqa: BLE001 - a damaged file fails in many ways: one line for all
            raise UserError(f"bag {self.path}: unreadable: {_line(exc)}") from None

    def _recovered_messages(self, topics: Iterable[str] | None) -> Iterator[RawMessage]:
        sc = self._scan
        want = None if topics is None else set(topics)
        ids = [cid for cid, (t, _s, _e) in sc.channels.items() if want is None or t in want]
        off = self.epoch_ns
        try:
            for t, cid, data in iter_messages(sc, ids):
                topic, _sid, _enc = sc.channels[cid]
                yield RawMessage(topic, sc.msgtype(cid), t - off, data)
        except (OSError, ValueError) as exc:
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
