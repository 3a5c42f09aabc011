"""The ground segment's bundle agent: the same BPv7 agent and SQLite store as the satellites'
(sat_node/dtn/agent.py, sat_node/dtn/store.py), at the ground segment's node ``ipn:100``
(sat_node/dtn/downlink.py ``GROUND_NODE``; the ground stations are its antennas).

Its contact graph (CGR, sat_node/dtn/cgr.py) is the world's ground plan with every station renamed to
the ground node - each pass of any station is a contact of the ground with that satellite, both ways -
and, with a gateway (ground_station/gateway.py), two contacts with the peer's node ``ipn_<N>`` open
for the whole run (the terrestrial link: :data:`PEER_RATE_BPS`), so the peer's node number is
routed through the ground.

* Downlinks (:meth:`GroundAgent.downlink`): each bundle a satellite downlinked at a pass is received
  by the agent at the pass time (RFC 9171 5.6: BIB checked, duplicates and expired ones dropped):
  a bundle for the ground's own endpoint is delivered; one for the gateway's peer is stored and
  forwarded to it. Either way the ground segment has it: the planner (ground_segment.py) learns the
  observation it carries.
* Bundles from the peer (:meth:`GroundAgent.from_peer`): received under the gateway's policy
  (``foreign``: "accept" takes bundles made by another stack as ordinary unicast bundles; a BIB is
  always checked when present; sat_node/dtn/rx_policy.py), each decision counted per reason; they
  are routed by CGR to their destination satellite over the ground's uplinks and leave at its next
  pass as ``/ground/bundles`` messages (GroundBundle), one per transmission.
* Transmissions (:meth:`GroundAgent.transmissions`): to a satellite - emitted and settled (the pass
  is the ground's own contact); to the peer - handed to the gateway and settled (deleted from the
  store) only when the peer acknowledged the bundle (TCPCLv4 XFER_ACK, TCPCLv3 ACK_SEGMENT); over
  UDP there is no acknowledgment: settled when the datagram left.

A run without a gateway holds the agent too (downlinks delivered at ``ipn:100.1``, its store in
memory: nothing is ever held); it sends nothing then, so the ground's plans - and every report
figure - are those of a ground that read the downlinked observations directly. With a gateway the
store is the run's ``store/ground.sqlite`` (bringup/scenario/participants.py).

How we know it is right: tests/unit/test_ground_agent.py (downlink bundles delivered or forwarded,
learned once; a bundle from the peer routed to the named satellite at its next pass, by the ground
plan searched by hand; refused and BIB-failing bundles counted; the store holds every forwarded
bundle until its acknowledgment); tests/unit/test_ground_segment.py (a whole centralized run).
"""

from __future__ import annotations

from collections import Counter
from typing import NamedTuple

from orbit_clock.contact_plan import Contact, ContactPlan, ipn_node
from sat_node.dtn.agent import AgentConfig, BundleAgent, Transmission
from sat_node.dtn.bpv7 import dtn_ms_of, eid_text
from sat_node.dtn.downlink import GROUND_NODE, observation_of
from sat_node.dtn.store import BundleStore

__all__ = ["GroundAgent", "PEER_RATE_BPS", "Uplink"]

PEER_RATE_BPS = 1.0e8  # the terrestrial link to the gateway's peer (100 Mbit/s): timing only
_NS = 1_000_000_000


class Uplink(NamedTuple):
    """A bundle the ground sends to satellite ``sat`` from ``station`` at ``t_ns``."""

    station: str
    sat: str
    t_ns: int
    data: bytes


class GroundAgent:
    """``peer_node``: the gateway peer's ipn node number (None: no gateway); ``foreign``: the
    gateway's policy for bundles made by other stacks (sat_node/dtn/rx_policy.py)."""

    def __init__(self, world, key: bytes, *, store_path: str | None = None, peer_node: int | None = None,
                 foreign: str = "accept"):
        sc = world.scenario
        self.node = ipn_node(GROUND_NODE)
        self.peer = ipn_node(peer_node) if peer_node is not None else None
        if peer_node is not None and int(peer_node) == GROUND_NODE:
            raise ValueError(f"gateway peer node {peer_node}: that is the ground segment's own node")
        stations = set(world.station_nodes)
        contacts = []
        self._station: dict[tuple, str] = {}
        for c in world.ground_plan.contacts:
            src = self.node if c.src in stations else c.src
            dst = self.node if c.dst in stations else c.dst
            m = Contact(c.start_s, c.end_s, src, dst, c.rate_bps, c.range_light_s)
            contacts.append(m)
            if src == self.node:
                self._station.setdefault((m.start_s, m.end_s, m.dst), c.src)
        if self.peer is not None:
            end = sc.scenario.horizon_s + 1.0
            contacts += [Contact(0.0, end, self.node, self.peer, PEER_RATE_BPS, 0.0),
                         Contact(0.0, end, self.peer, self.node, PEER_RATE_BPS, 0.0)]
        i = sc.isl
        cfg = AgentConfig(key=key, ttl_s_by_priority={1: i.ttl_p1_s, 3: i.ttl_p2_3_s, 15: i.ttl_p4_15_s},
                          bundle_bits=None, epoch_dtn_ms=dtn_ms_of(sc.epoch), settle_delay_s=None,
                          foreign=foreign if self.peer is not None else "refuse")
        self.store = BundleStore(store_path) if store_path else None
        self.agent = BundleAgent(self.node, ContactPlan(contacts), cfg, store=self.store, keep_events=False)
        self.counters: Counter[str] = Counter()
        self.uplinked: list[tuple[str, str, int]] = []  # (bundle id, satellite, t_ns)
        self.peer_log: list[tuple[str, str, int, str]] = []  # (bundle id or "?", destination, t_ns, outcome)

    # ------------------------------------------------------------------ in
    def downlink(self, data: bytes, sat: str, t_ns: int):
        """A bundle ``sat`` downlinked at ``t_ns``: the observation it carries when the ground took
        it (delivered here or held for the peer), else None (dropped, counted)."""
        r = self.agent.receive(data, sat, t_ns)
        self.counters[f"downlink.{r}"] += 1
        b = self.agent.last_received
        if r not in ("delivered", "queued") or b is None:
            return None
        obs = observation_of(b.payload)
        if obs.sat != sat:
            raise ValueError(f"downlink bundle from {sat} carries an observation of {obs.sat}")
        return obs

    def from_peer(self, data: bytes, t_ns: int) -> str:
        """A bundle the gateway's peer sent: what the agent did with it (counted)."""
        r = self.agent.receive(data, self.peer, t_ns)
        self.counters[f"peer.{r}"] += 1
        b = self.agent.last_received
        self.peer_log.append(("?", "?", t_ns, r) if b is None else (b.bundle_id, eid_text(b.dest), t_ns, r))
        return r

    # ------------------------------------------------------------------ out
    def transmissions(self, t_ns: int) -> tuple[list[Uplink], list[Transmission]]:
        """What the agent sends up to ``t_ns``: uplinks to satellites (settled: sent) and
        transmissions to the peer (settled by :meth:`acknowledged` when the peer took them)."""
        ups, to_peer = [], []
        for tx in self.agent.transmissions_until(t_ns):
            if tx.next_hop == self.peer:
                to_peer.append(tx)
                self.counters["peer.forwarded"] += 1
                continue
            c = self.agent.graph.contacts[tx.contact]
            station = self._station.get((c.start_s, c.end_s, c.dst))
            if station is None:  # (a contact of the ground plan: every satellite contact has a station)
                raise ValueError(f"ground transmission on contact {tx.contact} to {tx.next_hop}: no station")
            ups.append(Uplink(station, tx.next_hop, tx.start_ns, tx.bundle_bytes))
            self.uplinked.append((tx.bundle_id, tx.next_hop, tx.start_ns))
            self.counters["uplinked"] += 1
            self.agent.settle(tx)
        return ups, to_peer

    def acknowledged(self, tx: Transmission) -> None:
        """The peer has ``tx``'s bundle: it leaves the ground's store."""
        if self.agent.settle(tx):
            self.counters["peer.acknowledged"] += 1

    def next_event_ns(self) -> int | None:
        return self.agent.next_event_ns()

    def held(self) -> int:
        return self.agent.held_count()

    def close(self) -> None:
        if self.store is not None:
            self.store.close()
