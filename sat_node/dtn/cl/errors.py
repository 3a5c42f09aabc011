"""The errors the convergence layers raise to their callers (one line each, naming the peer); raised
and checked in tests/unit/test_cl_tcpcl4.py."""

from __future__ import annotations

from collections import Counter


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


def send_failure(exc: BaseException, timeout_s: float | None) -> str:
    """Why a transfer failed, for a session's ``error``: asyncio.wait_for's TimeoutError is an
    OSError on Python 3.11, so the acknowledgement wait running out is named for what it is."""
    if isinstance(exc, TimeoutError):
        return f"no acknowledgement within {timeout_s} s"
    return f"connection lost while sending ({exc})"


def count_failure(counters: Counter[str], why: str) -> None:
    """Count a session's failure under its kind: a lost connection, an acknowledgement wait that ran
    out, or the peer's protocol error."""
    counters["connections_lost" if why.startswith("connection lost")
             else "ack_timeouts" if why.startswith("no acknowledgement") else "protocol_errors"] += 1
