"""dtn_router: the ISL medium (link.py) and a deterministic discrete-event engine for the DTN alone (des.py)."""

from .link import Copy, LinkModel, LinkOutcome

__all__ = ["LinkModel", "LinkOutcome", "Copy"]
