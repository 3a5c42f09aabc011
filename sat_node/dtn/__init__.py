"""The DTN stack of a satellite: BPv7 bundles (RFC 9171) and their routing blocks, BPSec BIB (RFC
9172/9173), contact graph routing (CCSDS 734.3-B-1 SABR), a persistent bundle store and the bundle
agents (unicast: one bundle per recipient; multicast: one per observation). Pure Python (no rclpy)."""

import importlib

# name -> submodule, imported on first use (PEP 562): the codec and the convergence layers load
# without the agents, CGR and their numerical dependencies
_LAZY = {"AgentConfig": "agent", "BundleAgent": "agent", "BundleEvent": "agent", "Transmission": "agent",
         "IntegrityError": "bpsec", "add_bib": "bpsec", "verify_bib": "bpsec", "Bundle": "bpv7",
         "BundleError": "bpv7", "CanonicalBlock": "bpv7", "decode_bundle": "bpv7", "encode_bundle": "bpv7",
         "ipn": "bpv7", "ContactGraph": "cgr", "Route": "cgr", "MulticastAgent": "multicast",
         "new_agent": "multicast", "dtn_report": "stats", "BundleStore": "store", "TrafficItem": "traffic",
         "read_traffic": "traffic"}


def __getattr__(name: str):
    if name in _LAZY:
        return getattr(importlib.import_module(f"sat_node.dtn.{_LAZY[name]}"), name)
    raise AttributeError(f"module 'sat_node.dtn' has no attribute {name!r}")


__all__ = [
    "AgentConfig",
    "Bundle",
    "BundleAgent",
    "BundleError",
    "BundleEvent",
    "BundleStore",
    "CanonicalBlock",
    "ContactGraph",
    "IntegrityError",
    "MulticastAgent",
    "Route",
    "TrafficItem",
    "Transmission",
    "add_bib",
    "decode_bundle",
    "dtn_report",
    "encode_bundle",
    "ipn",
    "new_agent",
    "read_traffic",
    "verify_bib",
]
