"""The DTN alone on a contact plan and a traffic table, driven by the engine of a whole run.

``constellation dtn`` and the DTN benchmarks study the study's own inputs (a contact plan and the
traffic its observations made, tests/fixtures/paper_inputs) without orbits or planning. They run the
same participants a distributed run has for its DTN, on the local engine (bringup/engine/local.py)
with the same step rule: one :class:`sat_node.dtn.traffic.TrafficNode` per node (the satellite's
own bundle agent and port, sat_node/dtn/port.py, fed by the traffic table instead of
observations) and the ISL medium (dtn_router/router.py) on the truth plan. So a transmission that
fails is found and reported by the medium, at the attempt's end, exactly as in ``constellation run``;
there is no second event loop for the DTN.

Timing: each node is woken at its creation times; between them the engine steps at most
``max_step_s`` apart (a run's ``lockstep_max_step_s``, 10 s by default). Transmissions, arrivals
and expiries are computed in continuous time and stamped exactly (sat_node/dtn/port.py), so
latencies do not depend on the step length; what does is only when a node *learns* of an arrival
or a failure: at the step after the medium emitted it (the medium emits a copy at the step that
reaches its arrival). A node's radio decides in continuous time up to each step with what it has
learned by then. The horizon is the last contact end or creation plus the longest TTL, so every
bundle is delivered, dropped or expired by the end.

How we know it is right: tests/unit/test_dtn_alone.py (hand-worked latencies on drawn chains,
conservation, send orders and hop tolerance through the CLI, the study's case4 targets),
tests/unit/test_dtn_liveness.py (200 random plans with awkward boundaries: every run ends,
conserves, respects the no-contention earliest arrival and the TTL) and
tests/unit/test_dtn_expected.py (the study's inputs give every figure they gave before, to the last
digit: what keeps the shortcuts below honest - the medium and the traffic nodes are event-driven,
and a node that hears only copies for other nodes before its wakeup just counts them and settles).
"""

from __future__ import annotations

import gc
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

from bringup.engine.keys import resolve_bpsec_key
from bringup.engine.local import run_local
from dtn_router.link import LinkModel
from dtn_router.router import RouterLogic
from orbit_clock.contact_plan import ContactPlan
from sat_node.dtn.agent import AgentConfig, BundleAgent
from sat_node.dtn.cgr import ContactGraph
from sat_node.dtn.multicast import new_agent
from sat_node.dtn.stats import dtn_report
from sat_node.dtn.traffic import TrafficItem, TrafficNode

__all__ = ["DtnRun", "run_dtn"]

_NS = 1_000_000_000


@dataclass
class DtnRun:
    """What a DTN-alone run leaves: the nodes' agents, the medium's link model, every bundle event
    (sat_node/dtn/agent.py BundleEvent), traffic index -> bundle id, wall time, steps."""

    agents: dict[str, BundleAgent]
    link: LinkModel
    events: list = field(default_factory=list)
    created_ids: dict = field(default_factory=dict)
    wall_s: float = 0.0
    end_ns: int = 0
    steps: int = 0
    nodes: list = field(default_factory=list)
    observations: int = 0  # traffic rows with at least one destination
    air_ns: dict = field(default_factory=dict)  # node -> time its radio was on air [ns]
    bits_on_air: dict = field(default_factory=dict)  # node -> bits it sent (recipient lists included)
    span_ns: int = 0  # the contact plan's last contact end [ns]

    def held(self) -> int:
        """(bundle, recipient) pairs still held by the agents."""
        return sum(a.held_count() for a in self.agents.values())

    def discarded(self) -> dict[str, int]:
        """Copies discarded without an event record (overheard, for another node), by reason."""
        return {"not_next_hop": sum(a.counters["discarded.not_next_hop"] for a in self.agents.values())}

    def transmissions(self) -> int:
        """Radio transmissions started by all nodes (a failed one counts; so does each relay hop; a
        multicast transmission serving several next hops is one)."""
        return sum(a.counters["forwarded"] for a in self.agents.values())

    def report(self, lower_bound_s: dict | None = None) -> dict:
        """The dtn.* figures of this run (:func:`sat_node.dtn.stats.dtn_report`, as a run's report),
        with transmissions per pair and per observation (a traffic row), the radios' busy fraction
        over the run and the bits they put on air."""
        rep = dtn_report(self.events, held=self.held(), lower_bound_s=lower_bound_s, discarded=self.discarded())
        created = rep["dtn.bundles_created"]
        rep["dtn.transmissions"] = self.transmissions()
        rep["dtn.transmissions_per_bundle"] = (rep["dtn.transmissions"] / created) if created else None
        rep["dtn.observations"] = self.observations
        rep["dtn.transmissions_per_observation"] = (rep["dtn.transmissions"] / self.observations) \
            if self.observations else None
        rep["dtn.tx_failed"] = sum(n.port.tx_failed.get(k, 0) for n in self.nodes for k in n.port.tx_failed)
        span = self.span_ns or self.end_ns  # the plan's span (its last contact end): the radios' time
        busy = [self.air_ns.get(n, 0) / span for n in self.agents] if span else []
        rep["dtn.radio_busy_fraction.mean"] = float(sum(busy) / len(busy)) if busy else None
        rep["dtn.radio_busy_fraction.max"] = max(busy) if busy else None
        rep["dtn.bits_on_air"] = sum(self.bits_on_air.values())
        return rep


def run_dtn(plan: ContactPlan, traffic: list[TrafficItem], *, config: AgentConfig | None = None,
            truth: ContactPlan | None = None, horizon_ns: int | None = None, payload_bytes: int = 160,
            max_step_s: float = 10.0, dump_dir=None, dump_count: int = 100, sink=None) -> DtnRun:
    """Run the DTN on ``plan`` (what the agents believe; ``truth``, what the medium obeys, defaults
    to it) with ``traffic``. ``dump_dir``: write the encoded bytes of the first ``dump_count``
    bundles created there (``<bundle id>.bpv7``, as they stand at creation: primary, BIB, priority,
    hop count, payload). ``sink``: called with every envelope of the run (default: none kept)."""
    t0 = time.perf_counter()
    # no config: the deployment's BPSec key (environment) or one generated for this run
    config = replace(config or AgentConfig(key=resolve_bpsec_key()[0]), settle_delay_s=None)
    if not config.bundle_bits:
        raise ValueError("run_dtn: the medium needs a fixed bundle size (AgentConfig.bundle_bits)")
    if not max_step_s > 0:
        raise ValueError(f"run_dtn: max_step_s must be > 0, got {max_step_s}")
    graph = ContactGraph(plan)
    names = sorted(set(plan.nodes) | {t.source for t in traffic} | {t.dest for t in traffic})
    events: list = []
    by_src: dict[str, list] = {n: [] for n in names}
    for i, item in enumerate(traffic):
        by_src[item.source].append((i, item))
    on_created = None
    if dump_dir is not None:
        agents_by_name: dict[str, BundleAgent] = {}
        dumped = [0]

        def on_created(index: int, bid: str) -> None:
            if dumped[0] < dump_count:
                dumped[0] += 1
                raw = agents_by_name[traffic[index].source].bundle_bytes(bid)
                if raw is not None:
                    (Path(dump_dir) / f"{bid}.bpv7").write_bytes(raw)
    nodes = [TrafficNode(new_agent(n, graph, config, on_event=events.append), by_src[n],
                         payload_bytes=payload_bytes, on_created=on_created, publish_events=sink is not None)
             for n in names]
    if dump_dir is not None:
        agents_by_name.update({n.name: n.agent for n in nodes})
    router = RouterLogic(names, truth or plan, config.bundle_bits)
    # Called only for transmissions or its wakeup (contract rule 1; most steps here are one node's
    # wakeup): a step with neither emits nothing and keeps its wakeup (its next arrival or report).
    router.event_driven = True
    if horizon_ns is None:
        last_s = max([c.end_s for c in plan.contacts] + [t.t_s for t in traffic] + [0.0])
        horizon_ns = int(last_s * _NS) + int(max(config.ttl_s_by_priority.values()) * _NS)
    # The run allocates millions of short-lived objects and makes next to no reference cycles: the
    # cyclic collector's young passes (each over the ~50k objects the engine lets accumulate, ~30 ms)
    # are ~5 % of the run and free almost nothing. It is off during the run (reference counting still
    # frees everything that is not a cycle) and as it was after it; nothing in the run depends on
    # when garbage is freed.
    gc_was_on = gc.isenabled()
    gc.disable()
    try:
        res = run_local([*nodes, router], horizon_ns=horizon_ns, max_step_ns=max(1, int(round(max_step_s * _NS))),
                        sink=sink or _discard, sink_many=None if sink else _discard)  # the report's events: the agents'
    finally:
        if gc_was_on:
            gc.enable()
    created_ids: dict[int, str] = {}
    for n in nodes:
        created_ids.update(n.created_ids)
    n_obs = len({(traffic[i].source, traffic[i].row, traffic[i].t_s) for i in created_ids})
    return DtnRun({n.name: n.agent for n in nodes}, router.link, events, created_ids,
                  time.perf_counter() - t0, horizon_ns, res.steps, nodes, n_obs,
                  dict(router.link.air_ns), dict(router.link.bits_sent),
                  int(max((c.end_s for c in plan.contacts), default=0.0) * _NS))


def _discard(_envelopes) -> None:
    return None
