"""The study's traffic table (tests/fixtures/paper_inputs/traffic_case*.csv; Nag et al. 2021's DTN inputs),
and the node that sends it.

One row per executed observation: ``source,time_s,packet_id,region,Sat11..Sat38``; the satellite
columns hold the bundle priority for that destination (-1: not a destination, 0: the source). Each
(row, destination with priority > 0) is one bundle. Items come out in creation order: by time, then
file row, then priority, then destination name.

:class:`TrafficNode` is a lockstep participant (msgs_json/envelope.py) for one node of a DTN-alone
run: a satellite whose bundles come from the table instead of its observations. It creates the
bundles of each creation time at that instant (a payload naming the packet, padded to
``payload_bytes``): one per (row, destination) with a unicast agent, one per row - an observation,
with all its destinations - with a multicast agent (sat_node/dtn/multicast.py); everything else -
receiving, the medium's failure reports, the radio, the bundle events - is the satellite's own code path (sat_node/dtn/port.py). It asks to be woken just after
its next creation time and its port's next event (the radio's next decision, an expiry, the end of
a transmission in flight), so every decision is taken at its own instant after every arrival and
creation up to it, and the medium hears of every transmission by its end: the run is the DTN in
continuous time. A step with an empty inbox before that wakeup would change nothing: the node is
event-driven (contract rule 1), the engine calls it only for an inbox or at its wakeup.

Reading checks every row (:func:`read_traffic`): finite creation times from 0, priorities -1..15,
one row per (source, packet_id) - an exact repeat merged with a warning, a differing one refused -
and at most :data:`MAX_TRAFFIC_BUNDLES` bundles, counted as the file is read, so a huge table is
refused at the line where it passes the limit instead of hanging the run (the hostile inputs in
tests/faults/test_hostile_inputs.py).

How we know it is right: the study's README counts (traffic_case4: 7430 bundles; case1: 52413),
and DTN-alone runs on drawn plans with hand-worked delivery times, checked in
tests/unit/test_dtn_alone.py.
"""

from __future__ import annotations

import csv
import hashlib
import math
from dataclasses import dataclass
from pathlib import Path

from msgs_json.envelope import Emit, Envelope, StepResult
from msgs_json.text_input import TextInputError, decode_error_line, open_text
from orbit_clock.contact_plan import canonical_node
from sat_node.dtn.agent import BundleAgent
from sat_node.dtn.port import DtnPort, count_rejection

__all__ = ["MAX_TRAFFIC_BUNDLES", "MAX_TRAFFIC_TIME_S", "TrafficError", "TrafficItem", "TrafficNode", "read_traffic",
           "traffic_payload"]

_NS = 1_000_000_000
MAX_TRAFFIC_BUNDLES = 1_000_000  # ~1 GiB and hours of simulation; case1 (the study's largest) has 52,413
MAX_TRAFFIC_TIME_S = 2**62 / 1e9  # half the engines' int64-nanosecond clock (~146 years)


class TrafficError(ValueError):
    """A traffic file that cannot be read (names the file and line)."""


@dataclass(frozen=True)
class TrafficItem:
    t_s: float
    source: str
    dest: str
    priority: int
    packet_id: str
    region: str
    row: int


def read_traffic(path, *, on_duplicate=None, max_bundles: int = MAX_TRAFFIC_BUNDLES) -> list[TrafficItem]:
    """The table's bundles in creation order (module docstring). Checked as it is read: UTF-8 text,
    times finite in 0..:data:`MAX_TRAFFIC_TIME_S`, priorities -1..15, destination columns named
    once, at most ``max_bundles`` bundles (the reading stops there). A row repeated with the same
    (source, packet_id) is one observation: merged when identical (told to ``on_duplicate``; an error
    without it), an error when it differs. TrafficError (one line, file and line) otherwise."""
    path = Path(path)
    try:
        fh = open_text(path, "traffic table")
    except TextInputError as exc:
        raise TrafficError(str(exc)) from None
    line = 1
    seen: dict[tuple[str, str], tuple[int, bytes]] = {}  # (source, packet_id) -> (line, digest of the row)
    dups = 0
    try:
        with fh:
            reader = csv.reader(fh)
            header = next(reader, None)
            if not header or header[:4] != ["source", "time_s", "packet_id", "region"] or len(header) < 5:
                raise TrafficError(f"{path}: header must start with source,time_s,packet_id,region then one "
                                   f"column per satellite; got {str(header)[:200]}")
            dests = [canonical_node(h.strip()) for h in header[4:]]
            twice = sorted({d for d in dests if dests.count(d) > 1})
            if twice:
                raise TrafficError(f"{path}: destination columns named twice: {twice[:5]}")
            out = []
            for line, row in enumerate(reader, start=2):
                if not row:
                    continue
                if len(row) != len(header):
                    raise TrafficError(f"{path}:{line}: {len(row)} fields, header has {len(header)}")
                try:
                    t_s = float(row[1])
                    prios = [int(x) for x in row[4:]]
                except ValueError:
                    raise TrafficError(f"{path}:{line}: time or a priority is not a number") from None
                if not (math.isfinite(t_s) and 0.0 <= t_s <= MAX_TRAFFIC_TIME_S):
                    raise TrafficError(f"{path}:{line}: time_s {row[1]!r} outside 0..{MAX_TRAFFIC_TIME_S:.3g} s")
                src = canonical_node(row[0].strip())
                key = (src, row[2])
                digest = hashlib.blake2b("\x1f".join(row).encode(), digest_size=16).digest()
                if key in seen:
                    first, was = seen[key]
                    if was != digest:
                        raise TrafficError(f"{path}:{line}: packet {row[2]!r} of {src} was already listed on line "
                                           f"{first} with other values: one packet, one row")
                    dups += 1
                    continue
                seen[key] = (line, digest)
                for d, p in sorted(zip(dests, prios), key=lambda x: (x[1], x[0])):
                    if not -1 <= p <= 15:
                        raise TrafficError(f"{path}:{line}: priority {p} for {d} is outside -1..15 "
                                           "(-1: not a destination, 0: the source, 1..15: a bundle)")
                    if p > 0 and d != src:
                        out.append(TrafficItem(t_s, src, d, p, row[2], row[3], line))
                if len(out) > max_bundles or len(seen) > max_bundles:
                    raise TrafficError(f"{path}:{line}: more than {max_bundles:,} bundles (rows x destinations) by "
                                       f"this line; a DTN-alone run handles a few hundred bundles per second "
                                       f"(case4's 7,430 take ~20 s): split the table")
    except UnicodeDecodeError as exc:
        raise TrafficError(f"{path}:{line + 1}: " + decode_error_line(exc, "the table").split(": ", 1)[1]) from None
    except csv.Error as exc:
        raise TrafficError(f"{path}:{line}: not a CSV table: {exc}") from None
    if dups:
        msg = f"{path}: {dups} rows repeat a (source, packet_id) row exactly: each counted once"
        if on_duplicate is None:
            raise TrafficError(msg.replace("each counted once", "remove the copies"))
        on_duplicate(msg)
    out.sort(key=lambda x: (x.t_s, x.row, x.priority, x.dest))
    return out


def traffic_payload(item: TrafficItem, size: int) -> bytes:
    """The payload of one traffic item's bundle: which packet, region and time, padded to ``size``."""
    head = f'{{"packet_id":"{item.packet_id}","region":"{item.region}","t_s":{item.t_s}}}'.encode()
    return head + b" " * max(0, size - len(head))


class TrafficNode:
    """Node ``agent.node`` of a DTN-alone run, sending ``items`` [(index, item)] (module docstring).

    ``on_created(index, bundle_id)`` is called right after each bundle is created (before it is sent);
    ``publish_events=False``: the bundle events are not published (the caller reads the agent's).
    """

    # Called only for an inbox or at its wakeup (msgs_json/envelope.py rule 1): a step with neither
    # changes nothing for it - nothing arrives and nothing is due before the wakeup it asked for.
    event_driven = True

    def __init__(self, agent: BundleAgent, items, *, payload_bytes: int = 160, on_created=None,
                 publish_events: bool = True):
        self.name = agent.node
        self.agent = agent
        self.port = DtnPort(self.name, agent, events=publish_events)
        self._items = sorted(((int(round(it.t_s * _NS)), i, it) for i, it in items), key=lambda x: (x[0], x[1]))
        self._next = 0
        self.payload_bytes = payload_bytes
        self.on_created = on_created
        self.created_ids: dict[int, str] = {}  # traffic index -> bundle id
        self.rejected = 0
        self.rejected_by_reason: dict[str, int] = {}
        self._wake: int | None = 0  # the wakeup the last step returned (0 before the first: all is due)

    def subscriptions(self) -> list[str]:
        return self.port.subscriptions()

    def start(self, t0_ns: int) -> StepResult:
        return self.step(t0_ns, [])

    def step(self, t_ns: int, inbox: list[Envelope]) -> StepResult:
        port = self.port
        heard = port.overheard
        for env in inbox:
            try:
                port.receive(env, t_ns)
            except (ValueError, KeyError, TypeError) as exc:  # a bad message never kills the node
                self.rejected += 1
                count_rejection(self.rejected_by_reason, env, exc)
        # Up to t_ns - 1 only: a copy stamped t_ns itself is emitted by the medium at this very step
        # and seen at the next one, so what is due at t_ns waits for the wakeup at t_ns + 1
        # (at one instant: arrivals first, then creations, then the radio's decision).
        upto = t_ns - 1
        if (self._wake is None or t_ns < self._wake) and port.overheard - heard == len(inbox):
            # Only copies for other nodes (the broadcast medium's most common step), before the wakeup
            # the node asked for: no creation, radio decision or expiry is due by ``upto`` and the agent
            # is as it was when that wakeup was computed, so the radio would only count the step and
            # settle (DtnPort.idle); the wakeup changes only when something settled.
            if port.idle(upto):
                self._wake = self._wakeup(upto)
            return StepResult([], self._wake)
        items, i = self._items, self._next
        while i < len(items) and items[i][0] <= upto:
            at, index, item = items[i]
            row = [(index, item)]  # one observation: the same row's destinations, next to each other
            i += 1
            while i < len(items) and items[i][0] == at and items[i][2].row == item.row \
                    and items[i][2].source == item.source:
                row.append(items[i][1:])
                i += 1
            bids = port.originate(traffic_payload(item, self.payload_bytes), [(it.dest, it.priority) for _k, it in row],
                                  at)
            for k, (index_k, _it) in enumerate(row):
                bid = bids[k] if len(bids) == len(row) else bids[0]
                self.created_ids[index_k] = bid
                if self.on_created is not None:
                    self.on_created(index_k, bid)
        self._next = i
        emits = port.radio(upto)
        self._wake = self._wakeup(upto)
        return StepResult(emits, self._wake)

    def _wakeup(self, upto: int) -> int | None:
        """1 ns after the next creation or the port's next event (the radio's next decision, an
        expiry, a transmission's end) after ``upto``; None: nothing more to do."""
        i = self._next
        due = self._items[i][0] if i < len(self._items) else None
        nxt = self.port.next_event_ns(upto)
        if nxt is not None and (due is None or nxt < due):
            due = nxt
        return None if due is None else due + 1

    def finish(self, t_ns: int) -> list[Emit]:
        emits = self.port.radio(t_ns)
        emits.append(self.port.counters_emit(t_ns, rejected=self.rejected, rejected_by_reason=self.rejected_by_reason))
        return emits
