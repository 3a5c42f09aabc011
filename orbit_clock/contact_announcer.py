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

import msgspec
import numpy as np

from msgs_json import codec
from msgs_json import schemas as S
from msgs_json import topics as T
from msgs_json.envelope import Emit, Envelope, StepResult
from orbit_clock.contact_plan import ContactPlan

__all__ = ["ANNOUNCER_NAME", "ContactAnnouncer", "window_text"]

ANNOUNCER_NAME = "contacts"
_NS = 1_000_000_000
_ENC = msgspec.json.Encoder().encode  # a number's text as codec.encode writes it
_new = tuple.__new__  # Emit(topic, data, t_ns) from its fields at once (two per contact)


def window_text(event: str, kind: str, src: str, dst: str, start_ns: int, end_ns: int, rate_bps: float,
                range_light_s: float) -> str:
    """The JSON text of one ``ContactWindow`` as ``codec.encode`` gives it (the schema's checks
    included): the reference the announcer's texts are compared with."""
    return codec.encode(S.ContactWindow(event=event, kind=kind, src=src, dst=dst, start_ns=start_ns, end_ns=end_ns,
                                        rate_bps=float(rate_bps), range_light_s=float(range_light_s)))


class ContactAnnouncer:
    """Announces the windows of ``isl`` (kind ``isl``) and ``ground`` (kind ``ground``).

    The edges are kept as arrays (a 1000-satellite plan over 6 h has ~2.3 M contacts, 4.5 M edges),
    opens and closes each in announcing order, merged step by step. A window's text is written from
    the parts ``codec.encode`` of its ``ContactWindow`` would give (numbers as msgspec writes
    them), made when the window opens and kept
    until it closes, where only the event differs (tests/unit/test_contact_announcer.py compares
    every text with ``window_text``)."""

    name = ANNOUNCER_NAME

    def __init__(self, isl: ContactPlan, ground: ContactPlan | None = None):
        kinds: list[str] = []
        contacts = []
        for kind, cp in (("isl", isl), ("ground", ground)):
            for c in (cp.contacts if cp is not None else ()):
                contacts.append(c)
                kinds.append(kind)
        s_ns = np.array([round(c.start_s * _NS) for c in contacts], dtype=np.int64)
        e_ns = np.array([round(c.end_s * _NS) for c in contacts], dtype=np.int64)
        keep = np.flatnonzero(e_ns > s_ns)
        for k in keep:
            c = contacts[k]
            if c.src == c.dst:  # what ContactWindow's check refuses
                raise ValueError(f"contact {c.src} -> {c.dst} at {c.start_s} s: src and dst must differ")
        names = sorted({c.src for c in contacts} | {c.dst for c in contacts})
        rank = {n: i for i, n in enumerate(names)}
        src_r = np.array([rank[c.src] for c in contacts], dtype=np.int64)
        dst_r = np.array([rank[c.dst] for c in contacts], dtype=np.int64)
        # announcing order within one instant: opens before closes, then (src, dst); equal keys keep
        # the plan's order (isl first, each plan in its own order), as a stable sort of the edges
        self._open = keep[np.lexsort((dst_r[keep], src_r[keep], s_ns[keep]))]
        self._close = keep[np.lexsort((dst_r[keep], src_r[keep], e_ns[keep]))]
        self._open_t = s_ns[self._open]
        self._close_t = e_ns[self._close]
        self._contacts = contacts
        self._kinds = kinds
        self._s_ns = s_ns
        self._e_ns = e_ns
        self._rates: dict[float, str] = {}  # rate -> its text
        self._tail: dict[int, str] = {}  # open window -> its text after '"event":"open"'
        self._io = self._ic = 0
        self.announced = 0

    def subscriptions(self) -> list[str]:
        return []

    def start(self, t0_ns: int) -> StepResult:
        return StepResult(self._announce(t0_ns))

    def step(self, t_ns: int, inbox: list[Envelope]) -> StepResult:
        return StepResult(self._announce(t_ns))

    def finish(self, t_ns: int) -> list[Emit]:
        return []

    def _tail_of(self, k: int) -> str:
        c = self._contacts[k]
        rate = self._rates.get(c.rate_bps)
        if rate is None:
            rate = self._rates[c.rate_bps] = _ENC(float(c.rate_bps)).decode()
        light = _ENC(float(c.range_light_s)).decode()
        return (f',"kind":"{self._kinds[k]}","src":"{c.src}","dst":"{c.dst}","start_ns":{int(self._s_ns[k])},'
                f'"end_ns":{int(self._e_ns[k])},"rate_bps":{rate},"range_light_s":{light}}}')

    def _announce(self, t_ns: int) -> list[Emit]:
        io1 = int(np.searchsorted(self._open_t, t_ns, side="right"))
        ic1 = int(np.searchsorted(self._close_t, t_ns, side="right"))
        io0, ic0 = self._io, self._ic
        if io1 == io0 and ic1 == ic0:
            return []
        self._io, self._ic = io1, ic1
        opens = self._open[io0:io1]
        closes = self._close[ic0:ic1]
        times = np.concatenate((self._open_t[io0:io1], self._close_t[ic0:ic1]))
        flag = np.concatenate((np.zeros(opens.size, np.int64), np.ones(closes.size, np.int64)))
        pos = np.concatenate((np.arange(opens.size), np.arange(closes.size)))
        # opens and closes are each in order already: merge by (time, open before close, own order)
        order = np.lexsort((pos, flag, times))
        tail = self._tail
        emits = []
        append = emits.append
        topic = T.CONTACTS
        opens_l, closes_l, times_l = opens.tolist(), closes.tolist(), times.tolist()
        for j in order.tolist():
            if j < len(opens_l):
                k = opens_l[j]
                text = tail[k] = self._tail_of(k)
                append(_new(Emit, (topic, f'{{"v":{S.SCHEMA_VERSION},"event":"open"' + text, times_l[j])))
            else:
                k = closes_l[j - len(opens_l)]
                text = tail.pop(k, None) or self._tail_of(k)
                append(_new(Emit, (topic, f'{{"v":{S.SCHEMA_VERSION},"event":"close"' + text, times_l[j])))
        self.announced += len(emits)
        return emits
