"""Faults applied to a contact plan: ISL cuts and extra light time (the truth the medium obeys).

A fault study runs the agents on the predicted plan while the ISL medium (dtn_router/router.py) and
the contact-window announcer (orbit_clock/contact_announcer.py) use the *truth*: the same plan with
each cut ``(a, b, t1, t2)`` removing ``[t1, t2]`` from every contact between ``a`` and ``b`` (both
directions; a contact may split in two) and ``extra_delay_s`` added to every contact's one-way
light time. Both participants take the truth from :func:`truth_plan`, so what is announced is what
the medium carries.

How we know it is right: tests/unit/test_contact_announcer.py (cut pieces and extra light time by
hand, and the windows announced for them) and tests/faults/test_faults_link.py (a cut ends a contact
mid-transmission: the medium reports the failure).
"""

from __future__ import annotations

from orbit_clock.contact_plan import Contact, ContactPlan

__all__ = ["apply_cuts", "truth_plan"]


def apply_cuts(contacts: list[Contact], cuts) -> list[Contact]:
    """``contacts`` with ``[t1, t2]`` removed from every contact between each cut's pair (both ways)."""
    out = []
    for c in contacts:
        pieces = [(c.start_s, c.end_s)]
        for a, b, t1, t2 in cuts:
            if {c.src, c.dst} != {a, b}:
                continue
            nxt = []
            for s, e in pieces:
                if t2 <= s or t1 >= e:
                    nxt.append((s, e))
                    continue
                if s < t1:
                    nxt.append((s, t1))
                if t2 < e:
                    nxt.append((t2, e))
            pieces = nxt
        out += [Contact(s, e, c.src, c.dst, c.rate_bps, c.range_light_s) for s, e in pieces if e > s]
    return out


def truth_plan(plan: ContactPlan, *, cuts=None, extra_delay_s: float = 0.0) -> ContactPlan:
    """The plan the ISL medium obeys: ``plan`` with ``cuts`` and ``extra_delay_s`` (module docstring);
    ``plan`` itself when there are neither."""
    if cuts:
        plan = ContactPlan(apply_cuts(plan.contacts, cuts))
    if extra_delay_s:
        plan = ContactPlan([Contact(c.start_s, c.end_s, c.src, c.dst, c.rate_bps, c.range_light_s + extra_delay_s)
                            for c in plan.contacts])
    return plan
