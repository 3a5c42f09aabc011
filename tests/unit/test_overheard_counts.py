"""The ISL medium's overheard copies sent as counts (dtn_router/router.py ``overheard``,
sat_node/dtn/overhearing.py, msgs_json CopiesOverheard on /sat_XX/dtn/overheard).

Oracles: each agent's own ``overheard`` (the per-copy path) for the rule, and a whole run of the
medium that sends every copy (the path it replaces) for the rest: the same run with counts gives
every other message identical, the receivers the same counters, and the copies it still sends are,
message by message, the old run's copies less those the receiver only counted.
"""

from __future__ import annotations

import random
import re

import pytest

from bringup.engine.local import run_local
from bringup.scenario.participants import all_participants
from bringup.scenario.world import World
from dtn_router.router import RouterLogic
from msgs_json import codec
from msgs_json import topics as T
from msgs_json.envelope import Envelope
from orbit_clock.contact_plan import Contact, ContactPlan, node_number
from sat_node.dtn.agent import AgentConfig
from sat_node.dtn.bpv7 import Bundle, encode_bundle, ipn
from sat_node.dtn.multicast import new_agent
from sat_node.dtn.overhearing import only_counted
from sat_node.dtn.port import DtnPort
from sat_node.dtn.routing_blocks import NEXT_HOPS_BLOCK, encode_next_hops, peek_next_hops
from tests.keys import TEST_BPSEC_KEY

SATS = ["sat_11", "sat_12", "sat_13", "sat_21", "sat_22"]


def _copy(next_hops: tuple[int, ...]) -> bytes:
    b = Bundle(dest=ipn(21, 1), src=ipn(12, 1), creation_ms=1000, seq=3, lifetime_ms=900_000, payload=b"x" * 8)
    if next_hops:
        b.set_block(NEXT_HOPS_BLOCK, encode_next_hops({nh: (21,) for nh in next_hops}))
    return encode_bundle(b)


@pytest.mark.parametrize("forwarding", ["multicast", "unicast"])
def test_only_counted_is_what_each_agent_only_counts(forwarding):
    plan = ContactPlan([Contact(0.0, 100.0, "sat_11", "sat_12", 1000.0, 0.01)])
    rng = random.Random(5)
    cases = [()] + [tuple(sorted(rng.sample([11, 12, 13, 21, 22], rng.randint(1, 3)))) for _ in range(60)]
    seen = set()
    for nhs in cases:
        data = _copy(nhs)
        assert peek_next_hops(data) == nhs
        for node in SATS:
            agent = new_agent(node, plan, AgentConfig(key=TEST_BPSEC_KEY, settle_delay_s=None, bundle_bits=2000,
                                                       forwarding=forwarding))
            got = agent.overheard(data, 5)
            assert only_counted(forwarding, nhs, node_number(node)) is got, (forwarding, nhs, node)
            seen.add(got)
    assert seen == {True, False}


def test_only_counted_refuses_an_unknown_forwarding():
    with pytest.raises(ValueError, match="forwarding 'flood'"):
        only_counted("flood", (11,), 12)
    with pytest.raises(ValueError, match="overheard='flood'"):
        RouterLogic(SATS, ContactPlan([]), 2000, overheard="flood")


def test_a_port_counts_a_count_as_that_many_copies_and_rejects_another_nodes():
    plan = ContactPlan([Contact(0.0, 100.0, "sat_11", "sat_12", 1000.0, 0.01)])
    ports = [DtnPort("sat_13", new_agent("sat_13", plan, AgentConfig(key=TEST_BPSEC_KEY, settle_delay_s=None,
                                                                      bundle_bits=2000, forwarding=fw)))
             for fw in ("multicast", "multicast", "unicast")]
    one, many, uni = ports
    for _ in range(7):
        one.receive(Envelope(10, "dtn_router", 0, T.dtn_in_topic("sat_13"), _copy((11,))), 20)
    msg = codec.encode(codec.decode(T.dtn_overheard_topic("sat_13"),
                                    '{"v":1,"sat":"sat_13","t_ns":10,"copies":7}'))
    for p in (many, uni):
        assert p.receive(Envelope(10, "dtn_router", 0, T.dtn_overheard_topic("sat_13"), msg), 20) is None
    for p in ports:
        assert p.overheard == 7 and p.agent.counters["discarded.not_next_hop"] == 7
        assert p.counters(rejected=0, rejected_by_reason={}) == one.counters(rejected=0, rejected_by_reason={})
    other = '{"v":1,"sat":"sat_12","t_ns":10,"copies":2}'
    with pytest.raises(ValueError, match="sat_12 on sat_13"):
        many.receive(Envelope(10, "dtn_router", 1, T.dtn_overheard_topic("sat_13"), other), 20)
    with pytest.raises(ValueError):  # no count of zero copies
        many.receive(Envelope(10, "dtn_router", 1, T.dtn_overheard_topic("sat_13"),
                              '{"v":1,"sat":"sat_13","t_ns":10,"copies":0}'), 20)
    assert many.overheard == 7


def _run(world, sc, overheard: str | None):
    parts = all_participants(world, "distributed", bpsec_key=TEST_BPSEC_KEY)
    i = next(k for k, p in enumerate(parts) if isinstance(p, RouterLogic))
    assert parts[i].overheard == sc.isl.forwarding  # what a run uses
    parts[i] = RouterLogic(parts[i].sats, parts[i].link.truth, parts[i].bits, overheard=overheard)
    res = run_local(parts, horizon_ns=sc.horizon_ns, max_step_ns=int(sc.scenario.lockstep_max_step_s * 1e9))
    return parts, res


def _plain(e: Envelope):
    # (the planners' own CPU seconds, in their schedules, differ from run to run)
    data = re.sub(r'"(\w*cpu\w*)":[-+0-9.eE]+', r'"\1":0', e.data) if isinstance(e.data, str) else e.data
    return e.t_ns, e.source, e.topic, data


@pytest.mark.parametrize("forwarding", ["multicast", "unicast"])
def test_a_run_with_counts_equals_the_run_with_every_copy(paper_scenario, forwarding):
    sc = paper_scenario.with_overrides(sats=96, planes=6, hours=0.25, forwarding=forwarding)
    world = World.build(sc)
    old_parts, old = _run(world, sc, None)
    new_parts, new = _run(world, sc, forwarding)
    router = "dtn_router"
    # every message of a node other than the medium: identical, message by message, seq included
    assert [(*_plain(e), e.seq) for e in old.envelopes if e.source != router] == \
        [(*_plain(e), e.seq) for e in new.envelopes if e.source != router]
    # the medium: its copies less those only counted, its status reports, and the counts
    numbers = {s: node_number(s) for s in world.sat_names}
    kept, counted = [], {}
    for e in old.envelopes:
        if e.source != router:
            continue
        recv = T.sat_of_topic(e.topic)
        if e.topic.endswith("/dtn/in") and only_counted(forwarding, peek_next_hops(e.data), numbers[recv]):
            counted.setdefault(recv, []).append(e.t_ns)
        else:
            kept.append(_plain(e))
    new_router = [e for e in new.envelopes if e.source == router]
    assert [_plain(e) for e in new_router if not e.topic.endswith("/dtn/overheard")] == kept
    got = {}
    for e in new_router:
        if e.topic.endswith("/dtn/overheard"):
            m = codec.decode(e.topic, e.data)
            assert m.sat == T.sat_of_topic(e.topic) and m.t_ns == e.t_ns
            got.setdefault(m.sat, []).append((m.t_ns, m.copies))
    assert sum(n for v in got.values() for _t, n in v) == sum(len(v) for v in counted.values()) > 1000
    medium = next(p for p in new_parts if isinstance(p, RouterLogic))
    assert medium.copies_counted == sum(len(v) for v in counted.values())
    # each count stands for the copies of one step: stamped with the latest of them, the same total per receiver
    for sat, arrivals in counted.items():
        assert sum(n for _t, n in got[sat]) == len(arrivals)
        assert {t for t, _n in got[sat]} <= set(arrivals)
    # the receivers end with the same counters (and so report the same DtnCounters)
    for a, b in zip(old_parts, new_parts):
        if getattr(a, "port", None) is not None:
            assert a.port.overheard == b.port.overheard
            assert a.agent.counters == b.agent.counters
    assert sum(p.port.overheard for p in new_parts if getattr(p, "port", None) is not None) > 1000
    assert sum(new.counts_by_topic.values()) < sum(old.counts_by_topic.values())
