"""The errors the convergence layers raise to their callers (one line each, naming the peer); raised
and checked in tests/unit/test_cl_tcpcl4.py."""

from __future__ import annotations


class ClError(Exception):
    """A convergence-layer session failed: malformed input, a refused parameter, a lost peer."""


class SessionTerminated(ClError):
    """The session ended (SESS_TERM / SHUTDOWN / closed TCP) before the operation completed."""

    def __init__(self, message: str, reason: int | None = None):
        super().__init__(message)
        self.reason = reason


class TransferRefused(ClError):
    """The peer refused a bundle (XFER_REFUSE / REFUSE_BUNDLE) with a reason code."""

    def __init__(self, message: str, reason: int):
        super().__init__(message)
        self.reason = reason
