"""BPv7 (RFC 9171) encoding: CRC check values, exact bytes, round trips, rejection of bad bytes."""

import cbor2
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sat_node.dtn.bpv7 import (
    CRC_16,
    CRC_32C,
    Bundle,
    BundleError,
    CanonicalBlock,
    Imc,
    crc16_x25,
    crc32c,
    decode_bundle,
    encode_bundle,
)


def test_crc_check_values():
    # the CRC catalogue's check values for "123456789"
    assert crc16_x25(b"123456789") == 0x906E
    assert crc32c(b"123456789") == 0xE3069283


def test_exact_bytes_of_a_small_bundle():
    b = Bundle(dest=(2, 1), src=(1, 1), creation_ms=1000, seq=0, lifetime_ms=900000, payload=b"hi")
    raw = encode_bundle(b)
    # primary written out by hand from RFC 9171's CDDL: array(9) [7, 0, 1(CRC-16), [2,[2,1]], [2,[1,1]],
    # [2,[1,1]], [1000, 0], 900000, crc]
    prim_no_crc = bytes.fromhex("89 07 00 01 82 02 82 02 01 82 02 82 01 01 82 02 82 01 01 82 19 03e8 00 1a 000dbba0"
                                .replace(" ", ""))
    crc = crc16_x25(prim_no_crc + bytes.fromhex("420000")).to_bytes(2, "big")
    payload = bytes.fromhex("85 01 01 00 00 42 6869".replace(" ", ""))  # [1, 1, 0, 0, h'6869']
    assert raw == b"\x9f" + prim_no_crc + b"\x42" + crc + payload + b"\xff"


def test_extension_blocks_round_trip_and_unknown_block_kept():
    b = Bundle(dest=(22, 1), src=(11, 1), creation_ms=5, seq=3, lifetime_ms=10, payload=b"x" * 50, crc_type=CRC_32C)
    b.previous_node = (11, 0)
    b.hop_count = (32, 2)
    b.blocks.append(CanonicalBlock(240, 9, 0, CRC_16, b"\x01\x02"))  # a block we know nothing of
    c = decode_bundle(encode_bundle(b))
    assert c.previous_node == (11, 0) and c.hop_count == (32, 2)
    assert c.block(240) == CanonicalBlock(240, 9, 0, CRC_16, b"\x01\x02")
    assert encode_bundle(c) == encode_bundle(b)


def test_imc_group_destination():
    """ION's imc scheme (code 3, [group, service]) as destination: exact bytes, never equal to ipn."""
    b = Bundle(dest=Imc(1, 1), src=(11, 1), creation_ms=1000, seq=0, lifetime_ms=900000, payload=b"hi")
    raw = encode_bundle(b)
    assert bytes.fromhex("8203820101") in raw  # [3, [1, 1]]
    c = decode_bundle(raw)
    assert c.dest == Imc(1, 1) and type(c.dest) is Imc and c.dest != (1, 1) and encode_bundle(c) == raw
    b.crc_type = 0  # (a CRC would catch the change first)
    raw = encode_bundle(b)
    with pytest.raises(BundleError, match="not an ipn or imc EID"):
        decode_bundle(raw.replace(bytes.fromhex("8203820101"), bytes.fromhex("8204820101")))


def test_bundle_age_required_without_creation_time():
    b = Bundle(dest=(2, 1), src=(1, 1), creation_ms=0, seq=0, lifetime_ms=10)
    with pytest.raises(BundleError, match="bundle-age"):
        encode_bundle(b)
    b.age_ms = 1234
    assert decode_bundle(encode_bundle(b)).age_ms == 1234


def test_every_single_byte_change_in_the_primary_block_is_rejected():
    raw = encode_bundle(Bundle(dest=(2, 1), src=(1, 1), creation_ms=77, seq=1, lifetime_ms=5, payload=b"p"))
    n_prim = len(cbor2.dumps(cbor2.loads(raw)[0]))
    for i in range(1, 1 + n_prim):
        for delta in (1, 0x80):
            bad = bytearray(raw)
            bad[i] ^= delta
            try:
                got = decode_bundle(bytes(bad))
            except BundleError:
                continue
            pytest.fail(f"byte {i} ^ {delta} accepted: {got}")


@pytest.mark.parametrize("bad", [b"", b"\x00", b"\x9f\xff", b"\x9f\x01\xff", b"\x80", b"not a bundle at all",
                                 cbor2.dumps([7, 0, 0]), b"\x9f" + cbor2.dumps([6, 0, 0, [2, [1, 1]]]) + b"\xff"])
def test_malformed_bytes_give_a_reason(bad):
    with pytest.raises(BundleError):
        decode_bundle(bad)


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=80))
def test_random_bytes_only_ever_raise_bundle_error(data):
    try:
        decode_bundle(data)
    except BundleError:
        pass


eids = st.tuples(st.integers(1, 2**32), st.integers(0, 2**16))


@settings(max_examples=150, deadline=None)
@given(dest=eids, src=eids, t=st.integers(1, 2**40), seq=st.integers(0, 2**20), life=st.integers(0, 2**32),
       payload=st.binary(max_size=300), crc=st.sampled_from([0, 1, 2]), imc=st.booleans(),
       hops=st.tuples(st.integers(0, 255), st.integers(0, 255)))
def test_round_trip(dest, src, t, seq, life, payload, crc, imc, hops):
    if imc:
        dest = Imc(*dest)
    b = Bundle(dest=dest, src=src, creation_ms=t, seq=seq, lifetime_ms=life, payload=payload, crc_type=crc)
    b.hop_count = hops
    raw = encode_bundle(b)
    c = decode_bundle(raw)
    assert (c.dest, c.src, c.creation_ms, c.seq, c.lifetime_ms, c.payload) == (dest, src, t, seq, life, payload)
    assert type(c.dest) is type(dest) and c.hop_count == hops
    assert encode_bundle(c) == raw
