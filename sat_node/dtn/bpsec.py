"""BPSec (RFC 9172) Block Integrity Block with the RFC 9173 BIB-HMAC-SHA2 security context.

A BIB (block type 11) holds an Abstract Security Block (RFC 9172 3.6): a CBOR *sequence* of security
targets, context id (1 = BIB-HMAC-SHA2), context flags (bit 0: parameters present), security
source EID, parameters ``[[id, value], ...]`` and results ``[[[result id, value], ...] per target]``.
The MAC is an HMAC-SHA2 over the Integrity-Protected Plaintext (RFC 9173 3.7): the scope flags as a
CBOR uint, then optionally the primary block (bit 0), the target's header (type, number, flags;
bit 1) and the BIB's header (bit 2), then the target's block-type-specific data as a CBOR byte
string. Parameters: 1 SHA variant (5 HMAC 256/256, 6 HMAC 384/384 default, 7 HMAC 512/512),
3 integrity scope flags (default 7). Wrapped keys (parameter 2) are not supported: the key is the
constellation's shared key, given to :func:`add_bib` / :func:`verify_bib`.

How we know it is right: RFC 9173 appendix A.1 (key 1a2b...1a2b, HMAC 512, scope 0, payload "Ready to
generate a 32-byte payload"): same IPPT bytes and the same 64-byte MAC as the RFC
(tests/unit/test_bpsec.py); a flipped payload bit, a wrong key and a truncated BIB all fail, also
after the same BIB bytes were parsed once and cached, and what add_bib leaves in those caches equals
the parse and a fresh check (tests/unit/test_speed_paths.py); the BIB add_bib writes equals one
made with cbor2 and hmac alone from RFC 9172 3.6 / RFC 9173 3.7 (tests/unit/test_wire_same_bytes.py).
"""

from __future__ import annotations

import hashlib
import hmac
import io

import cbor2

from .bpv7 import BIB_BLOCK, PAYLOAD_BLOCK, Bundle, BundleError, CanonicalBlock, _eid_bytes, _eid_from, encode_primary
from .cbor_enc import dumps as _dumps

__all__ = ["IntegrityError", "add_bib", "verify_bib", "ippt", "BIB_HMAC_SHA2", "SHA_VARIANTS"]

BIB_HMAC_SHA2 = 1
SHA_VARIANTS = {5: hashlib.sha256, 6: hashlib.sha384, 7: hashlib.sha512}


class IntegrityError(BundleError):
    """BIB missing, malformed or not matching: the bundle must be dropped (counted as integrity)."""


def _target(b: Bundle, number: int) -> tuple[int, int, int, bytes]:
    if number == 1:
        return (PAYLOAD_BLOCK, 1, b.payload_flags, b.payload)
    for blk in b.blocks:
        if blk.number == number:
            return (blk.type, blk.number, blk.flags, blk.data)
    raise IntegrityError(f"BIB target block {number} is not in the bundle")


# CBOR encodings of the small unsigned ints the IPPT is made of (0..255, the same bytes as cbor2.dumps)
_UINT = {i: _dumps(i) for i in range(256)}


def _u(x) -> bytes:
    e = _UINT.get(x) if type(x) is int else None
    return e if e is not None else _dumps(x)


def ippt(b: Bundle, target_number: int, scope: int, bib_header: tuple[int, int, int]) -> bytes:
    """Integrity-Protected Plaintext of RFC 9173 3.7."""
    ttype, tnum, tflags, tdata = _target(b, target_number)
    out = [_u(scope)]
    if scope & 1:
        out.append(encode_primary(b))
    if scope & 2:
        out += [_u(ttype), _u(tnum), _u(tflags)]
    if scope & 4:
        out += [_u(x) for x in bib_header]
    out.append(_dumps(tdata))
    return b"".join(out)


def add_bib(b: Bundle, key: bytes, security_source: tuple[int, int], *, sha_variant: int = 6, scope: int = 7,
            targets: tuple[int, ...] = (1,), block_number: int | None = None, flags: int = 0) -> Bundle:
    """Add (or replace) a BIB over ``targets`` (default: the payload). Returns ``b`` (modified)."""
    if sha_variant not in SHA_VARIANTS:
        raise ValueError(f"SHA variant {sha_variant}: one of {sorted(SHA_VARIANTS)}")
    b.blocks = [blk for blk in b.blocks if blk.type != BIB_BLOCK]
    if block_number is None:
        used = {blk.number for blk in b.blocks} | {1}
        block_number = 2
        while block_number in used:
            block_number += 1
    header = (BIB_BLOCK, block_number, flags)
    params = []
    if sha_variant != 6:
        params.append([1, sha_variant])
    if scope != 7:
        params.append([3, scope])
    results = []
    for t in targets:
        mac = hmac.digest(key, ippt(b, t, scope, header), SHA_VARIANTS[sha_variant])
        results.append([[1, mac]])
    # the abstract security block: a CBOR sequence, each item encoded on its own (the source EID's
    # encoding made once per EID: _eid_bytes is _dumps(_eid_cbor(eid)))
    seq = [_dumps(list(targets)), _dumps(BIB_HMAC_SHA2), _dumps(1 if params else 0), _eid_bytes(security_source)]
    if params:
        seq.append(_dumps(params))
    seq.append(_dumps(results))
    data = b"".join(seq)
    blk = CanonicalBlock(BIB_BLOCK, block_number, flags, 0, data)
    b.blocks.insert(0, blk)
    _remember_made(b, blk, key, targets, params, security_source, results, scope, sha_variant)
    return b


def _remember_made(b: Bundle, blk: CanonicalBlock, key: bytes, targets, params, source, results, scope: int,
                   variant: int) -> None:
    """The caches verify_bib reads, for a BIB just made: its parse (what _parse_asb_plain gives for
    these bytes, built from what was encoded) and its MACs as checked (they were computed from these
    very inputs, so checking them gives True). Only for plain ints and an ipn source; checked equal to
    the parse and to a fresh check in tests/unit/test_speed_paths.py."""
    if type(blk.data) is not bytes or not all(type(t) is int for t in targets) \
            or not (type(source) is tuple and len(source) == 2 and all(type(x) is int and x >= 0 for x in source)) \
            or not all(type(x) is int for p in params for x in p):
        return
    if len(_ASB) >= _MEMO_MAX:
        _ASB.clear()
    _ASB[blk.data] = (list(targets), BIB_HMAC_SHA2, source, {p[0]: p[1] for p in params}, results)
    for t in targets:
        memo = _verified_key(b, blk, key, t, scope, variant)
        if len(_VERIFIED) >= _MEMO_MAX:
            _VERIFIED.clear()
        _VERIFIED.add(memo)


def _verified_key(b: Bundle, blk: CanonicalBlock, key: bytes, t: int, scope: int, variant: int) -> tuple:
    """Every input of a BIB's MAC over target ``t`` (verify_bib's memo key)."""
    return (key, blk.data, blk.number, blk.flags, scope, variant, t, encode_primary(b) if scope & 1 else b"",
            _target(b, t))


# entries kept in each memo below before it is emptied: more than the bundles a run has in transit at
# once (each entry holds the bytes of a bundle's BIB, primary block and payload: ~0.5 kB)
_MEMO_MAX = 1 << 16

# BIB block-type-specific data -> its parse (a pure function of the bytes; a bundle's BIB is the same at
# every hop, so a process parses it once). Only successful parses are kept; nobody mutates them.
_ASB: dict = {}


def _parse_asb(data: bytes):
    got = _ASB.get(data) if type(data) is bytes else None
    if got is None:
        got = _parse_asb_plain(data)
        if type(data) is bytes:
            if len(_ASB) >= _MEMO_MAX:
                _ASB.clear()
            _ASB[data] = got
    return got


def _parse_asb_plain(data: bytes):
    fp = io.BytesIO(data)
    dec = cbor2.CBORDecoder(fp)
    try:
        targets, ctx_id, ctx_flags, source = dec.decode(), dec.decode(), dec.decode(), dec.decode()
        params = dec.decode() if isinstance(ctx_flags, int) and ctx_flags & 1 else []
        results = dec.decode()
    except Exception as exc:
        raise IntegrityError(f"BIB: malformed abstract security block: {exc}") from None
    if fp.tell() != len(data):
        raise IntegrityError("BIB: trailing bytes in the abstract security block")
    if not (isinstance(targets, list) and isinstance(results, list) and len(results) == len(targets)):
        raise IntegrityError("BIB: targets and results do not match")
    return targets, ctx_id, _eid_from(source, "BIB security source"), dict(
        (p[0], p[1]) for p in params if isinstance(p, list) and len(p) == 2), results


# MAC inputs already checked in this process (see verify_bib)
_VERIFIED: set = set()


def verify_bib(b: Bundle, key: bytes, *, required_targets: tuple[int, ...] = (1,)) -> None:
    """Check every BIB in ``b``; raise :class:`IntegrityError` unless each required target is covered
    and every MAC matches."""
    covered = set()
    for blk in b.blocks:
        if blk.type != BIB_BLOCK:
            continue
        targets, ctx_id, _src, params, results = _parse_asb(blk.data)
        if ctx_id != BIB_HMAC_SHA2:
            raise IntegrityError(f"BIB: unsupported security context {ctx_id}")
        variant, scope = params.get(1, 6), params.get(3, 7)
        if variant not in SHA_VARIANTS or 2 in params:
            raise IntegrityError(f"BIB: unsupported parameters {params}")
        for t, res in zip(targets, results):
            macs = [r[1] for r in res if isinstance(r, list) and len(r) == 2 and r[0] == 1]
            if len(macs) != 1:
                raise IntegrityError(f"BIB: no HMAC result for target {t}")
            # every input of the MAC: a bundle's BIB, primary block and payload are the same at every
            # hop, so a process that checked them once (N agents in one process) need not again
            memo = _verified_key(b, blk, key, t, scope, variant) if type(blk.data) is bytes else None
            if memo is None or memo not in _VERIFIED:
                want = hmac.digest(key, ippt(b, t, scope, (blk.type, blk.number, blk.flags)), SHA_VARIANTS[variant])
                if not hmac.compare_digest(want, macs[0]):
                    raise IntegrityError(f"BIB: HMAC mismatch on block {t}")
                if memo is not None:
                    if len(_VERIFIED) >= _MEMO_MAX:
                        _VERIFIED.clear()
                    _VERIFIED.add(memo)
            covered.add(t)
    missing = set(required_targets) - covered
    if missing:
        raise IntegrityError(f"BIB: blocks {sorted(missing)} not integrity-protected")
