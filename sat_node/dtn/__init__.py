"""The DTN stack of a satellite: BPv7 bundles (RFC 9171) and their routing blocks, BPSec BIB (RFC
9172/9173), contact graph routing (CCSDS 734.3-B-1 SABR), a persistent bundle store and the bundle
agents (unicast: one bundle per recipient; multicast: one per observation). Pure Python (no rclpy)."""

from .agent import AgentConfig, BundleAgent, BundleEvent, Transmission
from .bpsec import IntegrityError, add_bib, verify_bib
from .bpv7 import Bundle, BundleError, CanonicalBlock, decode_bundle, encode_bundle, ipn
from .cgr import ContactGraph, Route
from .multicast import MulticastAgent, new_agent
from .stats import dtn_report
from .store import BundleStore
from .traffic import TrafficItem, read_traffic

__all__ = ["Bundle", "BundleError", "CanonicalBlock", "decode_bundle", "encode_bundle", "ipn",
           "IntegrityError", "add_bib", "verify_bib", "ContactGraph", "Route", "BundleAgent", "MulticastAgent", "new_agent", "AgentConfig",
           "Transmission", "BundleEvent", "BundleStore", "TrafficItem", "read_traffic", "dtn_report"]
