"""The ISL medium on drawn plans (rate 1000 b/s, 2000-bit bundles: 2 s on air).

   sat_11 --[0;100] owlt 0.5--> sat_12
   sat_11 --[0;101] owlt 0.25-> sat_13
   sat_11 --[50;60]-----------> sat_14
"""

from orbit_clock.contact_plan import Contact, ContactPlan
from dtn_router.link import LinkModel

S = 10**9
PLAN = ContactPlan([Contact(0.0, 100.0, "sat_11", "sat_12", 1000.0, 0.5),
                    Contact(0.0, 101.0, "sat_11", "sat_13", 1000.0, 0.25),
                    Contact(50.0, 60.0, "sat_11", "sat_14", 1000.0, 0.0)])


def test_broadcast_copies_with_light_time():
    link = LinkModel(PLAN)
    out = link.transmit("sat_11", "sat_12", 10 * S, 2000)
    assert out.ok and out.end_ns == 12 * S
    assert [(c.node, c.arrival_ns) for c in out.copies] == [("sat_13", 12 * S + S // 4), ("sat_12", 12 * S + S // 2)]
    out = link.transmit("sat_11", "sat_14", 55 * S, 2000)
    assert out.ok and {c.node for c in out.copies} == {"sat_12", "sat_13", "sat_14"}


def test_failures():
    link = LinkModel(PLAN)
    assert link.transmit("sat_11", "sat_14", 10 * S, 2000).reason == "no_contact"
    out = link.transmit("sat_11", "sat_12", 99 * S, 2000)  # ends at 101 > 100
    assert not out.ok and out.reason == "contact_ended"
    assert [c.node for c in out.copies] == ["sat_13"]  # sat_13's contact lasts to 101: it still hears it
    link.transmit("sat_11", "sat_13", 20 * S, 2000)
    assert link.transmit("sat_11", "sat_13", 21 * S, 2000).reason == "radio_busy"


def test_truth_differs_from_belief_cut_contact():
    truth = ContactPlan([c for c in PLAN.contacts if c.dst != "sat_12"])
    assert LinkModel(truth).transmit("sat_11", "sat_12", 10 * S, 2000).reason == "no_contact"
