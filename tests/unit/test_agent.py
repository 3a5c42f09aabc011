"""Bundle agents stepped by hand on a drawn plan (rate 1000 b/s, 2000-bit bundles = 2 s on air).

   sat_11 --[0;100]--> sat_12 --[50;200]--> sat_13      (and the reverse contacts)
"""

from orbit_clock.contact_plan import Contact, ContactPlan
from sat_node.dtn.agent import AgentConfig, BundleAgent
from tests.keys import TEST_BPSEC_KEY

S = 10**9
PLAN = ContactPlan([Contact(0.0, 100.0, "sat_11", "sat_12", 1000.0, 0.0),
                    Contact(0.0, 100.0, "sat_12", "sat_11", 1000.0, 0.0),
                    Contact(50.0, 200.0, "sat_12", "sat_13", 1000.0, 0.5),
                    Contact(50.0, 200.0, "sat_13", "sat_12", 1000.0, 0.5)])


def agents(**kw):
    cfg = AgentConfig(**{"key": TEST_BPSEC_KEY, **kw})
    return {n: BundleAgent(n, PLAN, cfg) for n in ("sat_11", "sat_12", "sat_13")}


def test_two_hop_delivery_priority_order_and_events():
    a = agents()
    low = a["sat_11"].originate(b"low", "sat_13", 9, 10 * S)
    high = a["sat_11"].originate(b"high", "sat_13", 1, 10 * S)
    txs = a["sat_11"].transmissions_until(10 * S)
    assert [t.bundle_id for t in txs] == [high]  # one radio: the second waits for the first
    txs += a["sat_11"].transmissions_until(12 * S)
    assert [t.bundle_id for t in txs] == [high, low] and [t.start_ns for t in txs] == [10 * S, 12 * S]
    assert all(t.next_hop == "sat_12" for t in txs)
    for t in txs:
        assert a["sat_13"].receive(t.bundle_bytes, "sat_11", t.end_ns) == "discarded.not_next_hop"
        assert a["sat_12"].receive(t.bundle_bytes, "sat_11", t.end_ns) == "queued"
    assert a["sat_12"].next_event_ns() == 50 * S  # waits for the contact to sat_13
    relay = a["sat_12"].transmissions_until(60 * S)
    assert [(t.bundle_id, t.start_ns) for t in relay] == [(high, 50 * S), (low, 52 * S)]
    for t in relay:
        assert a["sat_13"].receive(t.bundle_bytes, "sat_12", t.end_ns + S // 2) == "delivered"
    assert a["sat_13"].receive(relay[0].bundle_bytes, "sat_12", 70 * S) == "discarded.duplicate"
    kinds = [(e.kind, e.node) for e in a["sat_13"].events]
    assert kinds.count(("delivered", "sat_13")) == 2
    d = [e for e in a["sat_13"].events if e.kind == "delivered"]
    assert d[0].t_ns - d[0].created_ns == 42 * S + S // 2


def test_ttl_drop_and_conservation():
    a = agents(ttl_s_by_priority={1: 30.0, 15: 30.0})
    a["sat_11"].originate(b"x", "sat_13", 1, 0)  # earliest arrival 52.5 s > 30 s lifetime: no route
    assert a["sat_11"].counters["dropped.no_route"] == 1
    a = agents(ttl_s_by_priority={1: 60.0, 15: 60.0})
    a["sat_11"].originate(b"x", "sat_13", 1, 0)
    t = a["sat_11"].transmissions_until(0)[0]
    assert a["sat_12"].receive(t.bundle_bytes, "sat_11", t.end_ns) == "queued"
    a["sat_12"].expire(61 * S)  # it was due at 50 s but 60 s is its lifetime: sending at 50 still fits
    assert a["sat_12"].counters["dropped.ttl"] == 1 and a["sat_12"].held_count() == 0


def test_integrity_and_malformed_are_dropped():
    a = agents()
    a["sat_11"].originate(b"payload", "sat_12", 1, 0)
    t = a["sat_11"].transmissions_until(0)[0]
    bad = bytearray(t.bundle_bytes)
    bad[-3] ^= 0x01  # inside the payload
    assert a["sat_12"].receive(bytes(bad), "sat_11", 3 * S) == "dropped.integrity"
    assert a["sat_12"].receive(b"\x9f\x00", "sat_11", 3 * S) == "dropped.integrity"
    other = BundleAgent("sat_12", PLAN, AgentConfig(key=b"another constellation key"))
    assert other.receive(t.bundle_bytes, "sat_11", 3 * S) == "dropped.integrity"
    assert a["sat_12"].receive(t.bundle_bytes, "sat_11", 3 * S) == "delivered"


def test_missed_contact_reroutes_and_failed_transmission_returns():
    a = agents()
    b1 = a["sat_11"].originate(b"x", "sat_12", 1, 99 * S - S // 2)  # 98.5-100.5 would overrun the contact
    assert a["sat_11"].transmissions_until(100 * S) == []
    assert a["sat_11"].counters["dropped.no_route"] == 1
    a = agents()
    b1 = a["sat_11"].originate(b"x", "sat_12", 1, 10 * S)
    tx = a["sat_11"].transmissions_until(10 * S)[0]
    a["sat_11"].transmission_failed(tx, 10 * S)
    # the only contact to sat_12 was excluded after the failure: nothing else reaches it
    assert a["sat_11"].counters["tx_failed"] == 1 and a["sat_11"].counters["dropped.no_route"] == 1
    assert b1 == tx.bundle_id


def test_deadline_queue_sends_the_earliest_expiry_first():
    """Strict priority sends a new P1 before an older P9; earliest-expiry-first ('deadline' queue:
    priority_delay_s = each priority's TTL) sends the P9 first when it expires sooner, and the P1
    first when the P1 expires sooner."""
    from sat_node.dtn.agent import deadline_delays
    assert deadline_delays({1: 900.0, 3: 1800.0, 15: 3000.0}) == (900.0, 1800.0, 1800.0) + (3000.0,) * 12
    ttl = {1: 30.0, 3: 60.0, 15: 100.0}
    for delays, p1_created_s, first in ((None, 75, "new"), (deadline_delays(ttl), 75, "old"),
                                        (deadline_delays(ttl), 65, "new")):
        a = agents(ttl_s_by_priority=ttl, priority_delay_s=delays)
        a["sat_12"].radio_free_ns = 80 * S  # busy until 80 s: both wait for the same decision
        ids = {"old": a["sat_12"].originate(b"old", "sat_11", 9, 0),  # expires at 100 s
               "new": a["sat_12"].originate(b"new", "sat_11", 1, p1_created_s * S)}  # at 105 s or 95 s
        order = [t.bundle_id for t in a["sat_12"].transmissions_until(90 * S)]
        other = "old" if first == "new" else "new"
        assert order == [ids[first], ids[other]], (delays, p1_created_s)


def test_shared_route_memo_respects_each_deadline():
    """Bundles that route alike at one instant share a CGR answer (agent._route), but only where
    the answer holds under their own deadline. On this plan the route to sat_13 arrives at 52.5 s:
    a bundle with a 60 s lifetime gets it, one with 30 s has none (and is dropped no_route) whether
    it comes before or after the other at the same instant."""
    cfg = {"ttl_s_by_priority": {1: 30.0, 15: 60.0}}
    for order in ((9, 1), (1, 9)):
        a = agents(**cfg)["sat_11"]
        out = [a.originate(b"x", "sat_13", p, 0) and a.counters["dropped.no_route"] for p in order]
        assert a.counters["dropped.no_route"] == 1, order
        assert a.held_count() == 1, order
        assert out == ([0, 1] if order == (9, 1) else [1, 1])
