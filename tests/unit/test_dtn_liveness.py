"""Liveness and physics of the DTN alone (bringup/analysis/dtn_alone.py) on random small plans with
awkward boundaries.

Oracle: every run ends (a per-test timeout), conserves bundles (created = delivered + dropped + held),
never delivers a bundle before its earliest arrival over the plan with transmission and light time
and no contention (ContactGraph.earliest_arrivals; CGR is checked against a brute force over every
simple path in test_cgr_random.py), and never after its TTL. Contact ends, creation times and transmission ends are drawn to land on or near
each other: a transmission whose rounded end passes the contact's end must not make an agent re-try
the same route forever."""

import random

import pytest

from bringup.analysis.dtn_alone import run_dtn
from orbit_clock.contact_plan import Contact, ContactPlan
from sat_node.dtn.agent import AgentConfig, deadline_delays, ttl_s_for_priority
from sat_node.dtn.cgr import ContactGraph
from sat_node.dtn.traffic import TrafficItem
from tests.keys import TEST_BPSEC_KEY


def _case(seed: int):
    rng = random.Random(seed)
    nodes = [f"sat_{p}{s}" for p in (1, 2) for s in (1, 2, 3)][: rng.randint(2, 6)]
    rate = rng.choice([500.0, 1000.0, 3000.0, 4000.0, 7919.0])
    contacts = []
    for _ in range(rng.randint(1, 12)):
        a, b = rng.sample(nodes, 2)
        t0 = round(rng.uniform(0, 200), rng.choice([0, 1, 2, 3, 6]))
        dur = rng.choice([0.5, 1.0, 2.0, rng.uniform(0.1, 5), rng.uniform(5, 200)])
        light = rng.choice([0.0, 0.5, rng.uniform(0, 2)])
        contacts.append(Contact(t0, t0 + dur, a, b, rate, light))
        if rng.random() < 0.7:
            contacts.append(Contact(t0, t0 + dur, b, a, rate, light))
    traffic = []
    for k in range(rng.randint(1, 25)):
        s, d = rng.sample(nodes, 2)
        c = rng.choice(contacts)
        t = rng.choice([rng.uniform(0, 250), c.start_s, c.end_s, c.end_s - 0.5, c.end_s - 2000 / rate,
                        c.start_s + rng.uniform(0, 1)])
        traffic.append(TrafficItem(max(0.0, t), s, d, rng.randint(1, 15), f"p{k}", "r", k))
    traffic.sort(key=lambda i: i.t_s)
    ttl = {1: rng.choice([5.0, 60.0, 900.0]), 3: 1800.0, 15: 3000.0}
    config = AgentConfig(key=TEST_BPSEC_KEY, ttl_s_by_priority=ttl, bundle_bits=2000,
                         priority_delay_s=deadline_delays(ttl) if rng.random() < 0.3 else None,
                         hop_tolerance_s=rng.choice([0.0, 0.0, 5.0]))
    return ContactPlan(contacts), traffic, config


@pytest.mark.timeout(120)
@pytest.mark.parametrize("block", range(4))
def test_random_plans_end_conserve_and_respect_physics(block):
    for seed in range(block * 50, block * 50 + 50):
        plan, traffic, config = _case(seed)
        run = run_dtn(plan, traffic, config=config)
        rep = run.report()
        assert rep["dtn.conservation_ok"] and rep["dtn.bundles_created"] == len(traffic), seed
        graph = ContactGraph(plan)
        index = {bid: i for i, bid in run.created_ids.items()}
        for e in run.events:
            if e.kind != "delivered":
                continue
            item = traffic[index[e.bundle_id]]
            latency = e.t_ns / 1e9 - item.t_s
            earliest = graph.earliest_arrivals(item.source, item.t_s, 2000).get(item.dest, float("inf"))
            assert latency >= earliest - item.t_s - 1e-6, (seed, e)
            assert latency <= ttl_s_for_priority(item.priority, config.ttl_s_by_priority) + 1e-6, (seed, e)
