"""sat_node/dtn/cbor_enc.py writes exactly cbor2.dumps's bytes (the oracle: cbor2 itself)."""

from __future__ import annotations

import enum

import cbor2
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sat_node.dtn.cbor_enc import dumps

# every head length's boundaries (RFC 8949 3.1: 0..23 in the head, then 1, 2, 4, 8 bytes)
_EDGES = [0, 1, 23, 24, 255, 256, 65535, 65536, 2**32 - 1, 2**32, 2**64 - 1]
_ints = st.one_of(st.sampled_from(_EDGES), st.integers(0, 2**64 - 1), st.integers(-2**70, 2**70))
_leaves = st.one_of(_ints, st.binary(max_size=300), st.text(max_size=40), st.booleans(), st.none(),
                    st.floats(allow_nan=False))
_items = st.recursive(_leaves, lambda inner: st.one_of(st.lists(inner, max_size=30),
                                                        st.lists(inner, max_size=5).map(tuple)), max_leaves=60)


@given(_items)
@settings(max_examples=1000, deadline=None)
def test_same_bytes_as_cbor2(obj):
    assert dumps(obj) == cbor2.dumps(obj)


@pytest.mark.parametrize("n", _EDGES)
def test_heads_at_the_boundaries(n):
    for obj in (n, b"\0" * min(n, 70000), [0] * min(n, 70000), "a" * min(n, 70000), [n, [n, b"x"]]):
        assert dumps(obj) == cbor2.dumps(obj)


def test_kinds_handed_to_cbor2():
    class Small(enum.IntEnum):
        A = 3

    for obj in (-1, 2**64, True, None, 1.5, {1: 2}, Small.A, [1, Small.A], b"x" * 3 + b"", bytearray(b"ab"),
                cbor2.CBORTag(24, b"x"), [1, [2, {3: 4}]]):
        assert dumps(obj) == cbor2.dumps(obj)


def test_what_cbor2_refuses_is_refused():
    with pytest.raises(Exception) as ours:
        dumps(["\ud800"])
    with pytest.raises(Exception) as theirs:
        cbor2.dumps(["\ud800"])
    assert type(ours.value) is type(theirs.value)
    with pytest.raises(cbor2.CBOREncodeError):
        dumps(object())
