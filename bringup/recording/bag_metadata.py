"""A bag's metadata.yaml checked against its ``.mcap`` file, which is the truth.

rosbag2 keeps a summary of a bag in ``metadata.yaml`` (format version 9: topics with their types
and message counts, total count, start time and duration, the storage files, ``custom_data``;
https://github.com/ros2/rosbag2 ``rosbag2_storage/src/rosbag2_storage/yaml.hpp``). The MCAP file
carries its own channels, statistics and messages, and that is what a reader gets; a metadata.yaml
from another run, edited by hand or left stale describes something else. :func:`disagreements`
compares the two and lists every difference in the file's numbers, so a reader warns with the
``.mcap``'s numbers instead of trusting the YAML (bringup/recording/bag.py BagReader).

How we know it is right: tests/unit/test_bag_recovery.py (a renamed topic, another bag's
metadata.yaml, counts multiplied by 10, a missing or unreadable metadata.yaml: each named, the
report and bag-info give the .mcap's numbers).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ruamel.yaml import YAML
from ruamel.yaml.error import YAMLError

from bringup.recording import metadata_yaml

__all__ = ["BagTruth", "disagreements", "read_metadata_yaml"]

_MAX_LISTED = 4  # differences named in the warning; the rest are counted


@dataclass(frozen=True)
class BagTruth:
    """What the ``.mcap`` holds: (topic, type) -> messages, total, log-time bounds, epoch, file name."""

    file_name: str
    topics: dict[tuple[str, str], int]
    message_count: int
    start_time: int | None  # log time (Unix ns) of the first message
    end_time: int | None
    epoch_ns: int | None  # from the file's own leading metadata record (None: the file has none)


def read_metadata_yaml(path: Path, *, fast: bool = True) -> tuple[dict | None, str | None]:
    """(the ``rosbag2_bagfile_information`` mapping, None) or (None, why it cannot be used).
    Read as ruamel.yaml's safe loader reads it (rosbags' reader): through libyaml where that gives
    the same (bringup/recording/metadata_yaml.py), ruamel itself with ``fast=False``."""
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        return None, "no metadata.yaml"
    except (OSError, UnicodeDecodeError) as exc:
        return None, f"metadata.yaml unreadable ({getattr(exc, 'strerror', None) or exc})"
    try:
        doc = metadata_yaml.load(text) if fast else YAML(typ="safe").load(text)
    except YAMLError as exc:
        return None, f"metadata.yaml is not YAML ({' '.join(str(exc).split())[:120]})"
    info = doc.get("rosbag2_bagfile_information") if isinstance(doc, dict) else None
    if not isinstance(info, dict):
        return None, "metadata.yaml has no rosbag2_bagfile_information mapping"
    return info, None


def _int(x) -> int | None:
    return x if type(x) is int else None


def disagreements(info: dict, truth: BagTruth, *, counts: bool = True) -> list[str]:
    """Every way ``info`` (metadata.yaml) differs from ``truth`` (the .mcap), one phrase each.
    ``counts=False``: compare only what a cut file cannot change (files, topic types, epoch)."""
    out: list[str] = []
    files = info.get("relative_file_paths")
    if isinstance(files, list) and files and truth.file_name not in [Path(str(f)).name for f in files]:
        out.append(f"it names the storage files {[str(f) for f in files][:3]}, not {truth.file_name}")
    yaml_topics: dict[tuple[str, str], int | None] = {}
    rows = info.get("topics_with_message_count")
    if not isinstance(rows, list):
        out.append("it has no topics_with_message_count list")
        rows = []
    for row in rows:
        tm = row.get("topic_metadata") if isinstance(row, dict) else None
        if not isinstance(tm, dict):
            out.append("a topic entry without topic_metadata")
            continue
        key = (str(tm.get("name")), str(tm.get("type")))
        yaml_topics[key] = _int(row.get("message_count"))
    only_yaml = sorted(set(yaml_topics) - set(truth.topics))
    only_mcap = sorted(set(truth.topics) - set(yaml_topics))
    for t, m in only_yaml[:_MAX_LISTED]:
        out.append(f"topic {t} ({m}) is not in {truth.file_name}")
    for t, m in only_mcap[:_MAX_LISTED]:
        out.append(f"topic {t} ({m}) of {truth.file_name} is not listed")
    hidden = max(0, len(only_yaml) - _MAX_LISTED) + max(0, len(only_mcap) - _MAX_LISTED)
    if hidden:
        out.append(f"{hidden} more topics differ")
    if counts:
        wrong = [(k, n) for k, n in sorted(yaml_topics.items()) if k in truth.topics and n != truth.topics[k]]
        for (t, _m), n in wrong[:_MAX_LISTED]:
            out.append(f"{t}: {n} messages ({truth.file_name}: {truth.topics[(t, _m)]})")
        if len(wrong) > _MAX_LISTED:
            out.append(f"{len(wrong) - _MAX_LISTED} more topic counts differ")
        n = _int(info.get("message_count"))
        if n != truth.message_count:
            out.append(f"message_count {info.get('message_count')!r} ({truth.file_name}: {truth.message_count})")
        if truth.message_count:
            start = _int((info.get("starting_time") or {}).get("nanoseconds_since_epoch")
                         if isinstance(info.get("starting_time"), dict) else None)
            dur = _int((info.get("duration") or {}).get("nanoseconds")
                       if isinstance(info.get("duration"), dict) else None)
            if start != truth.start_time:
                out.append(f"starting_time {start} ns ({truth.file_name}: {truth.start_time})")
            elif dur is None or start + dur != truth.end_time:
                out.append(f"duration {dur} ns ({truth.file_name}: {truth.end_time - truth.start_time})")
    custom = info.get("custom_data")
    if (truth.epoch_ns is not None and isinstance(custom, dict) and "epoch_ns" in custom
            and str(custom.get("epoch_ns")) != str(truth.epoch_ns)):
        out.append(f"custom_data epoch_ns {custom.get('epoch_ns')!r} ({truth.file_name}: {truth.epoch_ns})")
    return out
