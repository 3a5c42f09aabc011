"""dtn_router: the ISL medium - the link model (link.py) and the participant that applies it (router.py)."""

from .link import Copy, LinkModel, LinkOutcome
from .router import ROUTER_NAME, RouterLogic

__all__ = ["Copy", "LinkModel", "LinkOutcome", "ROUTER_NAME", "RouterLogic"]
