"""A node's bundle agent on the lockstep bus: what crosses between the agent and the ISL medium.

One class for every node that runs a bundle agent under an engine (msgs_json/envelope.py): the
satellite (sat_node/satellite.py) and the DTN-alone study's traffic nodes
(sat_node/dtn/traffic.py TrafficNode) use it, so the DTN behaves the same in a whole run and in
``constellation dtn``. Per step the node hands it its inbox and asks it for the radio's output:

* ``/<node>/dtn/in`` (raw BPv7 bytes, RFC 9171, stamped with the arrival time): a copy whose
  next-hop block names another node is counted (``overheard``; broadcast medium) and nothing more;
  anything else goes to :meth:`BundleAgent.receive` at the arrival time. :meth:`receive` returns the
  bundle when it was delivered here, so the node can act on its payload;
* ``/<node>/dtn/overheard`` (msgs_json CopiesOverheard from the medium): that many copies for other
  nodes, which the medium sent as one count instead of one envelope each (dtn_router/router.py):
  counted as if each had come on ``/<node>/dtn/in`` (``overheard``, the agent's
  ``discarded.not_next_hop``);
* ``/<node>/dtn/status`` (msgs_json TransmissionFailed from the medium, stamped when the attempt
  ended): the transmission goes back to the agent, re-routed without that contact;
* :meth:`radio`: the transmissions the agent's one radio starts up to the step time, emitted on
  ``/<node>/dtn/out`` stamped with their start times (computed in continuous time, so no figure
  depends on the step length), and the agent's events as msgs_json bundle events on
  ``/<node>/dtn/events`` (what a run's report is built from; ``events=False``: not published, for
  a caller that reads the agent's event records itself).

When a sent bundle is gone: the agent holds each transmission until the port settles it
(``AgentConfig.settle_delay_s=None``), and the port settles it when no failure report can still
come, by the contract's delivery rule alone (nothing emitted at step k is seen before step k+1): the
medium sees a transmission emitted at step j at step j+1, and reports a failure at the first of its
steps at or after both j+1 and the attempt's end; the report reaches the sender one step later. So
at step m every report about a transmission emitted at step <= m-2 that ended by t_{m-1} has
arrived: those are settled (the bundle leaves the agent and its persistent store). No step length,
no engine and no time-out enters (the same rule holds under the local and the ROS engine). The
port counts the steps it is called at: a node not called at every step (an event-driven one,
msgs_json/envelope.py rule 1) settles later, never earlier. At ``finish`` the port settles by the
same rule, as if finish were one more step.

How we know it is right: tests/unit/test_dtn_port.py (a failure report always finds its
transmission in flight, settling after two steps and the end, overheard copies counted, events
turned into messages), tests/faults/test_faults_link.py (a cut ends a contact mid-transmission:
the bundle is re-routed; conservation created = delivered + dropped + held) and the DTN-alone tests
(tests/unit/test_dtn_alone.py), which drive traffic nodes through the same port.
"""

from __future__ import annotations

from collections import deque

from msgs_json import codec
from msgs_json import schemas as S
from msgs_json import topics as T
from msgs_json.envelope import Emit, Envelope
from orbit_clock.contact_plan import node_name
from sat_node.dtn.agent import BundleAgent, ttl_s_for_priority
from sat_node.dtn.bpv7 import BundleError, Imc, decode_bundle
from sat_node.dtn.routing_blocks import next_hops_of, recipients_of

__all__ = ["DtnPort", "count_rejection"]

_NS = 1_000_000_000
_NO_INFO = object()  # sentinel: no _ev_info entry for an event
_INFO: dict[bytes, tuple[int, dict]] = {}  # received bytes -> (DTN epoch, _bundle_info): DtnPort._bundle_info
_INFO_MAX = 1024
_KEEP_EVENTS = 4096  # the agent's event list is emptied past this (memory stays flat over long runs)


def count_rejection(counts: dict[str, int], env: Envelope, exc: BaseException) -> str:
    """Count one message a node rejected (it never dies on one) under ``<topic leaf>.<exception>``."""
    reason = f"{env.topic.rsplit('/', 1)[-1]}.{type(exc).__name__}"
    counts[reason] = counts.get(reason, 0) + 1
    return reason


class DtnPort:
    """The lockstep side of ``agent`` for node ``name`` (see the module docstring)."""

    def __init__(self, name: str, agent: BundleAgent, *, events: bool = True):
        if agent.config.settle_delay_s is not None:
            raise ValueError(f"{name}: the port settles transmissions itself; "
                             "build the agent with AgentConfig(settle_delay_s=None)")
        if agent.events is None:
            raise ValueError(f"{name}: the port turns the agent's events into messages; keep_events must be True")
        if not agent.config.bundle_bits:
            raise ValueError(f"{name}: the port needs a fixed bundle size (AgentConfig.bundle_bits)")
        self.name = name
        self.agent = agent
        self.events = events  # publish the agent's events on /<node>/dtn/events (False: the caller reads them)
        self.in_topic = T.dtn_in_topic(name)
        self.status_topic = T.dtn_status_topic(name)
        self.out_topic = T.dtn_out_topic(name)
        self.events_topic = T.dtn_events_topic(name)
        self.counters_topic = T.dtn_counters_topic(name)
        self.overheard_topic = T.dtn_overheard_topic(name)
        self.overheard = 0
        self.tx_failed: dict[str, int] = {}
        self._ev_done = 0
        self._creations: dict[str, tuple[int, int]] = {}  # bundle id -> (gp, observation time) for BundleCreated
        self._ev_info: dict[int, dict | None] = {}  # id(event) -> what the received bundle said (None: overheard)
        self._next_hop: dict[str, str] = {}
        self._sent: deque = deque()  # (step index, Transmission) not settled yet, in send order
        self._steps = 0  # radio() calls so far: the step index
        self._prev_t = -1  # the previous step's time

    def subscriptions(self) -> list[str]:
        return [self.in_topic, self.status_topic, self.overheard_topic]

    # ------------------------------------------------------------------ inputs
    def originate(self, payload: bytes, dests, t_ns: int, *, gp: int = 0) -> list[str]:
        """The bundles for the ``(destination, priority)`` pairs of ``dests``, created at ``t_ns``: one
        per destination (unicast agent) or one for all of them (multicast agent, which has
        ``originate_many``); ``gp`` is what the BundleCreated messages name (the observed ground
        point). Returns the bundle ids."""
        dests = list(dests)
        if not dests:
            return []
        many = getattr(self.agent, "originate_many", None)
        if many is not None:
            bids = [many(payload, dests, t_ns)]
        else:
            bids = [self.agent.originate(payload, dest, prio, t_ns) for dest, prio in dests]
        for bid in bids:
            self._creations[bid] = (gp, t_ns)
        return bids

    def is_mine(self, topic: str) -> bool:
        return topic == self.in_topic or topic == self.status_topic or topic == self.overheard_topic

    def receive(self, env: Envelope, t_ns: int):
        """One envelope on the port's topics; the bundle when one was delivered to this node, else
        None. Raises ValueError (or KeyError/TypeError) on a bad message: the node counts it."""
        if env.topic == self.status_topic:
            self._on_status(codec.decode(env.topic, env.data), t_ns)
            return None
        if env.topic == self.overheard_topic:
            msg = codec.decode(env.topic, env.data)
            if msg.sat != self.name:
                raise ValueError(f"overheard copies of {msg.sat} on {self.name}'s topic")
            self.agent.overheard_count(msg.copies, env.t_ns)
            self.overheard += msg.copies
            return None
        if not isinstance(env.data, bytes):
            raise ValueError("bundle topic carries text")
        agent = self.agent
        if agent.overheard(env.data, env.t_ns):  # a copy for another node (broadcast medium)
            self.overheard += 1
            return None
        n_ev = len(agent.events)
        outcome = agent.receive(env.data, env.source, env.t_ns)
        if outcome == "discarded.not_next_hop":
            # overheard on the broadcast medium: counted (DtnCounters), not one event per copy
            self.overheard += 1
            if self.events:
                for ev in agent.events[n_ev:]:
                    self._ev_info[id(ev)] = None
            return None
        if not self.events:  # no event messages to write: what the bundle said is not needed
            return agent.last_received if outcome == "delivered" else None
        if outcome == "delivered" or outcome.startswith("discarded"):
            b = agent.last_received  # what receive() decoded from env.data (not altered)
            if b is None:
                try:
                    b = decode_bundle(env.data)
                except BundleError:
                    b = None
            if b is not None:
                info = self._bundle_info(b, env.data)
                for ev in agent.events[n_ev:]:
                    self._ev_info[id(ev)] = info
            if outcome == "delivered":
                return b
        return None

    def _on_status(self, st, t_ns: int) -> None:
        """The medium says a transmission failed: give the bundle back to the agent."""
        if st.sat != self.name:
            raise ValueError(f"status for {st.sat} on {self.name}'s topic")
        tx = self.agent.in_flight(st.bundle_id, st.start_ns)
        if tx is None or st.next_hop not in (tx.next_hops or (tx.next_hop,)):
            raise ValueError(f"status names no transmission of ours: {st.bundle_id} at {st.start_ns}")
        self.tx_failed[st.reason] = self.tx_failed.get(st.reason, 0) + 1
        self.agent.transmission_failed(tx, t_ns, st.next_hop)

    # ------------------------------------------------------------------ outputs
    def radio(self, t_ns: int) -> list[Emit]:
        """Once per step (and once in ``finish``), after the inbox: settle what can no longer fail,
        expire, and emit the radio's transmissions up to ``t_ns`` and the agent's events."""
        self._settle()
        agent = self.agent
        agent.expire(t_ns)
        emits: list[Emit] = []
        out_topic = self.out_topic
        step = self._steps
        next_hop = self._next_hop if self.events else None  # (read only by the event messages)
        for tx in agent.transmissions_until(t_ns):
            emits.append(Emit(out_topic, tx.bundle_bytes, tx.start_ns))
            if next_hop is not None:
                next_hop[(tx.bundle_id, tx.start_ns)] = tx.next_hop
            self._sent.append((step, tx))
        self._steps = step + 1
        self._prev_t = t_ns
        evs = agent.events
        if not self.events:  # nobody reads them here: forget what would turn them into messages
            if evs:
                del evs[:]
            if self._ev_info:
                self._ev_info.clear()
            if self._creations:
                self._creations.clear()
            if self._next_hop:
                self._next_hop.clear()
            return emits
        if len(evs) > self._ev_done:
            encode = codec.encode
            topic = self.events_topic
            for ev in evs[self._ev_done:]:
                msg = self._event_msg(ev)
                if msg is not None:
                    emits.append(Emit(topic, encode(msg), min(ev.t_ns, t_ns)))
        self._ev_done = len(evs)
        if len(evs) > _KEEP_EVENTS:
            del evs[:]
            self._ev_done = 0
            self._ev_info.clear()
        return emits

    def idle(self, t_ns: int) -> bool:
        """What :meth:`radio` does at a step at which the agent has nothing due by ``t_ns`` (no radio
        decision, expiry or new event since the last call: the caller knows, e.g. only copies for
        other nodes arrived before its wakeup): count the step and settle. True when something was
        settled (the next event may then be later)."""
        n = len(self._sent)
        self._settle()
        self._steps += 1
        self._prev_t = t_ns
        return len(self._sent) != n

    def next_event_ns(self, t_ns: int) -> int | None:
        """When a node that is not called at every step (msgs_json/envelope.py rule 1, event-driven)
        must next be called after ``t_ns``: the agent's next radio decision or expiry, or - while a
        transmission is not settled - its end (by then the medium must have heard of it, so that a
        failure is reported at that end), then the next steps until it is settled. None: nothing."""
        nxt = self.agent.next_event_ns()
        if self._sent:
            end = self._sent[0][1].end_ns  # the oldest unsettled transmission (the first to end)
            cand = end if end > t_ns else t_ns + 1
            if nxt is None or cand < nxt:
                nxt = cand
        return nxt

    def _settle(self) -> None:
        """Settle the transmissions whose failure report would have arrived by now (module docstring):
        emitted at least two steps ago and ended by the previous step's time."""
        sent, m, prev_t = self._sent, self._steps, self._prev_t
        settle = self.agent.settle
        while sent and sent[0][0] <= m - 2 and sent[0][1].end_ns <= prev_t:
            settle(sent.popleft()[1])

    def counters(self, *, rejected: int, rejected_by_reason: dict[str, int]) -> dict[str, int]:
        """The node's DTN counters now: overheard copies, bundles held (queued or in flight), the
        node's rejected messages (total and by reason), the agent's drops and discards by reason, and
        failed transmissions by reason. (What the engine rejects before a message reaches the node is
        the engine's count: report.json ``security``.) Reads only."""
        c = {"discarded.not_next_hop": self.overheard, "held": self.agent.held_count(),
             "rejected_messages": rejected}
        for k, v in rejected_by_reason.items():
            c[f"rejected.{k}"[:64]] = v
        for k, v in self.agent.counters.items():
            if k.startswith(("dropped.", "discarded.")) and k != "discarded.not_next_hop":
                c[f"agent.{k}"[:64]] = v
        for k, v in self.tx_failed.items():
            c[f"tx_failed.{k}"] = v
        return c

    def counters_emit(self, t_ns: int, *, rejected: int, rejected_by_reason: dict[str, int]) -> Emit:
        """The node's :meth:`counters` at ``t_ns`` as a DtnCounters envelope."""
        c = self.counters(rejected=rejected, rejected_by_reason=rejected_by_reason)
        return Emit(self.counters_topic, codec.encode(S.DtnCounters(sat=self.name, t_ns=t_ns, counters=c)), t_ns)

    # ------------------------------------------------------------------ events -> messages
    def _bundle_info(self, b, data: bytes | None = None) -> dict:
        """What the events of received bundle ``b`` say about it. ``data``: the bytes ``b`` was decoded
        from, as received (``b`` not altered since): the info is then a function of those bytes and
        the DTN epoch alone - unless it names this node -, kept for the other nodes in this process
        that receive the same bytes (a multicast copy reaches several recipients at once; the info is
        read, never changed)."""
        epoch = self.agent.config.epoch_dtn_ms
        if type(data) is bytes:
            hit = _INFO.get(data)
            if hit is not None and hit[0] == epoch:
                return hit[1]
        try:
            rs = recipients_of(b)
        except ValueError:
            rs = ()
        mine = not rs and isinstance(b.dest, Imc)  # the destination named is this node
        info = {"bundle_id": b.bundle_id, "src": node_name(b.src[0]),
                "dst": node_name(rs[0][0]) if rs else (self.name if isinstance(b.dest, Imc) else node_name(b.dest[0])),
                "priority": min((r[1] for r in rs), default=0),
                "creation_ns": (b.creation_ms - epoch) * 1_000_000,
                "hop_count": (b.hop_count[1] if b.hop_count else 0)}
        try:
            nhs = sorted(next_hops_of(b))
            if nhs:
                info["next_hop"] = node_name(nhs[0])
        except ValueError:
            pass
        if type(data) is bytes and not mine:
            if len(_INFO) >= _INFO_MAX:
                _INFO.clear()
            _INFO[data] = (epoch, info)
        return info

    def _event_msg(self, ev):
        """The agent's event as a msgs_json bundle event (None when it names no bundle we can tell)."""
        info = self._ev_info.pop(id(ev), _NO_INFO)
        if info is None:  # marked: an overheard copy's event, reported as a counter only
            return None
        if info is _NO_INFO:
            info = None
        base = {"sat": self.name, "t_ns": ev.t_ns}
        if info is not None:  # what the bundle said; the event's own recipient and priority come first
            bid, src, dst, prio, created = (info["bundle_id"], info["src"], ev.dest or info["dst"],
                                            ev.priority or info["priority"], info["creation_ns"])
        else:
            if ev.bundle_id == "?":
                return S.BundleDropped(**base, bundle_id="?", src=self.name, dst=self.name, priority=0,
                                       creation_ns=0, reason="malformed" if ev.kind == "dropped" else "other",
                                       detail=f"{ev.kind}.{ev.reason}") if ev.kind == "dropped" else None
            src = node_name(int(ev.bundle_id[3:].split(".", 1)[0]))
            bid, dst, prio, created = ev.bundle_id, ev.dest or self.name, ev.priority, ev.created_ns
        common = dict(base, bundle_id=bid, src=src, dst=dst, priority=prio, creation_ns=min(created, ev.t_ns))
        if ev.kind == "created":
            gp, obs_ns = self._creations.get(bid, (0, ev.t_ns))  # a multicast bundle: one event per recipient
            cfg = self.agent.config
            life = ev.deadline_ns - ev.created_ns if ev.deadline_ns > ev.created_ns else \
                int(ttl_s_for_priority(max(1, prio), cfg.ttl_s_by_priority) * _NS)
            return S.BundleCreated(**common, gp=gp, obs_t_ns=obs_ns, lifetime_ns=life, size_bits=cfg.bundle_bits)
        if ev.kind == "forwarded":
            return S.BundleForwarded(**common, next_hop=self._next_hop.pop((bid, ev.t_ns), dst))
        if ev.kind == "delivered":
            return S.BundleDelivered(**common, hop_count=(info or {}).get("hop_count", 0))
        if ev.kind == "dropped":
            reason = ev.reason if ev.reason in S.DROP_REASONS else "other"
            return S.BundleDropped(**common, reason=reason, detail=ev.reason)
        if ev.kind == "discarded":
            reason = ev.reason if ev.reason in ("not_next_hop", "duplicate") else "other"
            return S.CopyDiscarded(**common, reason=reason, intended_next_hop=(info or {}).get("next_hop"))
        return None
