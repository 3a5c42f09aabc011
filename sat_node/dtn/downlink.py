"""Downlinks as BPv7 bundles: each observation a satellite downlinks at a ground pass (centralized
mode, sat_node/satellite.py) travels in one bundle of its own to the ground segment's bundle agent
(ground_station/ground_agent.py).

The bundle (RFC 9171 section 4): source ``ipn:<sat>.1``, destination the ground segment's endpoint
``ipn:100.1`` (:data:`GROUND_NODE`, the first ground station's node number: the stations are the
ground segment's antennas) or, when the run has a ground gateway, the gateway peer's ``ipn:<N>.1``
(the ground forwards it there); creation time = the observation's time in DTN time of the scenario
clock, sequence number = the observed ground point (a satellite makes one observation of a GP at a
given millisecond, so (source, creation time, sequence) names the bundle uniquely and the same
observation downlinked again after a restart is the same bundle); lifetime :data:`LIFETIME_S` (an
observation waits up to an orbit for its pass, then for the ground's delivery); the constellation's
recipients block (one recipient, priority 1) and BIB (RFC 9172, BIB-HMAC-SHA2 over the payload);
hop count limit 32. The payload is the observation's msgs_json encoding (the ``Observation`` the
satellite also publishes on its observations topic), so the ground decodes it with the schema
that checks every field.

How we know it is right: tests/unit/test_ground_agent.py decodes the bundles with the project's
decoder and with pyD3TN (an independent BPv7 implementation) and checks the fields above, and
checks that a centralized run's ground learns exactly the observations its downlinks carried.
"""

from __future__ import annotations

from msgs_json import codec
from msgs_json import schemas as S
from orbit_clock.contact_plan import GS_NODE_BASE, node_number

from .bpsec import add_bib
from .bpv7 import Bundle, encode_bundle, ipn
from .routing_blocks import set_routing

__all__ = ["GROUND_NODE", "LIFETIME_S", "downlink_bundle", "observation_of"]

GROUND_NODE = GS_NODE_BASE  # the ground segment's ipn node number
LIFETIME_S = 86_400.0
HOP_LIMIT = 32


def downlink_bundle(obs: S.Observation, key: bytes, epoch_dtn_ms: int, dest_node: int = GROUND_NODE) -> bytes:
    """The encoded bundle carrying ``obs`` from its satellite to ``ipn:<dest_node>.1``."""
    src = node_number(obs.sat)
    b = Bundle(dest=ipn(int(dest_node), 1), src=ipn(src, 1), creation_ms=epoch_dtn_ms + obs.t_ns // 1_000_000,
               seq=int(obs.gp), lifetime_ms=int(LIFETIME_S * 1000), payload=codec.encode_bytes(obs))
    set_routing(b, [(int(dest_node), 1, b.lifetime_ms)], None)
    b.hop_count = (HOP_LIMIT, 0)
    add_bib(b, key, ipn(src, 0))
    return encode_bundle(b)


def observation_of(payload: bytes) -> S.Observation:
    """The observation a downlink bundle's payload carries (ValueError naming what is wrong)."""
    return codec.decode_as(S.Observation, payload, "downlink bundle payload")
