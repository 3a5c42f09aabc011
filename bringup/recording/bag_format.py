"""What a project bag is made of, shared by its writer (bag.py) and its reader (bag_reader.py).

The type store (ROS 2 Jazzy message definitions, rosbags), the two message types the recorder
writes itself (std_msgs/msg/String carrying wire envelopes, rosgraph_msgs/msg/Clock), their CDR
bytes written by hand (OMG CDR little endian with the 4-byte encapsulation header, as rclpy
serializes them), the epoch entries of a bag's custom data, and the reader's record types.

Checked by tests/unit/test_recording.py (the hand-written CDR against rosbags' serializer, byte for
byte; the epoch entries in metadata.yaml).
"""

from __future__ import annotations

import struct
from datetime import UTC, datetime, timedelta
from typing import NamedTuple

from rosbags.typesys import Stores, get_typestore

# the String CDR is the wire form's (the ROS engine publishes and reads it raw too)
from msgs_json.wire import string_cdr, string_from_cdr

__all__ = ["CLOCK_TYPE", "LEADING_METADATA", "STRING", "TYPESTORE", "RawMessage", "TopicStats", "clock_cdr",
           "epoch_custom_data", "string_cdr", "string_from_cdr"]

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
STRING = "std_msgs/msg/String"
CLOCK_TYPE = "rosgraph_msgs/msg/Clock"
CDR_LE = b"\x00\x01\x00\x00"  # CDR little-endian encapsulation header
U32 = struct.Struct("<I")
_CLOCK = struct.Struct("<4siI")
LEADING_METADATA = "constellation"  # the MCAP Metadata record right after the header (epoch, custom data)


def clock_cdr(t_ns: int) -> bytes:
    """CDR of rosgraph_msgs/msg/Clock at ``t_ns`` (builtin_interfaces/Time sec, nanosec)."""
    sec, nsec = divmod(int(t_ns), 1_000_000_000)
    return _CLOCK.pack(CDR_LE, sec, nsec)


def epoch_custom_data(epoch_ns: int) -> dict[str, str]:
    """metadata.yaml custom_data entries that name a bag's epoch (empty for epoch 0)."""
    if not epoch_ns:
        return {}
    when = datetime(1970, 1, 1, tzinfo=UTC) + timedelta(microseconds=epoch_ns // 1000)
    stamp = when.strftime("%Y-%m-%dT%H:%M:%S") + (f".{epoch_ns % 1_000_000_000:09d}" if epoch_ns % 1_000_000_000 else "")
    return {"epoch_ns": str(epoch_ns), "epoch_utc": stamp + "Z",
            "time_base": "log/publish times and /clock: Unix ns (UTC) = epoch_ns + t_ns; envelope t_ns since epoch_ns"}


class RawMessage(NamedTuple):
    topic: str
    msgtype: str
    log_time_ns: int
    cdr: bytes


class TopicStats(NamedTuple):
    topic: str
    msgtype: str
    count: int
