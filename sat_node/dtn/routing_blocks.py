"""The bundle's routing blocks: who the bundle is for, and which next hop serves whom.

One bundle per observation carries its recipient list (docs/design.md section 5). The layout follows ION's
IPN multicast (ION-DTN bpv7/library/ext/imc/imc.c, bpv7/include/bp.h) where ION has one, and uses
block types of the private range (RFC 9171 section 9.1: 192-255) that ION does not assign elsewhere:

* destination EID (primary block): a multi-recipient bundle goes to the group ``imc:1.1`` - the
  ``imc`` scheme, code 3, SSP ``[group number, service number]``, as ION's ``serializeEid`` writes it
  (:data:`OBSERVATION_GROUP`: every satellite is a member of group 1, the observation service is 1).
  A single-recipient (unicast) bundle goes to ``ipn:N.1`` as before.
* block 195, ION's IMC destinations block (:data:`IMC_BLOCK`): a definite CBOR array of the node
  numbers this copy still has to serve, ascending (ION's ``loadDestination`` keeps them sorted and
  ``imc_parse`` reads an array of unsigned integers and nothing after it). Only in multicast bundles.
* block 200, recipients (:data:`RECIPIENTS_BLOCK`, private): a definite CBOR array of triples,
  flattened, ``[node, priority, lifetime_ms, node, priority, lifetime_ms, ...]`` ascending by node:
  each recipient's priority (1 = most urgent .. 15) and its own lifetime in ms after the bundle's
  creation time (the recipient's deadline is creation + lifetime_ms; the primary block's lifetime
  is the largest of them). Same recipients as the IMC block.
* block 201, next hops (:data:`NEXT_HOPS_BLOCK`, private): a definite CBOR array, flattened,
  ``[next hop node, [recipient node, ...], ...]`` ascending by next hop: the next-hop split of this
  transmission. A node that hears the copy keeps it only for the recipients listed under its own
  number; a node not listed discards it. A unicast bundle has one entry ``[next hop, [dest]]``.

The BIB (RFC 9173, block 11) covers the payload only: the routing blocks change at every hop.

Codes ION assigns (:data:`ION_ASSIGNED_BLOCK_TYPES`): BPv7 ``bp.h`` 8 (metadata), 13 (CTEB), 14
(CREB), 192 DataLabel, 193 QoS, 194 SnW permits, 195 IMC, 196 RGR, 197 CGRR; the older BPv7 numbering
kept in ION's Unibo-CGR (13 manifest, 14 metadata, 15 data label, 19 QoS, 21 SnW, 22 IMC, 23 RGR,
24 CGRR); BPv6 extensions 5 (PHN), 8 (MEB), 10 (CTEB), 19 (ECOS), 20 (BAE), 21 (SnW), 65 (SNID).
The IANA "Bundle Block Types" registry assigns 0-12 and leaves 13-191 unassigned, 192-255 private.
Our 200 and 201 are in the private range and in none of those lists (tests/unit/test_routing_blocks.py).

On-air size: the link model times a bundle at the scenario's ``bundle_bits`` (the study's 2000 bits
for one observation to one recipient); a multicast copy takes :func:`overhead_bits` more, the
encoded size of its IMC, recipients and next-hops blocks beyond those of a one-recipient bundle
(recipient list overhead is counted, never hidden).

How we know it is right: tests/unit/test_routing_blocks.py (exact bytes written out by hand, round
trips, malformed blocks rejected with the reason, the bytes parse in pyD3TN - an independent BPv7
implementation - with every block kept, no private code in ION's lists).
"""

from __future__ import annotations

import cbor2

from .bpv7 import Bundle, BundleError, Imc
from .cbor_enc import dumps as _dumps

__all__ = ["IMC_BLOCK", "RECIPIENTS_BLOCK", "NEXT_HOPS_BLOCK", "ION_ASSIGNED_BLOCK_TYPES", "OBSERVATION_GROUP",
           "Recipient", "set_routing", "recipients_of", "next_hops_of", "peek_next_hops", "overhead_bits", "overhead_bits_of",
           "routing_bytes"]

IMC_BLOCK = 195
RECIPIENTS_BLOCK = 200
NEXT_HOPS_BLOCK = 201
ION_ASSIGNED_BLOCK_TYPES = frozenset({5, 8, 10, 13, 14, 15, 19, 20, 21, 22, 23, 24, 65, 192, 193, 194, 195, 196, 197})
OBSERVATION_GROUP = Imc(1, 1)

# Recipient: (node number, priority 1..15, lifetime after creation [ms])
Recipient = tuple[int, int, int]


def _uint(x) -> bool:
    return type(x) is int and x >= 0


def _loads(data: bytes, what: str):
    try:
        return cbor2.loads(data)
    except Exception as exc:  # cbor2 raises several types on garbage
        raise BundleError(f"{what}: bad CBOR: {exc}") from None


# block data -> parse (pure functions of the bytes; a bundle's blocks take few distinct values per run)
_RCPT: dict[bytes, tuple] = {}
_SPLIT: dict[bytes, tuple] = {}
_IMC: dict[bytes, tuple] = {}


def _memo(cache: dict, data: bytes, value) -> None:
    if len(cache) >= 8192:
        cache.clear()
    cache[data] = value


def encode_recipients(recipients) -> bytes:
    recipients = tuple(recipients)
    try:  # a few distinct recipient lists per run: each encoded once (equal inputs, equal ints, equal bytes)
        got = _ENC_RCPT.get(recipients)
    except TypeError:  # an unhashable item: encoded as it is
        got = _ENC_RCPT_NONE
    if got is not None and got is not _ENC_RCPT_NONE:
        return got
    flat = []
    for node, prio, life in sorted(recipients):
        flat += [int(node), int(prio), int(life)]
    out = _dumps(flat)
    if got is None:
        _memo(_ENC_RCPT, recipients, out)
    return out


# recipient lists / next-hop splits -> their encoding (the encoders' inputs: a handful per run)
_ENC_RCPT: dict = {}
_ENC_SPLIT: dict = {}
_ENC_RCPT_NONE = object()


def parse_recipients(data: bytes) -> tuple[Recipient, ...]:
    got = _RCPT.get(data)
    if got is not None:
        return got
    v = _loads(data, "recipients block")
    if not (isinstance(v, list) and v and len(v) % 3 == 0 and all(_uint(x) for x in v)):
        raise BundleError("recipients block: not a non-empty array of [node, priority, lifetime_ms] triples")
    out = tuple((v[i], v[i + 1], v[i + 2]) for i in range(0, len(v), 3))
    if any(not 1 <= p <= 15 for _n, p, _l in out):
        raise BundleError("recipients block: a priority outside 1..15")
    nodes = [r[0] for r in out]
    if nodes != sorted(set(nodes)):
        raise BundleError("recipients block: nodes not ascending or repeated")
    _memo(_RCPT, data, out)
    return out


def encode_next_hops(split: dict[int, tuple[int, ...]]) -> bytes:
    key = tuple(split.items())
    try:
        got = _ENC_SPLIT.get(key)
    except TypeError:  # e.g. lists of recipients: encoded as they are
        got = _ENC_RCPT_NONE
    if got is not None and got is not _ENC_RCPT_NONE:
        return got
    flat: list = []
    for nh in sorted(split):
        flat += [int(nh), sorted(int(r) for r in split[nh])]
    out = _dumps(flat)
    if got is None:
        _memo(_ENC_SPLIT, key, out)
    return out


def parse_next_hops(data: bytes) -> tuple[tuple[int, tuple[int, ...]], ...]:
    got = _SPLIT.get(data)
    if got is not None:
        return got
    v = _loads(data, "next-hops block")
    if not (isinstance(v, list) and v and len(v) % 2 == 0):
        raise BundleError("next-hops block: not a non-empty array of [next hop, [recipients]] pairs")
    out = []
    for i in range(0, len(v), 2):
        nh, rs = v[i], v[i + 1]
        if not (_uint(nh) and isinstance(rs, list) and rs and all(_uint(r) for r in rs)):
            raise BundleError(f"next-hops block: entry {i // 2} is not [next hop, [recipient, ...]]")
        out.append((nh, tuple(rs)))
    if [e[0] for e in out] != sorted({e[0] for e in out}):
        raise BundleError("next-hops block: next hops not ascending or repeated")
    out = tuple(out)
    _memo(_SPLIT, data, out)
    return out


def encode_imc(nodes) -> bytes:
    return _dumps(sorted(int(n) for n in nodes))


def parse_imc(data: bytes) -> tuple[int, ...]:
    got = _IMC.get(data)
    if got is not None:
        return got
    v = _loads(data, "IMC block")
    if not (isinstance(v, list) and all(_uint(x) for x in v)):
        raise BundleError("IMC block: not an array of node numbers")
    out = tuple(v)
    _memo(_IMC, data, out)
    return out


def set_routing(b: Bundle, recipients, split: dict[int, tuple[int, ...]] | None) -> None:
    """Write the routing blocks of ``b``: ``recipients`` [(node, priority, lifetime_ms)] this copy
    serves, ``split`` {next hop: recipients} (None: no next-hops block, e.g. in the store). A bundle
    to an ``imc`` group also gets ION's IMC block with the same nodes."""
    recipients = sorted(recipients)
    if isinstance(b.dest, Imc):
        b.set_block(IMC_BLOCK, encode_imc(r[0] for r in recipients))
    b.set_block(RECIPIENTS_BLOCK, encode_recipients(recipients))
    if split is None:
        b.blocks = [blk for blk in b.blocks if blk.type != NEXT_HOPS_BLOCK]
    else:
        b.set_block(NEXT_HOPS_BLOCK, encode_next_hops(split))


def recipients_of(b: Bundle) -> tuple[Recipient, ...]:
    """The recipients block, checked against the IMC block (same nodes) and the destination (a unicast
    bundle's one recipient is its destination). Raises BundleError naming the defect."""
    blk = b.block(RECIPIENTS_BLOCK)
    if blk is None:
        raise BundleError("no recipients block")
    rs = parse_recipients(blk.data)
    if isinstance(b.dest, Imc):
        imc = b.block(IMC_BLOCK)
        if imc is None:
            raise BundleError("a bundle to an imc group without an IMC block")
        if parse_imc(imc.data) != tuple(r[0] for r in rs):
            raise BundleError("IMC block and recipients block name different nodes")
    elif len(rs) != 1 or rs[0][0] != b.dest[0]:
        raise BundleError("a unicast bundle's recipients block must name its destination only")
    if any(life > b.lifetime_ms for _n, _p, life in rs):
        raise BundleError("a recipient's lifetime exceeds the bundle's")
    return rs


def next_hops_of(b: Bundle, recipients: tuple[Recipient, ...] | None = None) -> dict[int, tuple[int, ...]]:
    """{next hop: recipients} of the next-hops block ({} without one); every recipient named must be
    one of the bundle's recipients (``recipients``: :func:`recipients_of` of ``b``, if the caller has
    it)."""
    blk = b.block(NEXT_HOPS_BLOCK)
    if blk is None:
        return {}
    split = dict(parse_next_hops(blk.data))
    known = {r[0] for r in (recipients_of(b) if recipients is None else recipients)}
    for nh, rs in split.items():
        if not set(rs) <= known:
            raise BundleError(f"next-hops block: next hop {nh} serves nodes that are not recipients")
    return split


# bundle bytes -> (next hop nodes, overhead bits): the medium and every node in view peek each copy
_PEEK: dict[bytes, tuple[tuple[int, ...], int]] = {}


def _peek(data: bytes) -> tuple[tuple[int, ...], int]:
    got = _PEEK.get(data) if type(data) is bytes else None
    if got is not None:
        return got
    try:
        items = cbor2.loads(data)
    except Exception as exc:
        raise BundleError(f"bad CBOR: {exc}") from None
    if not isinstance(items, list) or not items:
        raise BundleError("not a CBOR array of blocks")
    nhs: tuple[int, ...] = ()
    sizes = {}
    for blk in items[1:]:
        if isinstance(blk, list) and len(blk) >= 5 and isinstance(blk[4], bytes) and blk[0] in _ROUTING:
            if blk[0] in sizes:
                raise BundleError(f"block type {blk[0]} repeated")
            sizes[blk[0]] = blk[4]
    if NEXT_HOPS_BLOCK in sizes:
        nhs = tuple(nh for nh, _rs in parse_next_hops(sizes[NEXT_HOPS_BLOCK]))
    out = (nhs, 8 * _overhead_bytes(sizes))
    if type(data) is bytes:
        _memo(_PEEK, data, out)
    return out


_ROUTING = frozenset((IMC_BLOCK, RECIPIENTS_BLOCK, NEXT_HOPS_BLOCK))


def remember_unicast_peek(data: bytes, b: Bundle, split: dict[int, tuple[int, ...]]) -> None:
    """Note what :func:`_peek` of ``data`` gives, ``data`` being the encoding of ``b`` just after
    ``set_routing(b, recipients, split)``: its next hops are ``split``'s (ascending, as written) and,
    without an IMC block, its overhead is 0 - so the medium and the nodes in view need not parse the
    copy. Not noted when ``b`` has an IMC block or a routing block twice (then it is parsed)."""
    if type(data) is not bytes:
        return
    seen = set()
    for blk in b.blocks:
        t = blk.type
        if t in _ROUTING:
            if t == IMC_BLOCK or t in seen:
                return
            seen.add(t)
    if NEXT_HOPS_BLOCK not in seen:
        return
    _memo(_PEEK, data, (tuple(sorted(int(nh) for nh in split)), 0))


def peek_next_hops(data: bytes) -> tuple[int, ...]:
    """The next hops the copy names (ascending; () without a next-hops block), without checking the
    rest. Raises BundleError if the bytes are not a bundle-shaped CBOR array."""
    return _peek(data)[0]


def _head_len(n: int) -> int:
    """Bytes of a CBOR head carrying ``n`` (an unsigned integer, or a length)."""
    return 1 if n < 24 else 2 if n < 256 else 3 if n < 65536 else 5 if n < 2**32 else 9


def routing_bytes(block_data: dict[int, bytes]) -> int:
    """Encoded size of routing blocks given their data by type (block header included):
    ``len(cbor2.dumps([type, number, 0, 0, data]))`` for a block number below 24, by arithmetic."""
    return sum(1 + _head_len(t) + 1 + 1 + 1 + _head_len(len(d)) + len(d) for t, d in block_data.items())


def _overhead_bytes(block_data: dict[int, bytes]) -> int:
    """Routing-block bytes beyond those of a one-recipient bundle with one next hop (0 for it)."""
    if IMC_BLOCK not in block_data:
        return 0
    rs = parse_recipients(block_data[RECIPIENTS_BLOCK]) if RECIPIENTS_BLOCK in block_data else ()
    if not rs:
        return routing_bytes(block_data)
    node, prio, life = rs[0]
    base = {RECIPIENTS_BLOCK: encode_recipients([(node, prio, life)])}
    if NEXT_HOPS_BLOCK in block_data:
        first_nh = parse_next_hops(block_data[NEXT_HOPS_BLOCK])[0][0]
        base[NEXT_HOPS_BLOCK] = encode_next_hops({first_nh: (node,)})
    return max(0, routing_bytes(block_data) - routing_bytes(base))


def overhead_bits_of(recipients, split: dict[int, tuple[int, ...]] | None, multicast: bool = True) -> int:
    """:func:`overhead_bits` of the copy whose routing blocks :func:`set_routing` would write for
    ``recipients`` and ``split`` (without encoding the bundle)."""
    key = (tuple(sorted(recipients)), None if split is None else tuple(sorted(split.items())), multicast)
    got = _OVERHEAD_OF.get(key)
    if got is None:
        data = {RECIPIENTS_BLOCK: encode_recipients(key[0])}
        if multicast:
            data[IMC_BLOCK] = encode_imc(r[0] for r in key[0])
        if split is not None:
            data[NEXT_HOPS_BLOCK] = encode_next_hops(split)
        got = 8 * _overhead_bytes(data)
        _memo(_OVERHEAD_OF, key, got)
    return got


_OVERHEAD_OF: dict = {}


def overhead_bits(data: bytes) -> int:
    """On-air bits a copy takes beyond the nominal bundle size (module docstring): its IMC, recipients
    and next-hops blocks beyond those of a one-recipient bundle. 0 for a unicast bundle."""
    return _peek(data)[1]
