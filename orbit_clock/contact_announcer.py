"""Contact windows as they open and close, announced on ``/orbit/contacts`` (docs/design.md section 4).

A lockstep participant (msgs_json/envelope.py) present in every run, whatever the mode: for every
ISL contact of the truth plan (orbit_clock/contact_faults.py: the plan the ISL medium obeys, with
the run's cuts and extra light time) and every ground contact, it emits a ``ContactWindow`` ``open``
stamped at the contact's start and a ``close`` stamped at its end, each at the step that covers
that instant (rule 2 of the contract: nothing stamped in the future). Edges add no steps: the
announcer never asks to be woken, so a run's steps are those of its other participants. Within one
instant, opens go before closes, then by (src, dst). Contacts of zero length are not announced.

How we know it is right: tests/unit/test_contact_announcer.py (every edge once, in order, at the
step covering it, stamped exactly; cuts split windows) and tests/system/test_engines_equal.py (the
ROS run records the same /orbit/contacts as the local run).
"""

from __future__ import annotations

from msgs_json import codec
from msgs_json import schemas as S
from msgs_json import topics as T
from msgs_json.envelope import Emit, Envelope, StepResult
from orbit_clock.contact_plan import ContactPlan

__all__ = ["ANNOUNCER_NAME", "ContactAnnouncer"]

ANNOUNCER_NAME = "contacts"
_NS = 1_000_000_000


class ContactAnnouncer:
    """Announces the windows of ``isl`` (kind ``isl``) and ``ground`` (kind ``ground``)."""

    name = ANNOUNCER_NAME

    def __init__(self, isl: ContactPlan, ground: ContactPlan | None = None):
        edges = []
        for kind, cp in (("isl", isl), ("ground", ground)):
            for c in (cp.contacts if cp is not None else ()):
                s_ns, e_ns = int(round(c.start_s * _NS)), int(round(c.end_s * _NS))
                if e_ns <= s_ns:
                    continue
                edges.append((s_ns, 0, "open", c, kind, s_ns, e_ns))
                edges.append((e_ns, 1, "close", c, kind, s_ns, e_ns))
        edges.sort(key=lambda e: (e[0], e[1], e[3].src, e[3].dst))
        self._edges = edges
        self._i = 0
        self.announced = 0

    def subscriptions(self) -> list[str]:
        return []

    def start(self, t0_ns: int) -> StepResult:
        return StepResult(self._announce(t0_ns))

    def step(self, t_ns: int, inbox: list[Envelope]) -> StepResult:
        return StepResult(self._announce(t_ns))

    def finish(self, t_ns: int) -> list[Emit]:
        return []

    def _announce(self, t_ns: int) -> list[Emit]:
        edges, i = self._edges, self._i
        if i >= len(edges) or edges[i][0] > t_ns:
            return []
        emits = []
        while i < len(edges) and edges[i][0] <= t_ns:
            at, _, event, c, kind, s_ns, e_ns = edges[i]
            i += 1
            msg = S.ContactWindow(event=event, kind=kind, src=c.src, dst=c.dst, start_ns=s_ns, end_ns=e_ns,
                                  rate_bps=float(c.rate_bps), range_light_s=float(c.range_light_s))
            emits.append(Emit(T.CONTACTS, codec.encode(msg), at))
        self._i = i
        self.announced += len(emits)
        return emits
