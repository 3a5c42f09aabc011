"""Housekeeping telemetry as CCSDS Space Packets (CCSDS 133.0-B-2, Space Packet Protocol).

Each Housekeeping message (msgs_json/schemas.py) becomes one telemetry packet: the 6-byte primary
header (section 4.1.3: version 0, type 0 = telemetry, no secondary header, the APID, sequence flags
3 = unsegmented, a per-APID 14-bit sequence count, data length = octets of the data field - 1) and
a data field of the channels of :data:`CHANNELS`, big-endian, in that order. One APID per satellite
and channel group: ``HK_APID_BASE`` + the satellite's index in the constellation (1-based) for the
housekeeping group.

Oracle: tests/system/test_operations_packets.py decodes the packets with ccsdspy (an independent
implementation of CCSDS 133.0-B-2) using only :data:`CHANNELS` and checks every value equals the
Housekeeping message it came from, headers included.
"""

from __future__ import annotations

import struct

__all__ = ["CHANNELS", "HK_APID_BASE", "encode_hk_packet", "hk_apid"]

HK_APID_BASE = 0x100
#: the housekeeping group's channels: (Housekeeping field, struct code, ccsdspy data type, bits, unit)
CHANNELS = (
    ("t_ns", "Q", "uint", 64, "ns"),
    ("mode", "B", "uint", 8, "0 NOMINAL, 1 DEGRADED, 2 SAFE"),
    ("pointing_error_deg", "d", "float", 64, "deg"),
    ("store_bundles", "I", "uint", 32, "bundles"),
    ("plan_version", "I", "uint", 32, ""),
    ("bundles_created", "I", "uint", 32, "bundles"),
    ("bundles_delivered", "I", "uint", 32, "bundles"),
    ("commands_accepted", "I", "uint", 32, "commands"),
    ("commands_rejected", "I", "uint", 32, "commands"),
)
_DATA = struct.Struct(">" + "".join(c[1] for c in CHANNELS))


def hk_apid(sat_index: int) -> int:
    """The housekeeping APID of the satellite at ``sat_index`` (0-based) in the constellation."""
    apid = HK_APID_BASE + sat_index + 1
    if not 0 < apid < 0x7FF:  # 0x7FF is the idle packet's APID
        raise ValueError(f"satellite index {sat_index}: no housekeeping APID left (11 bits)")
    return apid


def encode_hk_packet(msg, apid: int, seq: int) -> bytes:
    """One space packet of Housekeeping ``msg`` (module docstring); ``seq`` modulo 2**14."""
    data = _DATA.pack(*(getattr(msg, c[0]) for c in CHANNELS))
    word1 = (0 << 13) | (0 << 12) | (0 << 11) | apid  # version, type TM, no secondary header, APID
    word2 = (0b11 << 14) | (seq % 16384)
    return struct.pack(">HHH", word1, word2, len(data) - 1) + data
