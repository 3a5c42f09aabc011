"""The ISL medium model: the truth about which transmissions get through, to whom, and when.

Given one transmission (sender, intended next hops, start [ns], bits), :meth:`LinkModel.transmit`
looks up the *truth* contact plan (which may differ from what the agents believe: cut contacts,
extra light time) and returns:

* ``ok`` - for every intended next hop a truth contact sender -> next hop is open at the start and
  stays open until the last bit has left (duration = bits / the slowest of those contacts' rates; a
  multicast transmission serves several next hops at once); otherwise a failure with the reason per
  next hop that misses it (``failed``; ``no_contact``: none open at the start; ``contact_ended``: it
  closes mid-transmission);
* ``copies`` - broadcast medium: every node with a truth contact from the sender covering the whole
  transmission gets a copy, at end + that contact's one-way light time (receivers that are not an
  intended next hop discard it, which the agents count). A failed next hop gets no copy.

One transmission at a time per sender: a transmission that starts before the sender's previous one
ended fails with ``radio_busy``. Receiver-side collisions (two senders heard at once) are not
modelled (the study's link budget does not either).

How we know it is right: tests/unit/test_link.py on drawn plans (copies to every node in view,
arrival = end + light time, a contact ending mid-transmission fails, a cut contact fails), and
tests/unit/test_speed_paths.py (open_contacts, which checks a sender's long contacts one by one and
skips short ones that started more than its longest short contact ago, equals the full scan on a
random plan; so does the memo of the open contacts that transmit reads, on random transmission times).
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass, field
from typing import NamedTuple

from orbit_clock.contact_plan import Contact, ContactPlan

__all__ = ["LinkModel", "LinkOutcome", "Copy"]

_NS = 1_000_000_000
_new = tuple.__new__  # Copy(node, arrival_ns) from its fields at once (~170 copies per transmission at 1000 satellites)


class Copy(NamedTuple):
    node: str
    arrival_ns: int


@dataclass(frozen=True)
class LinkOutcome:
    ok: bool
    end_ns: int
    copies: list[Copy] = field(default_factory=list)
    reason: str = ""  # the first failed next hop's reason ("" when ok)
    failed: dict = field(default_factory=dict)  # next hop -> reason, for each that missed it


# a contact longer than this [s] is checked by open_contacts whenever its sender transmits
_LONG_S = 3600.0


def _view(open_now: list[Contact]) -> tuple[dict[str, Contact], list[tuple[int, str, float]] | None]:
    """What :meth:`LinkModel.transmit` reads from a sender's open contacts: per receiver the contact
    that stays open longest (the first of equals, as ``max`` gives), and - when no receiver has two
    open contacts - the copies' template: (light time [ns], receiver, end [ns, float]) sorted, so
    that the copies of a transmission ending at ``end_ns`` are those whose end is not before it, in
    (arrival, node) order already (arrival = end_ns + light time for all); None otherwise (transmit
    then takes each receiver's first contact in the plan's order that covers the transmission).
    tests/unit/test_speed_paths.py compares transmit with the contact-by-contact scan."""
    best: dict[str, Contact] = {}
    for c in open_now:
        b = best.get(c.dst)
        if b is None or c.end_s > b.end_s:
            best[c.dst] = c
    if len(best) < len(open_now):
        return best, None
    return best, sorted((round(c.range_light_s * _NS), c.dst, c.end_s * _NS) for c in open_now)


class LinkModel:
    def __init__(self, truth: ContactPlan):
        self.truth = truth
        self._by_src: dict[str, list[Contact]] = {}
        for c in truth.contacts:
            self._by_src.setdefault(c.src, []).append(c)
        # open_contacts: per sender, the contacts longer than _LONG_S (few: neighbours in view for
        # hours, e.g. in-plane ones) are checked one by one; the others are found by start time: one
        # that started more than the sender's longest short contact (+1 s against rounding) before t
        # has ended by t, so only the starts after that are scanned
        self._short: dict[str, tuple[list, list, list[int], float]] = {}
        self._long: dict[str, list[tuple[int, Contact]]] = {}
        for s, cs in self._by_src.items():
            short = [(i, c) for i, c in enumerate(cs) if c.end_s - c.start_s <= _LONG_S]
            self._short[s] = ([c for _i, c in short], [c.start_s for _i, c in short], [i for i, _c in short],
                              max((c.end_s - c.start_s for _i, c in short), default=0.0) + 1.0)
            self._long[s] = [(i, c) for i, c in enumerate(cs) if c.end_s - c.start_s > _LONG_S]
        # open_contacts at the sender's last transmission, with the interval [from, until) over which
        # that set stays the same (until: the first of its contacts to end or of the sender's
        # contacts to start after it): a radio sends many bundles between two changes
        self._open_memo: dict[str, tuple[float, float, list[Contact]]] = {}
        self._starts = {s: sorted(c.start_s for c in cs) for s, cs in self._by_src.items()}
        # per sender, what transmit derives from the open set of the memo above (made once per set:
        # the set is shared until the memo moves on): see _view
        self._view_memo: dict[str, tuple] = {}
        self._busy_until_ns: dict[str, int] = {}
        self.counters = {"tx": 0, "ok": 0, "no_contact": 0, "contact_ended": 0, "radio_busy": 0, "copies": 0}
        self.air_ns: dict[str, int] = {}  # sender -> time on air [ns] (every transmission that went out)
        self.bits_sent: dict[str, int] = {}  # sender -> bits put on air

    def open_contacts(self, sender: str, t_s: float) -> list[Contact]:
        """The sender's contacts open at ``t_s`` (start <= t_s < end), in the plan's order."""
        short = self._short.get(sender)
        if short is None:
            return []
        cs, starts, idx, span_s = short
        k = bisect.bisect_right(starts, t_s)
        lo = bisect.bisect_left(starts, t_s - span_s, 0, k)
        found = [(idx[j], cs[j]) for j in range(lo, k) if cs[j].end_s > t_s]
        longs = [(i, c) for i, c in self._long[sender] if c.start_s <= t_s < c.end_s]
        if longs:
            found = sorted(found + longs, key=lambda x: x[0])
        return [c for _i, c in found]

    def _open_at(self, sender: str, t_s: float) -> list[Contact]:
        """:meth:`open_contacts` (the list is shared: read only), from the memo while it holds."""
        got = self._open_memo.get(sender)
        if got is not None and got[0] <= t_s < got[1]:
            return got[2]
        found = self.open_contacts(sender, t_s)
        starts = self._starts.get(sender, ())
        k = bisect.bisect_right(starts, t_s)
        until = min([starts[k] if k < len(starts) else float("inf")] + [c.end_s for c in found])
        self._open_memo[sender] = (t_s, until, found)
        return found

    def transmit(self, sender: str, next_hop, start_ns: int, bits: int) -> LinkOutcome:
        """One transmission to ``next_hop`` (a node name, or a sequence of them for a multicast one)."""
        self.counters["tx"] += 1
        hops = (next_hop,) if isinstance(next_hop, str) else tuple(next_hop)
        if start_ns < self._busy_until_ns.get(sender, -1):
            self.counters["radio_busy"] += 1
            return LinkOutcome(False, start_ns, [], "radio_busy", {h: "radio_busy" for h in hops})
        t_s = start_ns / _NS
        open_now = self._open_at(sender, t_s)
        view = self._view_memo.get(sender)
        if view is None or view[0] is not open_now:
            view = self._view_memo[sender] = (open_now, *_view(open_now))
        _open, best, heard = view
        links = {h: best[h] for h in hops if h in best}
        if not links:
            self.counters["no_contact"] += 1
            return LinkOutcome(False, start_ns, [], "no_contact", {h: "no_contact" for h in hops})
        rate = min(c.rate_bps for c in links.values())
        end_ns = start_ns + int(-(-bits * _NS // int(rate))) if float(rate).is_integer() \
            else start_ns + int(bits / rate * _NS + 0.999999)
        self._busy_until_ns[sender] = end_ns
        self.air_ns[sender] = self.air_ns.get(sender, 0) + end_ns - start_ns
        self.bits_sent[sender] = self.bits_sent.get(sender, 0) + int(bits)
        failed = {h: ("no_contact" if h not in links else "contact_ended") for h in hops
                  if h not in links or end_ns > links[h].end_s * _NS}
        if heard is not None:  # (one open contact per receiver: the copies in (light time, node) order)
            copies = [_new(Copy, (node, end_ns + light)) for light, node, until in heard if until >= end_ns]
        else:
            copies = []
            seen = set()
            for c in open_now:
                if c.dst in seen or c.end_s * _NS < end_ns:
                    continue
                seen.add(c.dst)
                copies.append(Copy(c.dst, end_ns + int(round(c.range_light_s * _NS))))
            copies.sort(key=lambda x: (x.arrival_ns, x.node))
        self.counters["copies"] += len(copies)
        if failed:
            for reason in failed.values():
                self.counters[reason] += 1
            copies = [x for x in copies if x.node not in failed]
            return LinkOutcome(False, end_ns, copies, next(iter(failed.values())), failed)
        self.counters["ok"] += 1
        return LinkOutcome(True, end_ns, copies, "")
