"""The bytes on the wire are those of a plain RFC 9171 / RFC 9173 encoder written with cbor2 alone.

The codec (sat_node/dtn/bpv7.py, bpsec.py, routing_blocks.py) writes CBOR with
sat_node/dtn/cbor_enc.py, builds the primary block item by item and keeps encodings made once;
the oracle here is the plain encoding, made in this file from the RFCs' CDDL with ``cbor2.dumps`` of
each whole block and the reference CRC tables, with no cache: a bundle is an indefinite array of
the primary block ``[7, flags, crc type, dest, src, report-to, [time, seq], lifetime(, offset,
ADU length)(, crc)]``, its canonical blocks ``[type, number, flags, crc type, data(, crc)]`` and the
payload block last (RFC 9171 4.3.1, 4.3.2), CRCs over the block with the CRC field zeroed
(4.2.1); the BIB's data is the CBOR sequence of RFC 9172 3.6 with the HMAC over the IPPT of
RFC 9173 3.7. Checked on random bundles (every EID kind, CRC type, fragments, extension
blocks), after each change a forwarding node makes (hop count, previous node, routing blocks),
and on every transmission of agents forwarding bundles over two hops.
"""

from __future__ import annotations

import hashlib
import hmac

import cbor2
from hypothesis import given, settings
from hypothesis import strategies as st

from orbit_clock.contact_plan import Contact, ContactPlan
from sat_node.dtn.agent import AgentConfig, BundleAgent
from sat_node.dtn.bpsec import add_bib, verify_bib
from sat_node.dtn.bpv7 import (
    BIB_BLOCK,
    CRC_16,
    CRC_32C,
    CRC_NONE,
    Bundle,
    Dtn,
    Imc,
    _crc16_x25_table,
    crc32c,
    decode_bundle,
    encode_bundle,
)
from sat_node.dtn.routing_blocks import set_routing
from tests.keys import TEST_BPSEC_KEY

_N = {CRC_NONE: 0, CRC_16: 2, CRC_32C: 4}


def _eid(e) -> list:
    if e is None or e == (0, 0) and type(e) is tuple:
        return [1, 0]
    if type(e) is Imc:
        return [3, [e.group, e.service]]
    if type(e) is Dtn:
        return [1, f"//{e.node}/{e.demux}"]
    return [2, [e[0], e[1]]]


def _with_crc(items: list, crc_type: int) -> bytes:
    if crc_type == CRC_NONE:
        return cbor2.dumps(items)
    n = _N[crc_type]
    raw = cbor2.dumps(items + [bytes(n)])
    crc = _crc16_x25_table(raw) if crc_type == CRC_16 else crc32c(raw)
    return raw[:-n] + crc.to_bytes(n, "big")


def plain_encode(b: Bundle) -> bytes:
    """The bundle's bytes by RFC 9171 section 4, one ``cbor2.dumps`` per block, nothing cached."""
    prim = [7, b.flags, b.crc_type, _eid(b.dest), _eid(b.src), _eid(b.report_to or b.src), [b.creation_ms, b.seq],
            b.lifetime_ms]
    if b.fragment is not None:
        prim += list(b.fragment)
    parts = [b"\x9f", _with_crc(prim, b.crc_type)]
    parts += [_with_crc([k.type, k.number, k.flags, k.crc_type, k.data], k.crc_type) for k in b.blocks]
    parts.append(_with_crc([1, 1, b.payload_flags, b.payload_crc_type, b.payload], b.payload_crc_type))
    return b"".join(parts) + b"\xff"


def plain_bib_data(b: Bundle, key: bytes, source: tuple[int, int], number: int) -> bytes:
    """RFC 9172 3.6 / RFC 9173 3.7 BIB data over the payload, HMAC-SHA384 (variant 6), scope 7."""
    primary = _with_crc([7, b.flags, b.crc_type, _eid(b.dest), _eid(b.src), _eid(b.report_to or b.src),
                         [b.creation_ms, b.seq], b.lifetime_ms] + (list(b.fragment) if b.fragment else []), b.crc_type)
    ippt = b"".join([cbor2.dumps(7), primary, cbor2.dumps(1), cbor2.dumps(1), cbor2.dumps(b.payload_flags),
                     cbor2.dumps(BIB_BLOCK), cbor2.dumps(number), cbor2.dumps(0), cbor2.dumps(b.payload)])
    mac = hmac.new(key, ippt, hashlib.sha384).digest()
    return b"".join(cbor2.dumps(x) for x in [[1], 1, 0, _eid(source), [[[1, mac]]]])


_nums = st.one_of(st.sampled_from([0, 1, 23, 24, 255, 256, 65535, 65536, 2**32 - 1, 2**32, 2**64 - 1]),
                  st.integers(0, 2**64 - 1))
_ipn = st.tuples(st.integers(0, 2**64 - 1), st.integers(0, 2**64 - 1))
_eids = st.one_of(_ipn, _ipn.map(lambda e: Imc(*e)),
                  st.tuples(st.text("abcz09-._~", min_size=1, max_size=8), st.text("abc/", max_size=8))
                  .map(lambda e: Dtn(*e)))
_blocks = st.lists(st.tuples(st.integers(12, 300), st.binary(max_size=80), st.integers(0, 64),
                             st.sampled_from([CRC_NONE, CRC_16, CRC_32C])), max_size=4)


@settings(max_examples=400, deadline=None)
@given(dest=_eids, src=_eids, rpt=st.one_of(st.none(), _eids), t=_nums.filter(bool), seq=_nums, life=_nums,
       flags=st.sampled_from([0, 4, 0x10, 0x20]), crc=st.sampled_from([CRC_16, CRC_32C, CRC_NONE]),
       frag=st.one_of(st.none(), st.tuples(_nums, _nums)), payload=st.binary(max_size=400),
       pcrc=st.sampled_from([CRC_NONE, CRC_16, CRC_32C]), blocks=_blocks,
       hops=st.tuples(st.integers(0, 300), st.integers(0, 300)), prev=_ipn)
def test_random_bundles_encode_as_the_plain_encoder(dest, src, rpt, t, seq, life, flags, crc, frag, payload, pcrc,
                                                    blocks, hops, prev):
    b = Bundle(dest=dest, src=src, report_to=rpt, creation_ms=t, seq=seq, lifetime_ms=life, payload=payload,
               flags=flags | (1 if frag else 0), crc_type=crc, fragment=frag, payload_crc_type=pcrc)
    for btype, data, bflags, bcrc in blocks:
        b.set_block(btype, data, bflags, bcrc)
    assert encode_bundle(b) == plain_encode(b)
    b.hop_count = hops  # what a forwarding node changes, one after the other
    assert encode_bundle(b) == plain_encode(b)
    b.previous_node = prev
    assert encode_bundle(b) == plain_encode(b)
    b.hop_count = (hops[0], hops[1] + 1)
    b.previous_node = (prev[0] + 1, 0)
    assert encode_bundle(b) == plain_encode(b)


@settings(max_examples=200, deadline=None)
@given(dest=st.integers(1, 2**32), src=st.integers(1, 2**32), t=_nums.filter(bool), seq=_nums,
       life=st.integers(1, 2**40), payload=st.binary(max_size=300), prio=st.integers(1, 15),
       nh=st.integers(1, 2**32))
def test_a_signed_bundle_and_its_hops_encode_as_the_plain_encoder(dest, src, t, seq, life, payload, prio, nh):
    b = Bundle(dest=(dest, 1), src=(src, 1), creation_ms=t, seq=seq, lifetime_ms=life, payload=payload)
    set_routing(b, [(dest, prio, life)], None)
    b.hop_count = (32, 0)
    add_bib(b, TEST_BPSEC_KEY, (src, 0))
    assert b.block(BIB_BLOCK).data == plain_bib_data(b, TEST_BPSEC_KEY, (src, 0), b.block(BIB_BLOCK).number)
    assert encode_bundle(b) == plain_encode(b)
    for hop in range(3):  # the relays: previous node, next hops, hop count
        b.previous_node = (nh + hop, 0)
        set_routing(b, [(dest, prio, life)], {nh + hop + 1: (dest,)})
        raw = encode_bundle(b)
        assert raw == plain_encode(b)
        c = decode_bundle(raw)
        verify_bib(c, TEST_BPSEC_KEY)
        assert encode_bundle(c) == raw == plain_encode(c)
        c.hop_count = (32, hop + 1)
        b = c


def test_every_transmission_of_forwarding_agents_is_plainly_encoded():
    s = 10**9
    plan = ContactPlan([Contact(0.0, 100.0, "sat_11", "sat_12", 1000.0, 0.0),
                        Contact(0.0, 100.0, "sat_12", "sat_11", 1000.0, 0.0),
                        Contact(50.0, 200.0, "sat_12", "sat_13", 1000.0, 0.5),
                        Contact(50.0, 200.0, "sat_13", "sat_12", 1000.0, 0.5)])
    cfg = AgentConfig(key=TEST_BPSEC_KEY)
    a = {n: BundleAgent(n, plan, cfg) for n in ("sat_11", "sat_12", "sat_13")}
    for k in range(6):
        a["sat_11"].originate(bytes([k]) * 50, "sat_13", 1 + k % 3, 10 * s)
    first = a["sat_11"].transmissions_until(30 * s)
    assert len(first) == 6
    for tx in first:
        assert tx.bundle_bytes == plain_encode(decode_bundle(tx.bundle_bytes))
        assert a["sat_12"].receive(tx.bundle_bytes, "sat_11", tx.end_ns) == "queued"
    relay = a["sat_12"].transmissions_until(80 * s)
    assert len(relay) == 6
    for tx in relay:
        b = decode_bundle(tx.bundle_bytes)
        assert tx.bundle_bytes == plain_encode(b) and b.hop_count == (32, 1) and b.previous_node == (12, 0)
        assert a["sat_13"].receive(tx.bundle_bytes, "sat_12", tx.end_ns + s) == "delivered"
        tampered = bytearray(tx.bundle_bytes)
        tampered[-3] ^= 1  # a payload byte: the BIB check must fail at the next node
        assert a["sat_13"].receive(bytes(tampered), "sat_12", tx.end_ns + s) == "dropped.integrity"
