"""Convergence layers: how a bundle (RFC 9171 bytes) crosses a real network to another DTN node.

* :mod:`.tcpcl4` - TCPCLv4 (RFC 9174), the current standard (HDTN, dtn7-rs, Hardy), TLS optional;
* :mod:`.tcpcl3` - TCPCLv3 (RFC 7242), what ION 4.x's ``tcp`` layer and uD3TN speak;
* :mod:`.udp` - one bundle per UDP datagram, as ION's ``udp`` layer sends them.

Each moves opaque bytes: none decodes a bundle, so a malformed bundle is the bundle agent's
business, a malformed convergence-layer message this package's. All are asyncio (no ROS), with
the same shape: an active side (``connect``/``send``) and a passive side (``serve``) that hands
each received bundle to a callback. Conformance tests: tests/unit/test_cl_tcpcl4.py,
tests/unit/test_cl_tcpcl3.py, tests/unit/test_cl_udp.py.
"""

from .errors import ClError, SessionTerminated, TransferRefused

__all__ = ["ClError", "SessionTerminated", "TransferRefused"]
