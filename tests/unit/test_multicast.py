"""Multicast forwarding (sat_node/dtn/multicast.py) on drawn plans stepped by hand, and on random plans
against an independent brute force of each recipient's earliest arrival. Rate 1000 b/s: a 2000-bit
bundle is 2 s on air, plus its recipient list (routing_blocks.overhead_bits)."""

import itertools
import random

import pytest

from bringup.analysis.dtn_alone import run_dtn
from orbit_clock.contact_plan import Contact, ContactPlan
from sat_node.dtn.agent import AgentConfig
from sat_node.dtn.bpv7 import decode_bundle
from sat_node.dtn.multicast import MulticastAgent
from sat_node.dtn.routing_blocks import next_hops_of, overhead_bits
from sat_node.dtn.traffic import TrafficItem
from tests.keys import TEST_BPSEC_KEY

S = 10**9


def _plan(links):
    cs = []
    for a, b, t0, t1 in links:
        cs += [Contact(t0, t1, a, b, 1000.0, 0.0), Contact(t0, t1, b, a, 1000.0, 0.0)]
    return ContactPlan(cs)


#        sat_12 --[0;300]-- sat_14            sat_11 hears sat_12 and sat_13 during [0;100]
#       /                                      (case "in view"), or sat_13 only from 50 s
# sat_11                                       (case "not in view").
#       \
#        sat_13
def _drawn(sat13_from: float):
    return _plan([("sat_11", "sat_12", 0, 100), ("sat_11", "sat_13", sat13_from, 100), ("sat_12", "sat_14", 0, 300)])


def _agents(plan, **kw):
    cfg = AgentConfig(**{"key": TEST_BPSEC_KEY, **kw})
    return {n: MulticastAgent(n, plan, cfg) for n in ("sat_11", "sat_12", "sat_13", "sat_14")}


def _hear(agents, tx, exclude=()):
    """Every node in view gets the copy (the medium's broadcast); returns {node: outcome}."""
    return {n: a.receive(tx.bundle_bytes, tx.sender, tx.end_ns) for n, a in agents.items()
            if n != tx.sender and n not in exclude}


def test_three_recipients_behind_two_next_hops_in_view_take_one_transmission():
    a = _agents(_drawn(0.0))
    bid = a["sat_11"].originate_many(b"obs", [("sat_12", 1), ("sat_14", 2), ("sat_13", 3)], 10 * S)
    txs = a["sat_11"].transmissions_until(30 * S)
    assert len(txs) == 1 and txs[0].next_hops == ("sat_12", "sat_13")
    split = next_hops_of(decode_bundle(txs[0].bundle_bytes))
    assert split == {12: (12, 14), 13: (13,)}  # sat_12 carries sat_14's copy on
    assert txs[0].end_ns == 10 * S + (2000 + overhead_bits(txs[0].bundle_bytes)) * 10**6
    got = _hear(a, txs[0], exclude=("sat_14",))  # sat_14 is not in view of sat_11
    assert got == {"sat_12": "delivered", "sat_13": "delivered"}
    assert a["sat_12"].held_pairs() == {(bid, "sat_14")} and a["sat_13"].held_pairs() == set()
    relay = a["sat_12"].transmissions_until(30 * S)
    assert len(relay) == 1 and relay[0].next_hops == ("sat_14",)
    assert a["sat_14"].receive(relay[0].bundle_bytes, "sat_12", relay[0].end_ns) == "delivered"
    for n in a:
        for tx in (txs if n == "sat_11" else relay if n == "sat_12" else ()):
            assert a[n].settle(tx)
    assert sum(x.held_count() for x in a.values()) == 0


def test_next_hops_not_in_view_together_take_two_transmissions():
    a = _agents(_drawn(50.0))
    a["sat_11"].originate_many(b"obs", [("sat_12", 1), ("sat_14", 2), ("sat_13", 3)], 10 * S)
    first = a["sat_11"].transmissions_until(30 * S)
    assert [t.next_hops for t in first] == [("sat_12",)]
    assert a["sat_11"].held_count() == 3  # two in flight (sat_12, sat_14 via sat_12), sat_13 waits
    assert a["sat_11"].settle(first[0]) and a["sat_11"].held_count() == 1
    assert a["sat_11"].next_event_ns() <= 50 * S  # parked until the contact to sat_13 opens
    second = a["sat_11"].transmissions_until(60 * S)
    assert [(t.next_hops, t.start_ns) for t in second] == [(("sat_13",), 50 * S)]
    assert overhead_bits(second[0].bundle_bytes) < overhead_bits(first[0].bundle_bytes)  # a shorter list


def test_per_recipient_deadlines_and_a_receiver_that_is_not_a_next_hop():
    """sat_14's copy must wait for sat_12's contact to sat_14 (from 200 s); with a 100 s lifetime for
    priority 2 it cannot arrive in time and is dropped at the source (no route), the others go. sat_13
    hears the transmission to sat_12 but is no next hop of it: it discards the copy."""
    plan = _plan([("sat_11", "sat_12", 0, 100), ("sat_11", "sat_13", 0, 100), ("sat_12", "sat_14", 200, 300)])
    a = _agents(plan, ttl_s_by_priority={1: 500.0, 2: 100.0, 15: 500.0})
    bid = a["sat_11"].originate_many(b"obs", [("sat_12", 1), ("sat_14", 2)], 10 * S)
    txs = a["sat_11"].transmissions_until(30 * S)
    assert [t.next_hops for t in txs] == [("sat_12",)]
    drops = [(e.dest, e.reason) for e in a["sat_11"].events if e.kind == "dropped"]
    assert drops == [("sat_14", "no_route")]
    assert a["sat_13"].overheard(txs[0].bundle_bytes, txs[0].end_ns)
    assert a["sat_13"].receive(txs[0].bundle_bytes, "sat_11", txs[0].end_ns) == "discarded.not_next_hop"
    assert a["sat_12"].receive(txs[0].bundle_bytes, "sat_11", txs[0].end_ns) == "delivered"
    assert a["sat_12"].receive(txs[0].bundle_bytes, "sat_11", txs[0].end_ns + S) == "discarded.duplicate"
    created = {e.dest: e.deadline_ns for e in a["sat_11"].events if e.kind == "created"}
    assert created == {"sat_12": 510 * S, "sat_14": 110 * S}
    assert all(e.bundle_id == bid for e in a["sat_11"].events)


def test_queued_recipient_expires_and_bundle_ranks_by_most_urgent_recipient():
    """A bundle held for a P9 and a P2 recipient goes before one held for a P3 only; when its P2
    recipient is gone (deadline), it ranks by the P9 one."""
    plan = _plan([("sat_11", "sat_12", 100, 200), ("sat_11", "sat_13", 100, 200)])
    a = _agents(plan, ttl_s_by_priority={1: 1000.0, 2: 50.0, 15: 1000.0})
    b3 = a["sat_11"].originate_many(b"x", [("sat_12", 3)], 0)
    b29 = a["sat_11"].originate_many(b"y", [("sat_13", 9), ("sat_12", 2)], 0)
    txs = a["sat_11"].transmissions_until(150 * S)
    # P2: deadline 50 s, no contact before 100 s: dropped at the first decision (t = 0)
    assert [(e.reason, e.dest, e.t_ns) for e in a["sat_11"].events if e.kind == "dropped"] == [("no_route", "sat_12", 0)]
    assert [t.bundle_id for t in txs] == [b3, b29]


def test_failed_next_hop_takes_its_recipients_back():
    a = _agents(_plan([("sat_11", "sat_12", 0, 100), ("sat_11", "sat_13", 0, 100), ("sat_12", "sat_13", 0, 100)]))
    a["sat_11"].originate_many(b"obs", [("sat_12", 1), ("sat_13", 3)], 10 * S)
    tx = a["sat_11"].transmissions_until(10 * S)[0]
    assert tx.next_hops == ("sat_12", "sat_13")
    a["sat_11"].transmission_failed(tx, tx.end_ns, "sat_13")  # the medium: sat_13 missed it
    assert a["sat_11"].held_pairs() == {(tx.bundle_id, "sat_12"), (tx.bundle_id, "sat_13")}
    again = a["sat_11"].transmissions_until(tx.end_ns)
    # the failed contact is excluded: sat_13 is reached via sat_12 now
    assert [t.next_hops for t in again] == [("sat_12",)]
    assert next_hops_of(decode_bundle(again[0].bundle_bytes)) == {12: (13,)}
    # (settle_delay_s = 0: the first transmission was settled at its end; sat_12's recipient is gone)
    assert a["sat_11"].settle(tx) is False and a["sat_11"].held_pairs() == {(tx.bundle_id, "sat_13")}


# ---------------------------------------------------------------------- random plans vs brute force
def _earliest_by_brute_force(plan: ContactPlan, src: str, t0: float, bits: float) -> dict[str, float]:
    """Earliest arrival at every node over every simple path of contacts (no queues, no volumes):
    an enumeration independent of CGR's label search."""
    best: dict[str, float] = {}
    out: dict[str, list] = {}
    for c in plan.contacts:
        out.setdefault(c.src, []).append(c)

    def walk(node, t, seen):
        for c in out.get(node, ()):
            if c.dst in seen:
                continue
            start = max(t, c.start_s)
            end = start + bits / c.rate_bps
            if end > c.end_s:
                continue
            arr = end + c.range_light_s
            if arr < best.get(c.dst, float("inf")):
                best[c.dst] = arr
            walk(c.dst, arr, seen | {c.dst})

    walk(src, t0, {src})
    return best


@pytest.mark.parametrize("seed", range(25))
def test_random_plans_multicast_never_later_than_unicast_on_an_empty_network(seed):
    """One observation on an empty network (nothing else queued): every recipient multicast delivers
    arrives no earlier than its brute-force earliest arrival and no later than unicast delivers it
    (up to the air time of the recipient list on each of its hops), unicast reaches none that
    multicast does not, and both conserve their pairs."""
    rng = random.Random(seed)
    nodes = [f"sat_{p}{s}" for p in (1, 2) for s in (1, 2, 3)]
    links = []
    for _ in range(rng.randint(4, 12)):
        a, b = rng.sample(nodes, 2)
        t0 = rng.uniform(0, 300)
        links.append((a, b, round(t0, 1), round(t0 + rng.uniform(5, 300), 1)))
    plan = _plan(links)
    src = rng.choice(nodes)
    dests = rng.sample([n for n in nodes if n != src], rng.randint(1, 5))
    t_s = round(rng.uniform(0, 200), 1)
    traffic = [TrafficItem(t_s, src, d, k, "p0", "r", 2) for k, d in enumerate(dests, start=1)]
    ttl = {15: 1000.0}
    got = {}
    for fwd in ("unicast", "multicast"):
        run = run_dtn(plan, traffic, config=AgentConfig(key=TEST_BPSEC_KEY, ttl_s_by_priority=ttl, forwarding=fwd))
        rep = run.report()
        assert rep["dtn.conservation_ok"] and rep["dtn.bundles_created"] == len(dests), (seed, fwd)
        got[fwd] = {e.dest: e.t_ns / S for e in run.events if e.kind == "delivered"}
        if fwd == "multicast":
            assert rep["dtn.bundles_originated"] == 1
    ea = _earliest_by_brute_force(plan, src, t_s, 2000)
    slack = (len(nodes) - 1) * 8 * 64 / 1000.0  # every hop's recipient list, at most 64 bytes here
    for d, t in got["multicast"].items():
        assert t >= ea[d] - 1e-6, (seed, d)
    for d, t in got["unicast"].items():
        assert t >= ea[d] - 1e-6, (seed, d)
        assert d in got["multicast"], (seed, d, "unicast delivered, multicast did not")
        assert got["multicast"][d] <= t + slack, (seed, d, got)
    assert len(got["multicast"]) >= len(got["unicast"])


def test_brute_force_agrees_with_itself_on_a_chain():
    plan = _plan([("sat_11", "sat_12", 0, 100), ("sat_12", "sat_13", 50, 100)])
    assert _earliest_by_brute_force(plan, "sat_11", 10.0, 2000) == pytest.approx({"sat_12": 12.0, "sat_13": 52.0})
    assert list(itertools.islice(iter(()), 1)) == []


def test_a_copy_accepted_unverified_is_still_verified_by_the_next_agent():
    """The agents of one process decode and verify each transmission once (multicast._VERIFIED):
    a copy whose payload was altered, accepted by an agent that does not verify, is still refused
    by one that does, and by one with another key, while an unaltered copy reaches both."""
    plan = _drawn(0.0)
    src = MulticastAgent("sat_11", plan, AgentConfig(key=TEST_BPSEC_KEY))
    src.originate_many(b"observation", [("sat_12", 1), ("sat_13", 2)], 10 * S)
    tx = src.transmissions_until(30 * S)[0]
    i = tx.bundle_bytes.index(b"observation")
    bad = tx.bundle_bytes[:i] + b"O" + tx.bundle_bytes[i + 1:]
    lax = MulticastAgent("sat_12", plan, AgentConfig(key=TEST_BPSEC_KEY, verify_integrity=False))
    strict = MulticastAgent("sat_13", plan, AgentConfig(key=TEST_BPSEC_KEY))
    other = MulticastAgent("sat_13", plan, AgentConfig(key=bytes(32)))
    assert lax.receive(bad, "sat_11", tx.end_ns) == "delivered"
    assert strict.receive(bad, "sat_11", tx.end_ns) == "dropped.integrity"
    assert strict.receive(tx.bundle_bytes, "sat_11", tx.end_ns) == "delivered"
    assert other.receive(tx.bundle_bytes, "sat_11", tx.end_ns) == "dropped.integrity"
