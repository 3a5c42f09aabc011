"""What a bundle agent admits from outside the constellation (RFC 9171 receive side): blocks it does
not know, handled by their block processing control flags, and bundles that lack the
constellation's BIB and recipients block ("foreign" bundles, e.g. from a ground DTN node).

RFC 9171 4.2.4 (block processing control flags) and 5.6 step 3 (bundle reception): for each block
of a type this node cannot process,
* flag 0x04 "delete bundle if block can't be processed": the bundle is deleted
  (:class:`UnprocessableBlock`, counted ``rx.deleted_by_block_flags``);
* else flag 0x10 "discard block if it can't be processed": the block is removed before the bundle
  goes on (``rx.blocks_discarded``);
* else the block is kept and forwarded unchanged (RFC 9171 4.3.2; ``rx.blocks_kept``).
Flag 0x02 "transmit status report" is counted (``rx.status_reports_not_sent``): this agent sends no
status reports (RFC 9171 6.1 makes them optional). Known here: payload (1), previous node (6),
bundle age (7), hop count (10), BIB (11, RFC 9172), ION's IMC (195) and the constellation's
recipients (200) and next-hops (201) blocks (sat_node/dtn/routing_blocks.py).

Foreign bundles (no BIB at all and no recipients block), by ``AgentConfig.foreign``:
* ``"refuse"`` (the default, the constellation's closed policy): dropped as ``integrity``
  (``rx.foreign_refused``);
* ``"accept"``: admitted as an ordinary unicast bundle to its primary block's destination, which
  must be an ipn EID (``rx.foreign_accepted``; otherwise ``rx.foreign_unroutable``; a node number
  the agent does not know is dropped after it: ``rx.unknown_destination``), at priority
  ``AgentConfig.foreign_priority`` (default 15, the least urgent) and its own lifetime. The
  unicast agent (sat_node/dtn/agent.py) that admits one and forwards it adds a BIB under the
  constellation's key with itself as security source (RFC 9172 3.5; ``rx.foreign_signed``): the
  nodes after it take a bundle with a recipients block only with the BIB.
A bundle that carries a BIB is always checked (a BIB that fails drops the bundle, foreign or
not: ``rx.bib_failed``), and a bundle with a recipients block but no BIB is refused
(``rx.unsigned_constellation_bundle``): only the constellation writes block 200.

How we know it is right: tests/unit/test_rfc9171_rx.py (each flag's action on a bundle with an
unknown block; foreign bundles made by pyD3TN, an independent BPv7 implementation, refused by
default and accepted and delivered under ``accept``; a failing BIB dropped under either policy).
"""

from __future__ import annotations

from collections import Counter

from .bpsec import IntegrityError, verify_bib
from .bpv7 import (
    BIB_BLOCK,
    BUNDLE_AGE_BLOCK,
    HOP_COUNT_BLOCK,
    PAYLOAD_BLOCK,
    PREVIOUS_NODE_BLOCK,
    Bundle,
    BundleError,
    Dtn,
    Imc,
)
from .routing_blocks import IMC_BLOCK, NEXT_HOPS_BLOCK, RECIPIENTS_BLOCK, Recipient, recipients_of

__all__ = ["FOREIGN_POLICIES", "KNOWN_BLOCK_TYPES", "UnprocessableBlock", "admit", "apply_block_flags"]

KNOWN_BLOCK_TYPES = frozenset({PAYLOAD_BLOCK, PREVIOUS_NODE_BLOCK, BUNDLE_AGE_BLOCK, HOP_COUNT_BLOCK, BIB_BLOCK,
                               IMC_BLOCK, RECIPIENTS_BLOCK, NEXT_HOPS_BLOCK})
FOREIGN_POLICIES = ("refuse", "accept")
REPORT, DELETE, DISCARD = 0x02, 0x04, 0x10  # RFC 9171 4.2.4 block processing control flags


class UnprocessableBlock(BundleError):
    """A block this node cannot process asks for the bundle's deletion (flag 0x04)."""


def apply_block_flags(b: Bundle, counts: Counter | None = None) -> None:
    """Apply RFC 9171 4.2.4 to ``b``'s blocks of unknown types (in place: discarded blocks removed);
    raise :class:`UnprocessableBlock` when one asks for the bundle's deletion."""
    counts = Counter() if counts is None else counts
    keep = []
    for blk in b.blocks:
        if blk.type in KNOWN_BLOCK_TYPES:
            keep.append(blk)
            continue
        if blk.flags & REPORT:
            counts["rx.status_reports_not_sent"] += 1
        if blk.flags & DELETE:
            counts["rx.deleted_by_block_flags"] += 1
            raise UnprocessableBlock(f"block {blk.number} of unknown type {blk.type} asks for the bundle's "
                                     "deletion (flag 0x04)")
        if blk.flags & DISCARD:
            counts["rx.blocks_discarded"] += 1
            continue
        counts["rx.blocks_kept"] += 1
        keep.append(blk)
    if len(keep) != len(b.blocks):
        b.blocks = keep


def admit(b: Bundle, key: bytes | None, foreign: str = "refuse", foreign_priority: int = 15,
          counts: Counter | None = None) -> tuple[Recipient, ...]:
    """The recipients of a received bundle under this module's rules (``key`` None: BIBs not
    checked); raises :class:`IntegrityError` / :class:`BundleError` naming why it is not admitted."""
    counts = Counter() if counts is None else counts
    apply_block_flags(b, counts)
    has_bib = b.block(BIB_BLOCK) is not None
    has_rcpts = b.block(RECIPIENTS_BLOCK) is not None
    if has_bib and key is not None:
        try:
            verify_bib(b, key)
        except IntegrityError:
            counts["rx.bib_failed"] += 1
            raise
    if has_rcpts:
        if not has_bib and key is not None:
            counts["rx.unsigned_constellation_bundle"] += 1
            raise IntegrityError("a recipients block without the constellation's BIB")
        return recipients_of(b)
    if has_bib and key is not None:
        # signed by the constellation's key but without its routing block: not ours to route
        counts["rx.foreign_refused"] += 1
        raise BundleError("a signed bundle without a recipients block")
    if foreign != "accept":
        counts["rx.foreign_refused"] += 1
        raise IntegrityError("a bundle without the constellation's BIB and recipients block "
                             "(foreign bundles refused by policy)")
    if type(b.dest) in (Imc, Dtn) or b.dest == (0, 0):
        counts["rx.foreign_unroutable"] += 1
        raise BundleError(f"a foreign bundle to a non-ipn destination ({b.dest!r}): no route here")
    counts["rx.foreign_accepted"] += 1
    return ((b.dest[0], foreign_priority, b.lifetime_ms),)
