"""CBOR encoding (RFC 8949) of the few item kinds a bundle's blocks are made of, byte for byte what
``cbor2.dumps`` writes for them.

A bundle's blocks (RFC 9171 section 4, sat_node/dtn/bpv7.py), its BIB's security block
(sat_node/dtn/bpsec.py) and its routing blocks (sat_node/dtn/routing_blocks.py) are definite
arrays of unsigned integers, byte strings and text strings. cbor2's C encoder costs a few
microseconds per call whatever the item (it builds an encoder and a stream each time), and a
bundle's creation makes about ten such calls. :func:`dumps` writes the same bytes for those kinds
directly: the shortest-form head (RFC 8949 3.1, 3.3: the argument in 0, 1, 2, 4 or 8 bytes) and
the content; any other item (a negative or very large integer, a float, a map, a tag, a bool or
None, an int or str subclass) is handed to ``cbor2.dumps`` itself, so the output is always what
cbor2 gives.

How we know it is right: tests/unit/test_cbor_enc.py compares :func:`dumps` with ``cbor2.dumps``
on random nested items (hypothesis: every head length's boundaries, empty and long strings,
lists of lists) and on the kinds it hands on.
"""

from __future__ import annotations

import cbor2

__all__ = ["dumps"]

_HEADS = [[bytes((major << 5 | n,)) for n in range(24)] for major in range(8)]
_H1 = [bytes((major << 5 | 24,)) for major in range(8)]
_H2 = [bytes((major << 5 | 25,)) for major in range(8)]
_H4 = [bytes((major << 5 | 26,)) for major in range(8)]
_H8 = [bytes((major << 5 | 27,)) for major in range(8)]
_U64 = 1 << 64
_SMALL = _HEADS[0]  # the unsigned ints 0..23


def _head(major: int, n: int) -> bytes:
    """The head of an item of major type ``major`` with argument ``n`` (0 <= n < 2**64), shortest form."""
    if n < 24:
        return _HEADS[major][n]
    if n < 256:
        return _H1[major] + bytes((n,))
    if n < 65536:
        return _H2[major] + n.to_bytes(2, "big")
    if n < 4294967296:
        return _H4[major] + n.to_bytes(4, "big")
    return _H8[major] + n.to_bytes(8, "big")


def _enc(obj, out: list) -> bool:
    """Append the encoding of ``obj`` to ``out``; False (``out`` then partly written) when ``obj``
    holds an item this module leaves to cbor2."""
    t = type(obj)
    if t is int:
        if 0 <= obj < 24:
            out.append(_SMALL[obj])
            return True
        if 0 <= obj < _U64:
            out.append(_head(0, obj))
            return True
        return False
    if t is bytes:
        out.append(_head(2, len(obj)))
        out.append(obj)
        return True
    if t is list or t is tuple:
        out.append(_head(4, len(obj)))
        append = out.append
        for x in obj:  # the leaves most arrays hold, without a call each
            tx = type(x)
            if tx is int and 0 <= x < 24:
                append(_SMALL[x])
            elif tx is bytes:
                append(_head(2, len(x)))
                append(x)
            elif not _enc(x, out):
                return False
        return True
    if t is str:
        try:
            raw = obj.encode("utf-8")
        except UnicodeEncodeError:  # (a lone surrogate: cbor2 says what it makes of it)
            return False
        out.append(_head(3, len(raw)))
        out.append(raw)
        return True
    return False


def dumps(obj) -> bytes:
    """``cbor2.dumps(obj)`` (default options), written here for unsigned ints below 2**64, bytes,
    str and lists/tuples of them; anything else goes to cbor2."""
    t = type(obj)
    if t is int and 0 <= obj < 24:
        return _SMALL[obj]
    if t is bytes:
        return _head(2, len(obj)) + obj
    out: list = []
    if _enc(obj, out):
        return b"".join(out)
    return cbor2.dumps(obj)
