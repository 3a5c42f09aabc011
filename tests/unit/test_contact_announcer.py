"""The contact-window announcer (orbit_clock/contact_announcer.py) and the truth plan's faults
(orbit_clock/contact_faults.py), on drawn plans worked by hand; and its presence in every mode.

Oracle: every window's open and close, each once, stamped at the exact edge and emitted at the
first step at or after it, opens before closes at one instant; a cut splits a window in two, extra
light time shows in the window; every mode's participants include the announcer (under the ROS
engine it is a role of its own).
"""

from __future__ import annotations

import pytest

from bringup.engine.local import run_local
from bringup.scenario.participants import CONTACTS_ROLE, MODES, roles_for
from msgs_json import codec
from msgs_json import topics as T
from orbit_clock.contact_announcer import ContactAnnouncer
from orbit_clock.contact_faults import truth_plan
from orbit_clock.contact_plan import Contact, ContactPlan

S = 10**9
ISL = ContactPlan([Contact(5.0, 25.0, "sat_11", "sat_12", 1000.0, 0.01),
                   Contact(5.0, 25.0, "sat_12", "sat_11", 1000.0, 0.01),
                   Contact(25.0, 31.5, "sat_12", "sat_13", 1000.0, 0.02),
                   Contact(40.0, 40.0, "sat_11", "sat_13", 1000.0, 0.02)])  # zero length: not announced
GROUND = ContactPlan([Contact(12.0, 18.0, "sat_11", "gs_svalbard", 1e6, 0.003)])


def _windows(envs):
    out = []
    for e in envs:
        assert e.topic == T.CONTACTS and e.source == "contacts"
        m = codec.decode(e.topic, e.data)
        out.append((e.t_ns, m.event, m.kind, m.src, m.dst, m.start_ns, m.end_ns, m.range_light_s))
    return out


def test_every_edge_once_at_the_step_covering_it():
    res = run_local([ContactAnnouncer(ISL, GROUND)], horizon_ns=60 * S, max_step_ns=10 * S)
    assert res.steps == 7  # the announcer adds no steps: 0, 10, ..., 60
    got = _windows(res.envelopes)
    assert got == [
        (5 * S, "open", "isl", "sat_11", "sat_12", 5 * S, 25 * S, 0.01),
        (5 * S, "open", "isl", "sat_12", "sat_11", 5 * S, 25 * S, 0.01),
        (12 * S, "open", "ground", "sat_11", "gs_svalbard", 12 * S, 18 * S, 0.003),
        (18 * S, "close", "ground", "sat_11", "gs_svalbard", 12 * S, 18 * S, 0.003),
        (25 * S, "open", "isl", "sat_12", "sat_13", 25 * S, 31_500_000_000, 0.02),
        (25 * S, "close", "isl", "sat_11", "sat_12", 5 * S, 25 * S, 0.01),
        (25 * S, "close", "isl", "sat_12", "sat_11", 5 * S, 25 * S, 0.01),
        (31_500_000_000, "close", "isl", "sat_12", "sat_13", 25 * S, 31_500_000_000, 0.02),
    ]


def test_emitted_at_the_first_step_at_or_after_the_edge():
    a = ContactAnnouncer(ISL, GROUND)
    assert a.start(0).emits == [] and a.subscriptions() == []
    assert a.step(4 * S, []).emits == []
    r = a.step(20 * S, [])
    assert [e.t_ns for e in r.emits] == [5 * S, 5 * S, 12 * S, 18 * S] and r.next_wakeup_ns is None
    assert len(a.step(60 * S, []).emits) == 4 and a.step(70 * S, []).emits == [] and a.announced == 8


def test_cut_and_extra_delay_show_in_the_windows():
    truth = truth_plan(ISL, cuts=[("sat_12", "sat_11", 10.0, 15.0)], extra_delay_s=0.5)
    pieces = sorted((c.src, c.dst, c.start_s, c.end_s, c.range_light_s) for c in truth.contacts
                    if {c.src, c.dst} == {"sat_11", "sat_12"})
    assert pieces == [("sat_11", "sat_12", 5.0, 10.0, 0.51), ("sat_11", "sat_12", 15.0, 25.0, 0.51),
                      ("sat_12", "sat_11", 5.0, 10.0, 0.51), ("sat_12", "sat_11", 15.0, 25.0, 0.51)]
    assert truth_plan(ISL) is ISL
    opens = [w for w in _windows(run_local([ContactAnnouncer(truth)], horizon_ns=60 * S, max_step_ns=10 * S).envelopes)
             if w[1] == "open" and w[3] == "sat_11"]
    assert [(w[5], w[6]) for w in opens] == [(5 * S, 10 * S), (15 * S, 25 * S)]


@pytest.mark.parametrize("mode", MODES)
def test_every_mode_has_the_announcer(mode):
    roles = roles_for([f"sat_1{i}" for i in range(1, 4)], mode)
    assert roles.count(CONTACTS_ROLE) == 1


def _reference_emits(isl, ground, steps_ns):
    """Every edge of the plans, sorted by (instant, open before close, src, dst) - ties in plan
    order, isl first -, each announced at the first step at or after it with ``codec.encode``'s text
    of its ContactWindow: the announcer as first written (one tuple per edge, one struct per text)."""
    from orbit_clock.contact_announcer import window_text

    edges = []
    for kind, cp in (("isl", isl), ("ground", ground)):
        for c in cp.contacts:
            s_ns, e_ns = round(c.start_s * S), round(c.end_s * S)
            if e_ns > s_ns:
                edges.append((s_ns, 0, "open", c, kind, s_ns, e_ns))
                edges.append((e_ns, 1, "close", c, kind, s_ns, e_ns))
    edges.sort(key=lambda e: (e[0], e[1], e[3].src, e[3].dst))
    out, i = [], 0
    for t in steps_ns:
        got = []
        while i < len(edges) and edges[i][0] <= t:
            at, _, event, c, kind, s_ns, e_ns = edges[i]
            got.append((T.CONTACTS, window_text(event, kind, c.src, c.dst, s_ns, e_ns, c.rate_bps, c.range_light_s), at))
            i += 1
        out.append(got)
    return out


def test_texts_and_order_equal_one_struct_per_edge(paper_scenario):
    """The announcer's arrays and texts written from parts give, step by step, the emits of one
    ContactWindow encoded per edge in one sorted list of edges: on a whole 24-satellite plan (ISL and
    ground) and on a random plan with equal instants, equal node pairs at once, ground contacts
    interleaved, zero-length windows and odd floats (1e-7 s light time, fractional rates)."""
    import random

    from bringup.scenario.world import World

    w = World.build(paper_scenario.with_overrides(hours=1.0))
    rng = random.Random(5)
    nodes = [f"sat_{p}{s}" for p in range(1, 4) for s in range(1, 4)] + ["gs_a", "gs_b"]
    cs, gs = [], []
    for _ in range(400):
        a, b = rng.sample(nodes, 2)
        s0 = rng.choice([0.0, 1.5, 2.0, 10.0, rng.uniform(0, 100)])
        c = Contact(round(s0, 3), round(s0 + rng.choice([0.0, 0.5, 8.0, rng.uniform(0, 50)]), 3), a, b,
                    rng.choice([1000.0, 250.5, 1e6]), rng.choice([1e-7, 0.01, rng.uniform(0, 0.03)]))
        (gs if a.startswith("gs_") or b.startswith("gs_") else cs).append(c)
    for isl, ground, horizon in ((w.isl_plan, w.ground_plan, 3600 * S), (ContactPlan(cs), ContactPlan(gs), 160 * S)):
        steps = [0]
        while steps[-1] < horizon:
            steps.append(min(horizon, steps[-1] + rng.choice([1, S // 2, 10 * S, 37 * S])))
        a = ContactAnnouncer(isl, ground)
        got = [a.start(steps[0]).emits] + [a.step(t, []).emits for t in steps[1:]]
        want = _reference_emits(isl, ground, steps)
        assert sum(map(len, want)) > 500
        assert [[tuple(e) for e in g] for g in got] == want
        assert a.announced == sum(map(len, want))
