"""CGR on small drawn plans with hand-worked routes and arrival times (rate 1 bit/s, 2-bit bundles:
every hop takes 2 s; light time 1 s unless drawn otherwise)."""

import numpy as np
import pytest

from orbit_clock.contact_plan import Contact, ContactPlan
from sat_node.dtn.cgr import ContactGraph


def C(a, b, t0, t1, owlt=1.0, rate=1.0):
    return Contact(float(t0), float(t1), f"sat_{a}", f"sat_{b}", rate, owlt)


# sat_11 = A, sat_12 = B, sat_13 = C, sat_14 = D
#
#        [0;10]       [20;30]
#   A ----------> B ----------> D          A->B->D: 0-2 (+1) at B 3, waits to 20, 20-22 (+1) = 23
#   |                           ^
#   | [0;10]      [4;10]        |          A->C->D: 0-2 (+1) at C 3, 4-6 (+1) = 7   <- best
#   +-----------> C ------------+
#   A ---------------[50;60]--> D          direct: 50-52 (+1) = 53
PLAN1 = ContactPlan([C(11, 12, 0, 10), C(12, 14, 20, 30), C(11, 13, 0, 10), C(13, 14, 4, 10), C(11, 14, 50, 60)])


def _names(g, route):
    return [(g.contacts[c].src, g.contacts[c].dst) for c in route.contacts]


def test_earliest_arrival_takes_the_two_hop_route():
    g = ContactGraph(PLAN1)
    r = g.route("sat_11", "sat_14", 0.0, 2)
    assert _names(g, r) == [("sat_11", "sat_13"), ("sat_13", "sat_14")]
    assert r.next_hop == "sat_13"
    assert r.arrival_s == pytest.approx(7.0)


def test_backlog_delays_first_hop_and_changes_route():
    # 6 bits queued ahead: A->C 6-8, at C 9, C->D would end at 11 > 10: fails; via B: 6-8, 9, 20-22, 23
    g = ContactGraph(PLAN1)
    r = g.route("sat_11", "sat_14", 0.0, 2, backlog_bits=6)
    assert _names(g, r) == [("sat_11", "sat_12"), ("sat_12", "sat_14")]
    assert r.arrival_s == pytest.approx(23.0)


def test_residual_volume_excluded_nodes_and_deadline():
    g = ContactGraph(PLAN1)
    residual = g.volume_bits.copy()
    residual[[i for i, c in enumerate(g.contacts) if (c.src, c.dst) == ("sat_13", "sat_14")][0]] = 1.0
    assert g.route("sat_11", "sat_14", 0.0, 2, residual_bits=residual).arrival_s == pytest.approx(23.0)
    assert g.route("sat_11", "sat_14", 0.0, 2, excluded_nodes=("sat_13",)).arrival_s == pytest.approx(23.0)
    assert g.route("sat_11", "sat_14", 0.0, 2, deadline_s=6.9) is None
    excl = np.zeros(len(g.contacts), dtype=bool)
    excl[[i for i, c in enumerate(g.contacts) if c.src == "sat_11" and c.dst != "sat_14"]] = True
    r = g.route("sat_11", "sat_14", 0.0, 2, excluded=excl)
    assert _names(g, r) == [("sat_11", "sat_14")] and r.arrival_s == pytest.approx(53.0)
    # an excluded contact past the first hop (the relay scan's own reading of the mask) as the
    # residual volume above: the route via sat_12
    relay = np.zeros(len(g.contacts), dtype=bool)
    relay[[i for i, c in enumerate(g.contacts) if (c.src, c.dst) == ("sat_13", "sat_14")]] = True
    assert g.route("sat_11", "sat_14", 0.0, 2, excluded=relay).arrival_s == pytest.approx(23.0)


def test_later_start_time_and_contact_too_short():
    g = ContactGraph(PLAN1)
    # at t=9 nothing fits before 10 (9-11): the only way is the direct contact at 50
    assert g.route("sat_11", "sat_14", 9.0, 2).arrival_s == pytest.approx(53.0)
    # a 1.5 s contact cannot carry a 2 s bundle
    g2 = ContactGraph(ContactPlan([C(11, 12, 0, 1.5)]))
    assert g2.route("sat_11", "sat_12", 0.0, 2) is None


#   A --[5;10]--> D                          direct: 5-7 (+1) = 8
#   A --[0;10]--> C --[5;10]--> D            5-7 (+1) = 8 too: same arrival, fewer hops wins
def test_tie_on_arrival_fewer_hops_wins():
    g = ContactGraph(ContactPlan([C(11, 14, 5, 10), C(11, 13, 0, 10), C(13, 14, 5, 10)]))
    r = g.route("sat_11", "sat_14", 0.0, 2)
    assert r.hops == 1 and r.arrival_s == pytest.approx(8.0)


#   A --[0;100]--> B --[0;100]--> C ; B --[0;100]--> A   (a loop back to A is never taken)
def test_no_loops_and_light_time():
    g = ContactGraph(ContactPlan([C(11, 12, 0, 100, owlt=0.25), C(12, 11, 0, 100), C(12, 13, 0, 100, owlt=0.5)]))
    r = g.route("sat_11", "sat_13", 10.0, 2)
    assert _names(g, r) == [("sat_11", "sat_12"), ("sat_12", "sat_13")]
    assert r.arrival_s == pytest.approx(10 + 2 + 0.25 + 2 + 0.5)
    assert g.earliest_arrivals("sat_11", 10.0, 2) == {"sat_12": pytest.approx(12.25), "sat_13": pytest.approx(14.75)}


def test_study_plan_routes_are_feasible(paper_inputs):
    from orbit_clock.contact_plan_io import read_contact_plan

    plan = read_contact_plan(paper_inputs / "contact_plan_3p_8s.csv", rate_bps=1000)
    g = ContactGraph(plan)
    rng = np.random.default_rng(4)
    for _ in range(200):
        a, b = rng.choice(g.node_names, 2, replace=False)
        t = float(rng.uniform(0, 20000))
        r = g.route(str(a), str(b), t, 2000)  # ContactGraph._check replays each route
        if r is not None:
            first = g.contacts[r.contacts[0]]
            assert r.arrival_s >= max(t, first.start_s) + 2.0 * r.hops + first.range_light_s - 1e-9


def test_hop_tolerance_prefers_fewer_hops_within_it():
    # via C arrives 7 s (2 hops), direct 53 s (1 hop): a 50 s tolerance takes the direct contact
    g = ContactGraph(PLAN1)
    r = g.route("sat_11", "sat_14", 0.0, 2, hop_tolerance_s=50.0)
    assert _names(g, r) == [("sat_11", "sat_14")] and r.arrival_s == pytest.approx(53.0)
    r = g.route("sat_11", "sat_14", 0.0, 2, hop_tolerance_s=45.0)
    assert _names(g, r) == [("sat_11", "sat_13"), ("sat_13", "sat_14")] and r.arrival_s == pytest.approx(7.0)


def test_first_hop_backlog_per_contact():
    # 6 bits already waiting for A->C only: A->C 6-8, at C 9, C->D would end at 11 > 10; A->B is free: 23
    g = ContactGraph(PLAN1)
    fb = np.zeros(len(g.contacts))
    fb[[i for i, c in enumerate(g.contacts) if (c.src, c.dst) == ("sat_11", "sat_13")][0]] = 6.0
    r = g.route("sat_11", "sat_14", 0.0, 2, first_backlog_bits=fb)
    assert _names(g, r) == [("sat_11", "sat_12"), ("sat_12", "sat_14")] and r.arrival_s == pytest.approx(23.0)
    # waiting for a contact that opens later: its backlog is sent after it opens (A->D 50 + 6 + 2 + 1)
    fb[:] = 0.0
    fb[[i for i, c in enumerate(g.contacts) if (c.src, c.dst) == ("sat_11", "sat_14")][0]] = 6.0
    excl = np.array([c.src == "sat_11" and c.dst != "sat_14" for c in g.contacts])
    r = g.route("sat_11", "sat_14", 0.0, 2, first_backlog_bits=fb, excluded=excl)
    assert r.arrival_s == pytest.approx(59.0)
