"""RFC 9171 receive side: dtn-scheme EIDs (sat_node/dtn/bpv7.py), blocks of unknown types by their
block processing control flags and foreign bundles by policy (sat_node/dtn/rx_policy.py, in both
bundle agents).

Oracles: the EID encodings written out from RFC 9171 4.2.5.1.1's CDDL; bundles built by pyD3TN (an
independent BPv7 implementation, the `interop` extra) with dtn and ipn EIDs and none of the
constellation's blocks; RFC 9171 4.2.4's flag table for the block actions.
"""

from __future__ import annotations

from collections import Counter
from datetime import UTC, datetime

import cbor2
import pytest
from pyd3tn.bundle7 import serialize_bundle7

from orbit_clock.contact_plan import Contact, ContactPlan
from sat_node.dtn.agent import AgentConfig, BundleAgent
from sat_node.dtn.bpsec import IntegrityError
from sat_node.dtn.bpv7 import (
    CRC_NONE,
    PAPER_EPOCH_DTN_MS,
    Bundle,
    BundleError,
    CanonicalBlock,
    Dtn,
    decode_bundle,
    dtn_eid,
    eid_text,
    encode_bundle,
    ipn,
)
from sat_node.dtn.multicast import MulticastAgent
from sat_node.dtn.rx_policy import UnprocessableBlock, admit, apply_block_flags
from tests.keys import TEST_BPSEC_KEY

# -- dtn EIDs ------------------------------------------------------------------------------------


def test_dtn_eid_encoding_by_hand():
    b = Bundle(dest=Dtn("ground", "obs"), src=ipn(11, 1), creation_ms=1000, seq=0, lifetime_ms=60_000,
               payload=b"x")
    raw = encode_bundle(b)
    # RFC 9171 4.2.5.1.1: [1, "//ground/obs"]: array(2) 0x82, uint 1 0x01, text(12) 0x6c, the SSP
    assert bytes([0x82, 0x01, 0x6C]) + b"//ground/obs" in raw
    back = decode_bundle(raw)
    assert back.dest == Dtn("ground", "obs") and back.src == ipn(11, 1) and eid_text(back.dest) == "dtn://ground/obs"
    assert encode_bundle(back) == raw
    assert Dtn("1", "1") != (1, 1) and dtn_eid("dtn://gs-1/a/b") == Dtn("gs-1", "a/b")
    assert eid_text((0, 0)) == "dtn:none" and eid_text(ipn(3, 1)) == "ipn:3.1"


@pytest.mark.parametrize("ssp", ["ground/obs", "//", "//a b/x", "///x", "//node"])
def test_malformed_dtn_eids_rejected(ssp):
    b = Bundle(dest=ipn(2, 1), src=ipn(11, 1), creation_ms=1000, seq=0, lifetime_ms=60_000, payload=b"x",
               crc_type=CRC_NONE)  # no CRC: the EID check itself is what answers
    raw = encode_bundle(b)
    bad = raw.replace(cbor2.dumps([2, [2, 1]]), cbor2.dumps([1, ssp]), 1)
    with pytest.raises(BundleError, match="destination"):
        decode_bundle(bad)


def test_pyd3tn_dtn_bundle_decodes():
    raw = serialize_bundle7("dtn://ground-station/in", "dtn://sat11/obs", b"from a ground node", lifetime=300,  # [s]
                            creation_timestamp=datetime(2026, 11, 27, 12, tzinfo=UTC), sequence_number=7)
    b = decode_bundle(raw)
    assert (b.src, b.dest, b.seq, b.payload) == (Dtn("ground-station", "in"), Dtn("sat11", "obs"), 7,
                                                 b"from a ground node")
    assert b.bundle_id == f"dtn//ground-station/in-{b.creation_ms}-7" and b.lifetime_ms == 300_000
    assert b.creation_ms == int((datetime(2026, 11, 27, 12, tzinfo=UTC) - datetime(2000, 1, 1, tzinfo=UTC))
                                .total_seconds()) * 1000


# -- unknown blocks by their flags (RFC 9171 4.2.4) ------------------------------------------------

def _with_block(flags: int) -> Bundle:
    b = Bundle(dest=ipn(12, 1), src=ipn(11, 1), creation_ms=PAPER_EPOCH_DTN_MS, seq=0, lifetime_ms=600_000,
               payload=b"p")
    b.blocks.append(CanonicalBlock(150, 2, flags, 0, b"\x01"))  # a type nobody here knows
    return decode_bundle(encode_bundle(b))


def test_unknown_block_actions():
    c = Counter()
    b = _with_block(0)
    apply_block_flags(b, c)
    assert [x.type for x in b.blocks] == [150] and c["rx.blocks_kept"] == 1  # kept, forwarded unchanged
    b = _with_block(0x10)
    apply_block_flags(b, c)
    assert b.blocks == [] and c["rx.blocks_discarded"] == 1  # 0x10: discard the block
    with pytest.raises(UnprocessableBlock, match="deletion"):
        apply_block_flags(_with_block(0x04 | 0x10 | 0x02), c)  # 0x04 wins over 0x10
    assert c["rx.deleted_by_block_flags"] == 1 and c["rx.status_reports_not_sent"] == 1


# -- foreign bundles -------------------------------------------------------------------------------

PLAN = ContactPlan([Contact(0.0, 1000.0, a, b, 1e6, 0.0) for a, b in [("sat_11", "sat_12"), ("sat_12", "sat_11")]])


def _foreign(dest: str = "ipn:12.1") -> bytes:
    # a bundle of another stack: no BIB, no recipients block; created 10 s into the scenario
    return serialize_bundle7("ipn:900.1", dest, b"hello constellation", lifetime=600,  # [s]
                             creation_timestamp=datetime(2000, 1, 1, 11, 59, 38, tzinfo=UTC), sequence_number=3)


@pytest.mark.parametrize("agent_cls", [BundleAgent, MulticastAgent])
def test_foreign_bundles_by_policy(agent_cls):
    forwarding = "multicast" if agent_cls is MulticastAgent else "unicast"
    refuse = agent_cls("sat_12", PLAN, AgentConfig(key=TEST_BPSEC_KEY, forwarding=forwarding))
    assert refuse.receive(_foreign(), "sat_11", 20 * 10**9) == "dropped.integrity"
    assert refuse.rx_counts["rx.foreign_refused"] == 1
    accept = agent_cls("sat_12", PLAN, AgentConfig(key=TEST_BPSEC_KEY, forwarding=forwarding, foreign="accept"))
    assert accept.receive(_foreign(), "sat_11", 20 * 10**9) == "delivered"
    assert accept.last_received.payload == b"hello constellation"
    # to another node: held and routed like any unicast bundle, at the least urgent priority
    relay = agent_cls("sat_11", PLAN, AgentConfig(key=TEST_BPSEC_KEY, forwarding=forwarding, foreign="accept"))
    assert relay.receive(_foreign(), "sat_12", 20 * 10**9) == "queued"
    assert relay.rx_counts["rx.foreign_accepted"] == 1
    # a dtn-scheme destination has no route in an ipn constellation
    assert accept.receive(_foreign("dtn://elsewhere/x"), "sat_11", 20 * 10**9) == "dropped.integrity"
    assert accept.rx_counts["rx.foreign_unroutable"] == 1


def test_a_failing_bib_drops_the_bundle_under_either_policy():
    from sat_node.dtn.bpsec import add_bib
    b = decode_bundle(_foreign())
    add_bib(b, bytes(range(16)), ipn(900, 0))  # signed with another key
    raw = encode_bundle(b)
    for policy in ("refuse", "accept"):
        c = Counter()
        with pytest.raises(IntegrityError):
            admit(decode_bundle(raw), TEST_BPSEC_KEY, policy, counts=c)
        assert c["rx.bib_failed"] == 1
    with pytest.raises(ValueError, match="foreign"):
        AgentConfig(key=TEST_BPSEC_KEY, foreign="maybe")
