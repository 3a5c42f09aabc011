"""The routing blocks of sat_node/dtn/routing_blocks.py: exact bytes written out by hand from the
layout in its docstring, round trips, malformed blocks named, the codes chosen against ION's and
IANA's, and the agents' bundles parsed by pyD3TN (an independent BPv7 implementation, PyPI pyd3tn)."""

from datetime import datetime, timedelta, timezone
from enum import IntEnum

import cbor2
import pytest

from orbit_clock.contact_plan import Contact, ContactPlan, node_number
from sat_node.dtn import routing_blocks as rb
from sat_node.dtn.agent import AgentConfig, BundleAgent
from sat_node.dtn.bpsec import add_bib, verify_bib
from sat_node.dtn.bpv7 import BIB_BLOCK, Bundle, BundleError, Imc, decode_bundle, encode_bundle, ipn
from tests.keys import TEST_BPSEC_KEY


def _mc_bundle() -> Bundle:
    b = Bundle(dest=rb.OBSERVATION_GROUP, src=ipn(11, 1), creation_ms=5000, seq=2, lifetime_ms=3_000_000,
               payload=b"obs")
    rb.set_routing(b, [(23, 4, 3_000_000), (12, 1, 900_000), (31, 2, 1_800_000)], {12: (12, 23), 21: (31,)})
    return b


def test_exact_bytes_of_the_routing_blocks():
    b = _mc_bundle()
    # IMC block (ION imc.c): array(3) of the nodes ascending: 83 0c 17 18 1f
    assert b.block(rb.IMC_BLOCK).data == bytes.fromhex("830c17181f")
    # recipients: array(9) [12, 1, 900000, 23, 4, 3000000, 31, 2, 1800000]
    assert b.block(rb.RECIPIENTS_BLOCK).data == bytes.fromhex(
        "89" "0c" "01" "1a000dbba0" "17" "04" "1a002dc6c0" "181f" "02" "1a001b7740")
    # next hops: array(4) [12, [12, 23], 21, [31]]
    assert b.block(rb.NEXT_HOPS_BLOCK).data == bytes.fromhex("84" "0c" "820c17" "15" "81181f")
    c = decode_bundle(encode_bundle(b))
    assert rb.recipients_of(c) == ((12, 1, 900_000), (23, 4, 3_000_000), (31, 2, 1_800_000))
    assert rb.next_hops_of(c) == {12: (12, 23), 21: (31,)}
    assert rb.peek_next_hops(encode_bundle(b)) == (12, 21)


def test_overhead_bits_count_the_recipient_list():
    """A one-recipient bundle takes the nominal size; a multicast copy the extra bytes of its routing
    blocks (IMC block, two more recipients, one more next hop) on top."""
    uni = Bundle(dest=ipn(12, 1), src=ipn(11, 1), creation_ms=5000, seq=2, lifetime_ms=900_000, payload=b"obs")
    rb.set_routing(uni, [(12, 1, 900_000)], {12: (12,)})
    assert rb.overhead_bits(encode_bundle(uni)) == 0
    b = _mc_bundle()
    extra = (len(cbor2.dumps([195, 2, 0, 0, bytes.fromhex("830c17181f")]))  # the IMC block
             + 2 * 7 + 1  # two more triples of 7 bytes (17 04 1a.., 181f 02 1a..); the 3 -> 9 item header
             + 5)  # next hops: 12 -> [12, 23] (one more byte), 21 -> [31] (15 81 181f: 4 more)
    assert rb.overhead_bits(encode_bundle(b)) == 8 * extra
    assert rb.overhead_bits_of(rb.recipients_of(b), rb.next_hops_of(b)) == 8 * extra  # the agent's shortcut
    assert rb.overhead_bits_of([(12, 1, 900_000)], {12: (12,)}, multicast=False) == 0


@pytest.mark.parametrize("field, data, match", [
    (rb.RECIPIENTS_BLOCK, cbor2.dumps([12, 1]), "triples"),
    (rb.RECIPIENTS_BLOCK, cbor2.dumps([12, 16, 5]), "priority outside"),
    (rb.RECIPIENTS_BLOCK, cbor2.dumps([23, 1, 5, 12, 1, 5]), "ascending"),
    (rb.RECIPIENTS_BLOCK, b"\xff\x00", "bad CBOR"),
    (rb.NEXT_HOPS_BLOCK, cbor2.dumps([12, []]), "entry 0"),
    (rb.NEXT_HOPS_BLOCK, cbor2.dumps([21, [12], 12, [23]]), "ascending"),
    (rb.IMC_BLOCK, cbor2.dumps([12, 23]), "different nodes"),
])
def test_malformed_routing_blocks_are_named(field, data, match):
    b = _mc_bundle()
    b.set_block(field, data)
    c = decode_bundle(encode_bundle(b))  # unknown to the codec: carried as they are
    with pytest.raises(BundleError, match=match):
        rb.recipients_of(c)
        rb.next_hops_of(c)


def test_unicast_recipient_must_be_the_destination():
    b = Bundle(dest=ipn(12, 1), src=ipn(11, 1), creation_ms=5000, seq=2, lifetime_ms=900_000, payload=b"obs")
    rb.set_routing(b, [(13, 1, 900_000)], None)
    with pytest.raises(BundleError, match="its destination only"):
        rb.recipients_of(b)
    rb.set_routing(b, [(12, 1, 900_001)], None)
    with pytest.raises(BundleError, match="exceeds"):
        rb.recipients_of(b)


def test_private_codes_are_off_ion_and_iana():
    """Our private codes lie in RFC 9171's private range and in none of the lists of codes ION assigns
    (bpv7/include/bp.h, the older BPv7 numbering of its Unibo-CGR copy, its BPv6 extensions)."""
    ours = {rb.RECIPIENTS_BLOCK, rb.NEXT_HOPS_BLOCK}
    assert all(192 <= c <= 255 for c in ours)
    assert not ours & rb.ION_ASSIGNED_BLOCK_TYPES
    assert {192, 193, 194, 195, 196, 197} <= rb.ION_ASSIGNED_BLOCK_TYPES
    assert rb.IMC_BLOCK == 195  # ION's own IMC block, used as ION defines it
    types = {blk.type for blk in _mc_bundle().blocks}
    assert types - {rb.IMC_BLOCK} <= ours | {1, 6, 7, 10, 11, 12}


# ----------------------------------------------------------------- an independent BPv7 implementation
PLAN = ContactPlan([Contact(0.0, 100.0, "sat_11", "sat_12", 1000.0, 0.0),
                    Contact(0.0, 100.0, "sat_12", "sat_11", 1000.0, 0.0)])


@pytest.fixture
def pyd3tn_bundle7(monkeypatch):
    """pyD3TN's BPv7 module with its BlockType enum opened to every block type: pyD3TN names only the
    RFC 9171 core types and raises on others, whereas RFC 9171 4.3.2 requires a receiver to carry a
    block of a type it does not know (our BIB 11, ION's IMC 195, our private 200/201)."""
    import pyd3tn.bundle7 as b7

    class OpenBlockType(IntEnum):
        PRIMARY = -1
        PAYLOAD = 1
        PREVIOUS_NODE = 6
        BUNDLE_AGE = 7
        HOP_COUNT = 10

        @classmethod
        def _missing_(cls, value):
            if type(value) is int and value >= 0:
                m = int.__new__(cls, value)
                m._name_, m._value_ = f"TYPE_{value}", value
                return m
            return None

    monkeypatch.setattr(b7, "BlockType", OpenBlockType)
    return b7


def _check_with_pyd3tn(b7, raw: bytes, want: Bundle) -> None:
    got = b7.Bundle.parse(raw)
    p = got.primary_block
    assert p.crc_provided == p.calculate_crc()  # pyD3TN's own CRC agrees with ours
    dtn_epoch = datetime(2000, 1, 1, tzinfo=timezone.utc)
    assert (tuple(p.source), p.creation_time.time, p.creation_time.sequence_number, p.lifetime) == (
        (2, [want.src[0], want.src[1]]), dtn_epoch + timedelta(milliseconds=want.creation_ms), want.seq,
        want.lifetime_ms)
    scheme = 3 if isinstance(want.dest, Imc) else 2
    assert tuple(p.destination) == (scheme, [want.dest[0], want.dest[1]])
    assert got.payload_block.data == want.payload
    assert sorted((int(x.block_type), x.block_number, x.data) for x in got.blocks) == sorted(
        (blk.type, blk.number, blk.data) for blk in want.blocks)
    # re-encoded by pyD3TN (its own block order): every block carried unchanged, our codec reads it back
    again = decode_bundle(bytes(got))
    assert again.primary_raw == want.primary_raw and again.payload == want.payload
    assert sorted(again.blocks, key=lambda x: x.number) == sorted(want.blocks, key=lambda x: x.number)


def test_unicast_bundle_parses_in_pyd3tn(pyd3tn_bundle7):
    a = BundleAgent("sat_11", PLAN, AgentConfig(key=TEST_BPSEC_KEY))
    a.originate(b"payload of one observation", "sat_12", 3, 0)
    tx = a.transmissions_until(0)[0]
    want = decode_bundle(tx.bundle_bytes)
    assert {blk.type for blk in want.blocks} == {BIB_BLOCK, rb.RECIPIENTS_BLOCK, rb.NEXT_HOPS_BLOCK, 10, 6}
    _check_with_pyd3tn(pyd3tn_bundle7, tx.bundle_bytes, want)


def test_multicast_bundle_parses_in_pyd3tn(pyd3tn_bundle7):
    b = _mc_bundle()
    b.hop_count = (32, 1)
    b.previous_node = ipn(11, 0)
    add_bib(b, b"k" * 32, ipn(11, 0))
    raw = encode_bundle(b)
    _check_with_pyd3tn(pyd3tn_bundle7, raw, decode_bundle(raw))
    verify_bib(decode_bundle(bytes(pyd3tn_bundle7.Bundle.parse(raw))), b"k" * 32)
    assert node_number("sat_12") == 12


def test_routing_block_sizes_by_arithmetic_equal_cbor2():
    """routing_bytes computes a block's encoded size without encoding it: checked against cbor2."""
    import random

    rng = random.Random(5)
    for _ in range(500):
        t = rng.choice([rb.IMC_BLOCK, rb.RECIPIENTS_BLOCK, rb.NEXT_HOPS_BLOCK, 7, 23, 24])
        d = bytes(rng.randrange(256) for _ in range(rng.choice([0, 5, 23, 24, 100, 255, 256, 300])))
        assert rb.routing_bytes({t: d}) == len(cbor2.dumps([t, 2, 0, 0, d]))
