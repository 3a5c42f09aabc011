"""Which copies heard on the broadcast ISL medium a node's bundle agent only counts.

A copy whose next-hops block (sat_node/dtn/routing_blocks.py) names other nodes is, for the agent
that hears it, a copy to discard and count (``discarded.not_next_hop``, no event, nothing else
changes: :meth:`BundleAgent.overheard` / :meth:`MulticastAgent.overheard` return True). Which those
are depends on the agent's forwarding:

* multicast (sat_node/dtn/multicast.py): the block names next hops and the node is not one of them;
* unicast (sat_node/dtn/agent.py): the block names exactly one next hop and it is another node (a
  copy naming several is not a unicast copy: the agent drops it as malformed, with an event).

The ISL medium (dtn_router/router.py) applies :func:`only_counted` to send such copies as one count
per node and step (/sat_XX/dtn/overheard) instead of one envelope each.

Oracle: tests/unit/test_overheard_counts.py draws next-hop sets and checks :func:`only_counted`
against both agents' own ``overheard`` on copies carrying them.
"""

from __future__ import annotations

__all__ = ["FORWARDINGS_COUNTED", "only_counted"]

FORWARDINGS_COUNTED = ("multicast", "unicast")


def only_counted(forwarding: str, next_hops: tuple[int, ...], number: int) -> bool:
    """True when the agent of node ``number`` in ``forwarding`` mode only counts a copy that names
    ``next_hops`` (ipn node numbers, as routing_blocks.peek_next_hops gives them)."""
    if forwarding == "multicast":
        return bool(next_hops) and number not in next_hops
    if forwarding == "unicast":
        return len(next_hops) == 1 and next_hops[0] != number
    raise ValueError(f"forwarding {forwarding!r}: one of {', '.join(FORWARDINGS_COUNTED)}")
