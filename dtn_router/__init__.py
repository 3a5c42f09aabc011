"""dtn_router: the ISL medium (link.py) and a deterministic discrete-event engine for the DTN alone (des.py)."""

from .des import DtnRun, latency_lower_bounds, run_dtn, store_forward_bound_mean
from .link import Copy, LinkModel, LinkOutcome

__all__ = ["LinkModel", "LinkOutcome", "Copy", "run_dtn", "DtnRun", "latency_lower_bounds",
           "store_forward_bound_mean"]
