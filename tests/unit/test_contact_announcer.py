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
