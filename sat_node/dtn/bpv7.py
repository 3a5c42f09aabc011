"""Bundle Protocol version 7 (RFC 9171): CBOR encoding and decoding of bundles, with CRCs.

What is here:
* primary block (RFC 9171 4.3.1) with ipn EIDs (4.2.5.1.2) or a group EID of ION's ``imc`` scheme
  (code 3, SSP ``[group, service]``: :class:`Imc`), creation timestamp (DTN time in ms since
  2000-01-01T00:00:00Z, and a sequence number), lifetime in ms, CRC-16 (X.25) or CRC-32C;
* canonical blocks (4.3.2): payload (type 1, block number 1, last), previous node (type 6), bundle
  age (type 7), hop count (type 10). Blocks of any other type (BPSec's BIB, the routing blocks of
  sat_node/dtn/routing_blocks.py) are kept as :class:`CanonicalBlock` and re-encoded unchanged, as
  RFC 9171 4.3.2 asks of a node that does not know them.
* :func:`decode_bundle` rejects malformed bytes with a :class:`BundleError` naming the reason
  (never another exception type), so an agent can drop and count them.

* EIDs of the ``dtn`` scheme (4.2.5.1.1): dtn:none and ``dtn://node/demux`` (:class:`Dtn`), encoded
  [1, 0] and [1, "//node/demux"], decoded with the node name and demux checked (RFC 3986 characters).

Not done: fragmentation (decoded and kept, never created), status reports.

Why one module: the codec is one grammar (RFC 9171 section 4 CDDL): the block encoders, the decoder
with its fast path and the CRCs share the CBOR helpers and the encoding caches, and each half is
tested against the other (decode(encode(b)) == b); split, the halves would import each other.

How we know it is right: exact-bytes golden encodings of small bundles written out by hand from
the RFC's CDDL (tests/unit/test_bpv7.py), CRC check values of the standard catalogue ("123456789"
-> CRC-16/X-25 0x906E, CRC-32C 0xE3069283), decode(encode(b)) == b on random bundles (hypothesis),
every one-byte corruption of the primary block detected, and the RFC 9173 A.1 bundle (whose
primary block is given in the RFC) decoding. Speed paths: :func:`decode_bundle`'s fast
path for the common shape and the encoding caches give exactly what the plain paths give
(tests/unit/test_speed_paths.py: fast vs plain decode on random bundles of every shape and on
random corruptions of them, cached vs fresh encodings, bytes a sender noted with
:func:`remember_sent` vs their plain decode), and every encoding - CBOR written by
sat_node/dtn/cbor_enc.py, the primary block item by item, blocks shared and memoised - equals, byte
for byte, that of a plain encoder written with cbor2 alone from the RFC's CDDL, on random bundles and
on forwarding agents' transmissions (tests/unit/test_wire_same_bytes.py).
"""

from __future__ import annotations

import binascii
import io
import re
from dataclasses import dataclass, field, replace
from datetime import datetime, timezone
from typing import NamedTuple

import cbor2

from .cbor_enc import dumps as _dumps

__all__ = [
    "Bundle", "CanonicalBlock", "encode_primary", "BundleError", "decode_bundle", "encode_bundle", "crc16_x25", "crc32c",
    "PAYLOAD_BLOCK", "PREVIOUS_NODE_BLOCK", "BUNDLE_AGE_BLOCK", "HOP_COUNT_BLOCK", "Imc", "IMC_SCHEME",
    "BIB_BLOCK", "Dtn", "dtn_eid", "eid_text", "CRC_NONE", "CRC_16", "CRC_32C", "dtn_time_ms", "dtn_ms_of", "PAPER_EPOCH_DTN_MS", "ipn",
]

PAYLOAD_BLOCK = 1
PREVIOUS_NODE_BLOCK = 6
BUNDLE_AGE_BLOCK = 7
HOP_COUNT_BLOCK = 10
BIB_BLOCK = 11
IMC_SCHEME = 3  # ION's code for the imc URI scheme (bp.h SchemeCodeNbr)
CRC_NONE, CRC_16, CRC_32C = 0, 1, 2

_DTN_EPOCH = datetime(2000, 1, 1, tzinfo=timezone.utc)
# The study's scenario epoch 2000-01-01T11:59:28Z in DTN time [ms].
PAPER_EPOCH_DTN_MS = int((datetime(2000, 1, 1, 11, 59, 28, tzinfo=timezone.utc) - _DTN_EPOCH).total_seconds() * 1000)


def dtn_ms_of(instant: datetime) -> int:
    """DTN time [ms since 2000-01-01T00:00:00Z, RFC 9171 4.2.6] of a timezone-aware instant, exactly."""
    if instant.tzinfo is None:
        raise ValueError("dtn_ms_of: the instant must be timezone-aware (UTC)")
    d = instant - _DTN_EPOCH
    ms = (d.days * 86_400 + d.seconds) * 1000 + d.microseconds // 1000
    if ms < 0:
        raise ValueError(f"{instant.isoformat()}: before the DTN epoch 2000-01-01T00:00:00Z")
    return ms


def dtn_time_ms(t_ns: int, epoch_dtn_ms: int) -> int:
    """DTN time [ms since 2000-01-01T00:00:00Z] of ``t_ns`` [ns since the scenario epoch]."""
    return epoch_dtn_ms + t_ns // 1_000_000


class BundleError(ValueError):
    """Malformed bundle bytes or fields; the message says what is wrong."""


# --- CRCs (RFC 9171 4.2.1: CRC-16 X.25 and CRC-32C, CRC field zeroed while computing) -----------

def _table(poly: int, width: int) -> list[int]:
    out = []
    for i in range(256):
        c = i
        for _ in range(8):
            c = (c >> 1) ^ poly if c & 1 else c >> 1
        out.append(c & ((1 << width) - 1))
    return out


_T16 = _table(0x8408, 16)
_T32C = _table(0x82F63B78, 32)


_REV8 = bytes(int(f"{i:08b}"[::-1], 2) for i in range(256))  # each byte's bits reversed


def crc16_x25(data: bytes) -> int:
    """CRC-16/X-25 (reflected 0x1021, init and xorout 0xFFFF; check value 0x906E). Computed with
    the C CRC-CCITT of binascii (the same polynomial, not reflected) on the bit-reversed bytes,
    then the 16-bit result reversed: ~50x faster than the table loop (:func:`_crc16_x25_table`,
    kept as the reference the tests compare against)."""
    c = binascii.crc_hqx(bytes(data).translate(_REV8), 0xFFFF)
    return ((_REV8[c & 0xFF] << 8) | _REV8[c >> 8]) ^ 0xFFFF


def _crc16_x25_table(data: bytes) -> int:
    crc = 0xFFFF
    t = _T16
    for b in data:
        crc = (crc >> 8) ^ t[(crc ^ b) & 0xFF]
    return crc ^ 0xFFFF


def crc32c(data: bytes) -> int:
    crc = 0xFFFFFFFF
    t = _T32C
    for b in data:
        crc = (crc >> 8) ^ t[(crc ^ b) & 0xFF]
    return crc ^ 0xFFFFFFFF


_CRC_LEN = {CRC_NONE: 0, CRC_16: 2, CRC_32C: 4}
_ZERO_CRC = {2: b"\x42\0\0", 4: b"\x44\0\0\0\0"}  # the CRC field, zeroed, as a CBOR byte string


def _crc_bytes(crc_type: int, encoded_with_zero_crc: bytes) -> bytes:
    if crc_type == CRC_16:
        return crc16_x25(encoded_with_zero_crc).to_bytes(2, "big")
    return crc32c(encoded_with_zero_crc).to_bytes(4, "big")


def _encode_with_crc(items: list, crc_type: int) -> bytes:
    if crc_type == CRC_NONE:
        return _dumps(items)
    n = _CRC_LEN[crc_type]
    raw = _dumps(items + [bytes(n)])
    return raw[:-n] + _crc_bytes(crc_type, raw)


def _check_crc(raw: bytes, crc_type: int, what: str) -> None:
    n = _CRC_LEN[crc_type]
    if crc_type == CRC_NONE:
        return
    got = raw[-n:]
    if _crc_bytes(crc_type, raw[:-n] + bytes(n)) != got:
        raise BundleError(f"{what}: CRC mismatch")


# --- EIDs ------------------------------------------------------------------------------------------

def ipn(node: int, service: int = 0) -> tuple[int, int]:
    """An ipn EID as (node number, service number)."""
    return (int(node), int(service))


DTN_NONE = (0, 0)  # encoded as [1, 0]


class Imc(NamedTuple):
    """A group EID of ION's ``imc`` scheme: ``imc:group.service``, encoded [3, [group, service]]
    (ION libbpP.c serializeEid). Never equal to the ipn EID with the same two numbers."""

    group: int
    service: int

    def __eq__(self, other) -> bool:
        return type(other) is Imc and tuple.__eq__(self, other)

    def __ne__(self, other) -> bool:
        return not self.__eq__(other)

    def __hash__(self) -> int:
        return hash(("imc", self.group, self.service))


class Dtn(NamedTuple):
    """A ``dtn`` scheme EID other than dtn:none (RFC 9171 4.2.5.1.1): ``dtn://node/demux``, encoded
    [1, "//node/demux"] (scheme code 1, the SSP as a text string). ``node`` is the node name (no
    "/"), ``demux`` the rest (may be empty or hold "/"). Never equal to an ipn or imc EID."""

    node: str
    demux: str

    def __eq__(self, other) -> bool:
        return type(other) is Dtn and tuple.__eq__(self, other)

    def __ne__(self, other) -> bool:
        return not self.__eq__(other)

    def __hash__(self) -> int:
        return hash(("dtn", self.node, self.demux))

    def __str__(self) -> str:
        return f"dtn://{self.node}/{self.demux}"


_DTN_NODE = re.compile(r"[A-Za-z0-9\-._~!$&'()*+,;=%]+")  # RFC 3986 reg-name characters
_DTN_DEMUX = re.compile(r"[A-Za-z0-9\-._~!$&'()*+,;=%:@/]*")  # path characters


def dtn_eid(text: str) -> Dtn:
    """``dtn://node/demux`` (RFC 9171 4.2.5.1.1) as a :class:`Dtn`; ValueError naming the defect."""
    if not text.startswith("dtn://"):
        raise ValueError(f"{text!r}: a dtn EID is dtn://node/demux (or dtn:none)")
    node, sep, demux = text[6:].partition("/")
    if not sep or not _DTN_NODE.fullmatch(node) or not _DTN_DEMUX.fullmatch(demux):
        raise ValueError(f"{text!r}: a dtn EID is dtn://node/demux with RFC 3986 characters")
    return Dtn(node, demux)


def eid_text(eid) -> str:
    """An EID as a URI: ipn:N.S, imc:G.S, dtn://node/demux, dtn:none."""
    if eid is None or eid == DTN_NONE:
        return "dtn:none"
    if type(eid) is Dtn:
        return str(eid)
    return f"{'imc' if type(eid) is Imc else 'ipn'}:{eid[0]}.{eid[1]}"


def _eid_cbor(eid: tuple[int, int] | None) -> list:
    if eid is None or eid == DTN_NONE:
        return [1, 0]
    if type(eid) is Imc:
        return [IMC_SCHEME, [eid[0], eid[1]]]
    if type(eid) is Dtn:
        return [1, f"//{eid.node}/{eid.demux}"]
    return [2, [eid[0], eid[1]]]


def _eid_from(obj, what: str) -> tuple[int, int]:
    if isinstance(obj, list) and len(obj) == 2:
        if obj[0] == 1 and obj[1] == 0:
            return DTN_NONE
        if obj[0] == 1 and type(obj[0]) is int and isinstance(obj[1], str):
            try:
                return dtn_eid("dtn:" + obj[1])
            except ValueError as exc:
                raise BundleError(f"{what}: {exc}") from None
        if obj[0] in (2, IMC_SCHEME) and type(obj[0]) is int and isinstance(obj[1], list) and len(obj[1]) == 2 \
                and all(isinstance(x, int) and not isinstance(x, bool) and x >= 0 for x in obj[1]):
            return (obj[1][0], obj[1][1]) if obj[0] == 2 else Imc(obj[1][0], obj[1][1])
    raise BundleError(f"{what}: not an ipn or imc EID, nor a dtn one: {obj!r}")


# --- blocks ----------------------------------------------------------------------------------------

@dataclass(frozen=True)
class CanonicalBlock:
    """A canonical block as on the wire; ``data`` is the block-type-specific data (bytes)."""

    type: int
    number: int
    flags: int = 0
    crc_type: int = CRC_NONE
    data: bytes = b""
    # its encoding, made once (the block is immutable; dataclasses.replace does not copy it)
    _raw: bytes | None = field(default=None, init=False, compare=False, repr=False)

    def encode(self) -> bytes:
        raw = self._raw
        if raw is None:
            t, n, f, c, d = self.type, self.number, self.flags, self.crc_type, self.data
            if type(t) is int and type(n) is int and type(f) is int and c == 0 and type(c) is int \
                    and type(d) is bytes:  # plain fields without CRC: the encoding depends on them only
                key = (t, n, f, d)
                raw = _BLOCK_RAW.get(key)
                if raw is None:
                    raw = _dumps([t, n, f, c, d])
                    if len(_BLOCK_RAW) >= 8192:
                        _BLOCK_RAW.clear()
                    _BLOCK_RAW[key] = raw
            else:
                raw = _encode_with_crc([t, n, f, c, d], c)
            object.__setattr__(self, "_raw", raw)
        return raw


# (type, number, flags, data) of a CRC-less block -> its encoding: a bundle's blocks are encoded again
# at every hop (and most blocks - priority, BIB, previous node, next hop - take few distinct values)
_BLOCK_RAW: dict = {}


_new_block = object.__new__


def _block(btype: int, num: int, flags: int, crc_type: int, data: bytes) -> CanonicalBlock:
    """``CanonicalBlock(btype, num, flags, crc_type, data)`` without the frozen dataclass's per-field
    ``object.__setattr__`` (same instance state; decode makes ~6 per received bundle)."""
    blk = _new_block(CanonicalBlock)
    blk.__dict__.update(type=btype, number=num, flags=flags, crc_type=crc_type, data=data, _raw=None)
    return blk


def _shared_block(btype: int, num: int, flags: int, crc_type: int, data: bytes) -> CanonicalBlock:
    """``CanonicalBlock(btype, num, flags, crc_type, data)``: for plain int fields and bytes data one
    instance per distinct block, shared by the bundles that carry it (a block is immutable; its
    encoding is then made once). The extension blocks a node writes at each hop (previous node, hop
    count, next hops) take a few hundred distinct values in a run."""
    if type(btype) is int and type(num) is int and type(flags) is int and type(crc_type) is int \
            and type(data) is bytes and len(data) <= 64:
        key = (btype, num, flags, crc_type, data)
        blk = _SHARED_BLOCKS.get(key)
        if blk is None:
            blk = _block(btype, num, flags, crc_type, data)
            if len(_SHARED_BLOCKS) >= 8192:
                _SHARED_BLOCKS.clear()
            _SHARED_BLOCKS[key] = blk
        return blk
    return CanonicalBlock(btype, num, flags, crc_type, data)


_SHARED_BLOCKS: dict = {}


@dataclass
class Bundle:
    """One bundle: primary block fields plus canonical blocks (payload last)."""

    dest: tuple[int, int]
    src: tuple[int, int]
    creation_ms: int  # DTN time [ms]
    seq: int
    lifetime_ms: int
    payload: bytes = b""
    report_to: tuple[int, int] | None = None
    flags: int = 0
    crc_type: int = CRC_16
    fragment: tuple[int, int] | None = None  # (offset, total ADU length) when a fragment
    blocks: list[CanonicalBlock] = field(default_factory=list)  # every block except the payload
    payload_crc_type: int = CRC_NONE
    payload_flags: int = 0
    # the primary block's bytes as received (decode_bundle sets it; BPSec's IPPT reads it)
    primary_raw: bytes | None = field(default=None, compare=False, repr=False)
    # encodings already made, keyed by every field they depend on (a changed field is a new key):
    # a bundle is encoded several times on its way (BIB, store, each transmission)
    _enc: dict = field(default_factory=dict, init=False, compare=False, repr=False)

    # -- identity
    @property
    def bundle_id(self) -> str:
        """Source node, creation time and sequence number (RFC 9171 4.2.3 names a bundle by these)."""
        if type(self.src) is Dtn:
            return f"dtn//{self.src.node}/{self.src.demux}-{self.creation_ms}-{self.seq}"
        return f"ipn{self.src[0]}.{self.src[1]}-{self.creation_ms}-{self.seq}"

    @property
    def expiry_ms(self) -> int:
        return self.creation_ms + self.lifetime_ms

    # -- extension block helpers
    def block(self, btype: int) -> CanonicalBlock | None:
        for b in self.blocks:
            if b.type == btype:
                return b
        return None

    def set_block(self, btype: int, data: bytes, flags: int = 0, crc_type: int = CRC_NONE) -> None:
        for i, b in enumerate(self.blocks):
            if b.type == btype:
                if b.data == data and type(b.data) is type(data) and b.flags == flags and type(b.flags) is type(flags) \
                        and b.crc_type == crc_type and type(b.crc_type) is type(crc_type):
                    return  # the same block already (kept: its encoding is made)
                self.blocks[i] = _shared_block(b.type, b.number, flags, crc_type, data)  # = replace(b, ...)
                return
        used = {b.number for b in self.blocks} | {1}
        num = 2
        while num in used:
            num += 1
        self.blocks.append(_shared_block(btype, num, flags, crc_type, data))

    @property
    def previous_node(self) -> tuple[int, int] | None:
        b = self.block(PREVIOUS_NODE_BLOCK)
        if b is None:
            return None
        eid = _EID_OF.get(b.data)
        return eid if eid is not None else _eid_from(_loads(b.data, "previous-node block"), "previous-node block")

    @previous_node.setter
    def previous_node(self, eid: tuple[int, int]) -> None:
        self.set_block(PREVIOUS_NODE_BLOCK, _eid_bytes(eid))

    @property
    def hop_count(self) -> tuple[int, int] | None:
        """(hop limit, hop count) or None."""
        b = self.block(HOP_COUNT_BLOCK)
        if b is None:
            return None
        hc = _HOP_OF.get(b.data)
        if hc is not None:
            return hc
        v = _loads(b.data, "hop-count block")
        if not (isinstance(v, list) and len(v) == 2 and all(isinstance(x, int) and x >= 0 for x in v)):
            raise BundleError(f"hop-count block: not [limit, count]: {v!r}")
        return (v[0], v[1])

    @hop_count.setter
    def hop_count(self, limit_count: tuple[int, int]) -> None:
        self.set_block(HOP_COUNT_BLOCK, _hop_bytes(limit_count))

    @property
    def age_ms(self) -> int | None:
        b = self.block(BUNDLE_AGE_BLOCK)
        if b is None:
            return None
        v = _loads(b.data, "bundle-age block")
        if not isinstance(v, int) or v < 0:
            raise BundleError(f"bundle-age block: not an unsigned integer: {v!r}")
        return v

    @age_ms.setter
    def age_ms(self, ms: int) -> None:
        self.set_block(BUNDLE_AGE_BLOCK, _dumps(int(ms)))

    def copy(self) -> "Bundle":
        return replace(self, blocks=list(self.blocks))


# Known extension blocks' data bytes -> the value their getter parses from them (a handful of distinct
# values per run; filled only with the encoder's own output for plain ints, so a hit returns exactly
# what parsing would).
_EID_OF: dict[bytes, tuple[int, int]] = {}
_EID_BYTES: dict[tuple[int, int], bytes] = {}
_HOP_OF: dict[bytes, tuple[int, int]] = {}
_HOP_BYTES: dict[tuple[int, int], bytes] = {}


def _pair_bytes(pair, cbor_of, made: dict, parsed: dict) -> bytes:
    """``cbor2.dumps(cbor_of(pair))``, made once per pair of plain non-negative ints (and remembered
    both ways: ``made[pair]`` -> bytes, ``parsed[bytes]`` -> pair)."""
    if type(pair) is tuple and len(pair) == 2:
        a, b = pair
        if type(a) is int and type(b) is int and a >= 0 and b >= 0:
            data = made.get(pair)
            if data is None:
                data = _dumps(cbor_of(pair))
                if len(made) < 4096:
                    made[pair] = data
                    parsed[data] = pair
            return data
    return _dumps(cbor_of(pair))


def _eid_bytes(eid) -> bytes:
    """``cbor2.dumps(_eid_cbor(eid))``."""
    return _pair_bytes(eid, _eid_cbor, _EID_BYTES, _EID_OF)


def _hop_bytes(limit_count) -> bytes:
    """``cbor2.dumps(list(limit_count))``."""
    return _pair_bytes(limit_count, list, _HOP_BYTES, _HOP_OF)


def _loads(data: bytes, what: str):
    try:
        return cbor2.loads(data)
    except Exception as exc:  # cbor2 raises several types on garbage
        raise BundleError(f"{what}: bad CBOR: {exc}") from None


def encode_primary(b: Bundle) -> bytes:
    """The primary block's bytes (CRC filled); as received when the bundle was decoded (the
    primary block is immutable in transit, RFC 9171 4.3.1)."""
    if b.primary_raw is not None:
        return b.primary_raw
    key = ("primary", b.flags, b.crc_type, b.dest, b.src, b.report_to, b.creation_ms, b.seq, b.lifetime_ms,
           b.fragment)
    raw = b._enc.get(key)
    if raw is None:
        raw = _encode_primary(b)
        if len(b._enc) > 8:
            b._enc.clear()
        b._enc[key] = raw
    return raw


def _encode_primary(b: Bundle) -> bytes:
    if b.fragment is None and b.crc_type in (CRC_16, CRC_32C):
        # the 9-item array written item by item (a definite array's encoding is its head and its
        # items' encodings, RFC 8949 3.2.1): the EIDs' encodings are made once per EID
        n = _CRC_LEN[b.crc_type]
        raw = b"".join((b"\x89\x07", _dumps(b.flags), _dumps(b.crc_type), _eid_bytes(b.dest), _eid_bytes(b.src),
                        _eid_bytes(b.report_to or b.src), b"\x82", _dumps(b.creation_ms), _dumps(b.seq),
                        _dumps(b.lifetime_ms), _ZERO_CRC[n]))
        raw = raw[:-n] + _crc_bytes(b.crc_type, raw)
    else:
        prim = [7, b.flags, b.crc_type, _eid_cbor(b.dest), _eid_cbor(b.src), _eid_cbor(b.report_to or b.src),
                [b.creation_ms, b.seq], b.lifetime_ms]
        if b.fragment is not None:
            prim += [b.fragment[0], b.fragment[1]]
        raw = _encode_with_crc(prim, b.crc_type)
    if b.fragment is None and b.crc_type in (CRC_16, CRC_32C):
        rpt = b.report_to or b.src
        _remember_primary((b.flags, b.crc_type, _ipn_key(b.dest), _ipn_key(b.src), _ipn_key(rpt), b.creation_ms,
                           b.seq, b.lifetime_ms, raw[-_CRC_LEN[b.crc_type]:]), raw)
    return raw


def _ipn_key(eid) -> tuple[int, int]:
    """What :func:`_ipn_fast` reads back from ``_eid_cbor(eid)``."""
    if type(eid) is Imc:
        return eid
    return DTN_NONE if eid is None or eid == DTN_NONE else (eid[0], eid[1])


# (payload flags, CRC type, payload) -> the payload block's encoding
_PAYLOAD_RAW: dict = {}


def encode_bundle(b: Bundle) -> bytes:
    """RFC 9171 bundle bytes: indefinite array of primary, extension blocks, payload; CRCs filled."""
    if b.creation_ms == 0 and b.block(BUNDLE_AGE_BLOCK) is None:
        raise BundleError("a bundle without a creation time needs a bundle-age block (RFC 9171 4.2.6)")
    parts = [b"\x9f", encode_primary(b)]
    parts += [blk.encode() for blk in b.blocks]
    flags, crc, payload = b.payload_flags, b.payload_crc_type, b.payload
    if type(flags) is int and type(crc) is int and type(payload) is bytes:
        # the payload block of a bundle is the same at every hop (made once per process, not per
        # Bundle object: each hop's node has its own); plain fields only (True == 1 as a key)
        key = (flags, crc, payload)
        raw = _PAYLOAD_RAW.get(key)
        if raw is None:  # (what CanonicalBlock.encode writes, without filling its memo of small blocks)
            items = [PAYLOAD_BLOCK, 1, flags, crc, payload]
            raw = _dumps(items) if crc == 0 else _encode_with_crc(items, crc)
            if len(_PAYLOAD_RAW) >= 1 << 16:
                _PAYLOAD_RAW.clear()
            _PAYLOAD_RAW[key] = raw
    else:
        raw = CanonicalBlock(PAYLOAD_BLOCK, 1, flags, crc, payload).encode()
    parts.append(raw)
    parts.append(b"\xff")
    return b"".join(parts)


def _uint(x, what: str) -> int:
    if not isinstance(x, int) or isinstance(x, bool) or x < 0:
        raise BundleError(f"{what}: not an unsigned integer: {x!r}")
    return x


def _split_blocks(data: bytes) -> list[tuple[object, bytes]]:
    """(item, raw bytes) per block. Fast path: one C-level decode, then re-encode and compare (true
    for every shortest-form encoder, ours included); otherwise walk the items one by one."""
    try:
        items = cbor2.loads(data)
    except Exception as exc:  # cbor2 raises several types on garbage
        raise BundleError(f"bad CBOR: {exc}") from None
    if isinstance(items, list) and items:
        # raw bytes are needed only for the CRC checks and the primary block (BPSec's IPPT reads
        # it): re-encode and compare with the input (true for every shortest-form encoder, ours too).
        try:
            no_crc = all(isinstance(x, list) and len(x) == 5 and x[3] == 0 for x in items[1:])
            pieces = []
            pos = 1
            for x in (items[:1] if no_crc else items):
                enc = _dumps(x)
                if data[pos:pos + len(enc)] != enc:
                    raise ValueError("not shortest form")
                pieces.append(enc)
                pos += len(enc)
            if no_crc:
                pieces += [b""] * (len(items) - 1)
            elif pos != len(data) - 1:
                raise ValueError("length")
            return list(zip(items, pieces))
        except Exception:
            pass
    fp = io.BytesIO(data)
    fp.read(1)
    dec = cbor2.CBORDecoder(fp)
    raws: list[tuple[object, bytes]] = []
    while fp.tell() < len(data) - 1:
        start = fp.tell()
        try:
            item = dec.decode()
        except Exception as exc:
            raise BundleError(f"block at byte {start}: bad CBOR: {exc}") from None
        raws.append((item, data[start:fp.tell()]))
    if fp.tell() != len(data) - 1:
        raise BundleError("trailing bytes after the last block")
    return raws


def decode_bundle(data: bytes) -> Bundle:
    """Parse and check bundle bytes; any defect raises :class:`BundleError` with the reason.

    The common shape (CRC on the primary block only, no fragment, every field a plain CBOR int or
    byte string) takes :func:`_decode_fast`; whatever it does not vouch for goes through the plain
    checks of :func:`_decode_plain`, which give the reason of any defect."""
    if type(data) is bytes:
        sent = _SENT.get(data)
        if sent is not None:  # bytes this process encoded and remembered (remember_sent)
            fields, blocks = sent
            b = _new_bundle(Bundle)
            b.__dict__.update(fields, blocks=list(blocks), _enc={_SENT_FIELDS: fields})
            return b
        b = _decode_fast(data)
        if b is not None:
            return b
    return _decode_plain(data)


def _decoded_eid(eid):
    """What the decoder reads back from ``_eid_cbor(eid)`` (None: not the fast path's kind)."""
    key = None
    if (type(eid) is tuple or type(eid) is Imc) and len(eid) == 2 and type(eid[0]) is int and type(eid[1]) is int:
        key = (type(eid) is Imc, eid[0], eid[1])  # (an Imc equals the tuple of its numbers: told apart here)
        got = _EID_DECODED.get(key)
        if got is not None:
            return got
    got = _ipn_fast(_eid_cbor(eid))
    if got is not None and key is not None and len(_EID_DECODED) < 4096:
        _EID_DECODED[key] = got
    return got


_EID_DECODED: dict = {}


# bundle bytes this process encoded for a transmission -> the Bundle that decoding them gives, as
# (fields, blocks): the copy is usually decoded by a node of the same process (a DTN-alone or local
# run: the next hop), which then builds that Bundle without parsing. A pure function of the bytes,
# like the caches below; kept only for the shape _decode_fast accepts (remember_sent), where the
# Bundle is a function of the sender's fields alone (tests/unit/test_speed_paths.py compares it
# with the plain decode of the same bytes on random bundles).
_SENT: dict = {}


def remember_sent(data: bytes, b: Bundle) -> None:
    """Note that ``data`` is ``encode_bundle(b)`` (just made), so that :func:`decode_bundle` of those
    bytes returns what parsing them would, without parsing. Bundles not of the common shape (a
    fragment, block CRCs, a non-ipn EID, a creation time of 0, a known extension block twice or
    unparsable) are not noted (their bytes are parsed)."""
    if type(data) is not bytes:
        return
    d = b.__dict__
    fields = d["_enc"].get(_SENT_FIELDS)  # ``b`` came from noted bytes: the fields noted with them, if
    if fields is None or not all(d[k] is v for k, v in fields.items()):  # every one is still that object
        fields = _sent_fields(b)
        if fields is None:
            return
    numbers = {1}
    known = set()
    for blk in b.blocks:
        t = blk.type
        if blk.crc_type != CRC_NONE or type(blk.data) is not bytes or type(t) is not int or t < 0 \
                or t == PAYLOAD_BLOCK or type(blk.number) is not int or blk.number <= 0 or blk.number in numbers \
                or type(blk.flags) is not int or blk.flags < 0:
            return
        numbers.add(blk.number)
        if t in _EXT_KNOWN:  # a known extension block: one of each, with data already seen to parse
            if t in known or (t, blk.data) not in _EXT_OK:
                return
            known.add(t)
    if len(_SENT) >= 4096:
        _SENT.clear()
    _SENT[data] = (fields, tuple(b.blocks))


_SENT_FIELDS = "_sent_fields"  # the Bundle._enc key of the fields a decoded Bundle was made from (_SENT)


def _sent_fields(b: Bundle) -> dict | None:
    """The fields ``decode_bundle(encode_bundle(b))`` has besides its blocks, for the common shape
    (:func:`remember_sent`); None for any other."""
    if b.fragment is not None or type(b.flags) is not int or b.flags < 0 or b.flags & 1 \
            or b.crc_type not in (CRC_16, CRC_32C) or b.payload_crc_type != CRC_NONE \
            or type(b.payload) is not bytes or type(b.payload_flags) is not int or b.payload_flags < 0 \
            or type(b.creation_ms) is not int or b.creation_ms <= 0 or type(b.seq) is not int or b.seq < 0 \
            or type(b.lifetime_ms) is not int or b.lifetime_ms < 0:
        return None
    dest, src, rpt = _decoded_eid(b.dest), _decoded_eid(b.src), _decoded_eid(b.report_to or b.src)
    if dest is None or src is None or rpt is None:
        return None
    return {"dest": dest, "src": src, "creation_ms": b.creation_ms, "seq": b.seq, "lifetime_ms": b.lifetime_ms,
            "payload": b.payload, "report_to": rpt, "flags": b.flags, "crc_type": b.crc_type, "fragment": None,
            "payload_crc_type": CRC_NONE, "payload_flags": b.payload_flags, "primary_raw": encode_primary(b)}


# (block type, block-type-specific data) of known extension blocks whose data parsed (a handful of
# distinct values in a run: the 24 previous-node and next-hop EIDs, hop counts 0..limit)
_EXT_OK: set = set()
_EXT_KNOWN = frozenset((PREVIOUS_NODE_BLOCK, HOP_COUNT_BLOCK, BUNDLE_AGE_BLOCK))
_new_bundle = object.__new__
_CHECK = {CRC_16: lambda raw: crc16_x25(raw[:-2] + b"\0\0").to_bytes(2, "big") == raw[-2:],
          CRC_32C: lambda raw: crc32c(raw[:-4] + b"\0\0\0\0").to_bytes(4, "big") == raw[-4:]}


def _ipn_fast(e):
    """(node, service) of a well-formed ipn EID item, :class:`Imc` of an imc one, DTN_NONE for
    [1, 0], else None (then the plain path decides)."""
    if type(e) is list and len(e) == 2:
        s, v = e
        if type(s) is int:
            if (s == 2 or s == IMC_SCHEME) and type(v) is list and len(v) == 2:
                n, x = v
                if type(n) is int and type(x) is int and n >= 0 and x >= 0:
                    return (n, x) if s == 2 else Imc(n, x)
            elif s == 1 and type(v) is int and v == 0:
                return DTN_NONE
    return None


def _decode_fast(data: bytes) -> Bundle | None:
    """The bundle :func:`_decode_plain` would return for ``data``, or None when ``data`` is not of
    the common shape (then the plain path decides, errors included). It accepts a subset of what
    the plain path accepts, and builds the same Bundle (tests/unit/test_speed_paths.py compares the
    two on random bundles and on every one-byte corruption)."""
    if len(data) < 3 or data[0] != 0x9F or data[-1] != 0xFF:
        return None
    try:
        items = cbor2.loads(data)
    except Exception:
        return None
    if type(items) is not list or len(items) < 2:
        return None
    prim = items[0]
    if type(prim) is not list or len(prim) != 9:
        return None
    v, flags, crc_type, dest, src, rpt, ts, life, crc = prim
    if not (v == 7 and type(v) is int and type(flags) is int and flags >= 0 and not flags & 1
            and type(crc_type) is int and (crc_type == CRC_16 or crc_type == CRC_32C) and type(crc) is bytes
            and len(crc) == _CRC_LEN[crc_type] and type(ts) is list and len(ts) == 2 and type(life) is int
            and life >= 0):
        return None
    cms, seq = ts
    if not (type(cms) is int and type(seq) is int and cms >= 0 and seq >= 0):
        return None
    dest, src, rpt = _ipn_fast(dest), _ipn_fast(src), _ipn_fast(rpt)
    if dest is None or src is None or rpt is None:
        return None
    # blocks without CRCs (the plain path's _split_blocks then re-encodes only the primary block)
    last = len(items) - 1
    numbers = set()
    blocks = []
    seen_ext = set()
    for i in range(1, last + 1):
        blk = items[i]
        if type(blk) is not list or len(blk) != 5:
            return None
        btype, num, bflags, bcrc, bd = blk
        if not (type(btype) is int and type(num) is int and type(bflags) is int and bcrc == 0
                and type(bcrc) is int and type(bd) is bytes and btype >= 0 and num > 0 and bflags >= 0
                and num not in numbers):
            return None
        numbers.add(num)
        if i == last:
            if btype != PAYLOAD_BLOCK or num != 1:
                return None
        else:
            if btype == PAYLOAD_BLOCK:
                return None
            if btype in _EXT_KNOWN:
                if btype in seen_ext:
                    return None
                seen_ext.add(btype)
                if (btype, bd) not in _EXT_OK:
                    return None
            blocks.append(_block(btype, num, bflags, 0, bd))
    if cms == 0 and BUNDLE_AGE_BLOCK not in seen_ext:
        return None
    key = (flags, crc_type, dest, src, rpt, cms, seq, life, crc)
    raw = _PRIM_RAW.get(key)
    if raw is None:
        raw = _dumps(prim)
        if not _CHECK[crc_type](raw):
            return None
        _remember_primary(key, raw)
    if data[1:1 + len(raw)] != raw:
        return None
    b = _new_bundle(Bundle)
    pblk = items[last]
    b.__dict__.update(dest=dest, src=src, creation_ms=cms, seq=seq, lifetime_ms=life, payload=pblk[4],
                      report_to=rpt, flags=flags, crc_type=crc_type, fragment=None, blocks=blocks,
                      payload_crc_type=0, payload_flags=pblk[2], primary_raw=raw, _enc={})
    return b


# primary block fields (as _decode_fast reads them, CRC bytes included) -> cbor2.dumps of that primary
# block, its CRC checked: a bundle's primary block never changes on its way (RFC 9171 4.3.1), so a
# process that made or saw it once does not encode it again. A hit is only taken when these bytes
# are exactly the received ones.
_PRIM_RAW: dict = {}


def _remember_primary(key: tuple, raw: bytes) -> None:
    if len(_PRIM_RAW) >= 8192:
        _PRIM_RAW.clear()
    _PRIM_RAW[key] = raw


def _remember_ext(b: Bundle) -> None:
    """Note the known extension blocks of ``b`` (the plain path has just parsed each of them)."""
    if len(_EXT_OK) > 4096:
        _EXT_OK.clear()
    for blk in b.blocks:
        if blk.type in _EXT_KNOWN and blk.crc_type == CRC_NONE:
            _EXT_OK.add((blk.type, blk.data))


def _decode_plain(data: bytes) -> Bundle:
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise BundleError(f"bundle is {type(data).__name__}, not bytes")
    data = bytes(data)
    if len(data) < 3 or data[0] != 0x9F or data[-1] != 0xFF:
        raise BundleError("not a CBOR indefinite-length array (0x9f ... 0xff)")
    raws = _split_blocks(data)
    if len(raws) < 2:
        raise BundleError("a bundle needs a primary and a payload block")
    prim, raw = raws[0]
    if not isinstance(prim, list) or len(prim) not in (8, 9, 10, 11):
        raise BundleError("primary block: not an array of 8..11 items")
    if prim[0] != 7:
        raise BundleError(f"primary block: version {prim[0]!r}, not 7")
    flags, crc_type = _uint(prim[1], "primary flags"), _uint(prim[2], "primary CRC type")
    if crc_type not in _CRC_LEN:
        raise BundleError(f"primary block: unknown CRC type {crc_type}")
    has_frag = bool(flags & 0x1)
    n_expected = 8 + (2 if has_frag else 0) + (1 if crc_type else 0)
    if len(prim) != n_expected:
        raise BundleError(f"primary block: {len(prim)} items, expected {n_expected}")
    if crc_type:
        if not isinstance(prim[-1], bytes) or len(prim[-1]) != _CRC_LEN[crc_type]:
            raise BundleError("primary block: bad CRC field")
        _check_crc(raw, crc_type, "primary block")
    ts = prim[6]
    if not (isinstance(ts, list) and len(ts) == 2):
        raise BundleError("primary block: creation timestamp is not [time, seq]")
    b = Bundle(primary_raw=raw, dest=_eid_from(prim[3], "destination"), src=_eid_from(prim[4], "source"),
               report_to=_eid_from(prim[5], "report-to"), creation_ms=_uint(ts[0], "creation time"),
               seq=_uint(ts[1], "sequence number"), lifetime_ms=_uint(prim[7], "lifetime"), flags=flags,
               crc_type=crc_type,
               fragment=(_uint(prim[8], "fragment offset"), _uint(prim[9], "ADU length")) if has_frag else None)
    numbers = set()
    for i, (blk, raw) in enumerate(raws[1:], start=1):
        if not isinstance(blk, list) or len(blk) not in (5, 6):
            raise BundleError(f"block {i}: not an array of 5 or 6 items")
        btype, num, bflags, bcrc = blk[0], blk[1], blk[2], blk[3]
        if not (type(btype) is int and type(num) is int and type(bflags) is int and type(bcrc) is int
                and btype >= 0 and num >= 0 and bflags >= 0 and bcrc >= 0):  # else say which (messages
            btype, num = _uint(blk[0], f"block {i} type"), _uint(blk[1], f"block {i} number")  # made
            bflags, bcrc = _uint(blk[2], f"block {i} flags"), _uint(blk[3], f"block {i} CRC type")  # here)
        if bcrc not in _CRC_LEN or len(blk) != (6 if bcrc else 5):
            raise BundleError(f"block {i}: CRC type {bcrc} does not match its length")
        if not isinstance(blk[4], bytes):
            raise BundleError(f"block {i}: block-type-specific data is not a byte string")
        if bcrc:
            if not isinstance(blk[5], bytes) or len(blk[5]) != _CRC_LEN[bcrc]:
                raise BundleError(f"block {i}: bad CRC field")
            _check_crc(raw, bcrc, f"block {i} (type {btype})")
        if num in numbers or num == 0:
            raise BundleError(f"block {i}: block number {num} repeated or 0")
        numbers.add(num)
        last = i == len(raws) - 1
        if btype == PAYLOAD_BLOCK:
            if not last or num != 1:
                raise BundleError("payload block must be the last block and have block number 1")
            b.payload, b.payload_flags, b.payload_crc_type = blk[4], bflags, bcrc
        else:
            if last:
                raise BundleError("the last block is not the payload block")
            b.blocks.append(_block(btype, num, bflags, bcrc, blk[4]))
    if b.creation_ms == 0 and b.block(BUNDLE_AGE_BLOCK) is None:
        raise BundleError("no creation time and no bundle-age block (RFC 9171 4.2.6)")
    # the known extension blocks must parse
    b.previous_node, b.hop_count, b.age_ms  # noqa: B018 (validation by access)
    _remember_ext(b)
    return b
