"""The ground segment of the centralized mode as a lockstep participant (Nag et al., section 5).

The ground station learns what the satellites observed only when they downlink at a pass over a
ground station (``/ground/downlink``), and commands them only at a pass (``/ground/uplink``). At
each downlink it schedules that satellite with the same planner as onboard
(sat_node/scheduler/planner.py) from what the ground knows: every downlinked observation, plus the
plans it uplinked to the other satellites, all treated as commitments that outrank the satellite
being planned (so two satellites are not sent to the same GP within 15 min, whatever their rank:
the onboard rank rule, where a lower-ranked satellite yields, does not hold here because that
satellite cannot be told until its own next pass), and uplinks the plan covering the time until
that satellite's next pass (plus one replan period of overlap). At the start it uplinks a first
plan to every satellite (as commanded before the run). With joint planning
(``scheduler.joint_planning``) the satellite is planned together with the others whose fields of
regard reach its GPs after their uplinked plans end (sat_node/scheduler/planner.py): the ground
cannot change what it already uplinked, but it does not give this satellite a GP another one will
be better placed to take.

Downlinks are bundles (sat_node/dtn/downlink.py): the ground segment runs a bundle agent with the
satellites' persistent store (ground_station/ground_agent.py) that receives each downlinked bundle at
its pass and delivers it (or, with a ground gateway, forwards it to the gateway's peer,
ground_station/gateway.py); the observation the ground learns is the one the bundle carries.
Bundles the gateway's peer sends go up to their satellite at its next pass (``/ground/bundles``).

Value knowledge: what was downlinked only. The ground processes each downlinked observation itself
(the recorded value through its own seeded inference noise) and keeps it in its
:class:`~sat_node.knowledge.KnowledgeState`; the scenario's knowledge model (``value.knowledge``,
sat_node/knowledge.py) turns that into the value it plans with - the same models as onboard, with
information as old as the satellites' passes make it. Each uplinked item carries the time of the
information it was planned with (``info_ns``).

Oracle (tests/unit/test_ground_segment.py, a local-engine centralized run): every executed
observation of a satellite is an item of the last plan uplinked to it; no GP is observed by two
satellites within 15 min; each observation reaches the ground in exactly one downlink, at a pass
after it. tests/unit/test_planner.py: the uplinked plans are the planner's plans for what the ground
knows.
"""

from __future__ import annotations

import time

from msgs_json import codec
from msgs_json import schemas as S
from msgs_json import topics as T
from msgs_json.envelope import Emit, Envelope, StepResult
from sat_node.dtn.downlink import GROUND_NODE
from sat_node.knowledge import KnowledgeParams, KnowledgeState
from sat_node.value import Belief, KnownObservation

from .ground_agent import GroundAgent

__all__ = ["GroundLogic", "GROUND_NAME"]

GROUND_NAME = "ground_station"
# Source of the uplinked plans of other satellites when the ground plans one satellite: sorts before
# every satellite name, so the rank rule of sat_node.value.prior_state makes them outrank everyone.
COMMITTED = ""
_NS = 1_000_000_000


class GroundLogic:
    """``bpsec_key``: the constellation's key (the ground's bundle agent checks the downlinks' BIBs;
    None: no agent - the ground can plan (start) but refuses downlinks); ``store_path``: its bundle
    store (None: in memory); ``gateway``: a started ground_station.gateway.Gateway (None: none)."""

    name = GROUND_NAME

    def __init__(self, world, bpsec_key: bytes | None = None, *, store_path: str | None = None, gateway=None):
        self.world = world
        self.gateway = gateway
        self.dtn = None if bpsec_key is None else GroundAgent(
            world, bpsec_key, store_path=store_path, peer_node=None if gateway is None else gateway.spec.node,
            foreign="accept" if gateway is None else gateway.spec.foreign)
        self._to_peer: dict[str, object] = {}  # bundle id -> transmission handed to the gateway
        sc = world.scenario
        self.sc = sc
        self.sats = list(world.sat_names)
        self.belief = Belief.from_scenario(sc, GROUND_NAME, world.n_gp, world.osse.n_slots)
        self.kstate = KnowledgeState(KnowledgeParams.from_scenario(sc), GROUND_NAME)
        self.downlinked: list[KnownObservation] = []
        self.planned: dict[str, list[KnownObservation]] = {s: [] for s in self.sats}
        self.plan_end_ns: dict[str, int] = {s: 0 for s in self.sats}  # end of each uplinked plan's window
        self.version = 0
        self.scheduler_cpu_s = 0.0
        self.rejected = 0
        passes: dict[str, list[tuple[int, int, str]]] = {s: [] for s in self.sats}
        for c in world.ground_plan.contacts:
            if c.src in passes:
                passes[c.src].append((int(round(c.start_s * _NS)), int(round(c.end_s * _NS)), c.dst))
        self.passes = {s: sorted(v) for s, v in passes.items()}
        self.margin_ns = int(round(sc.scheduler.replan_period_s * _NS))

    def subscriptions(self) -> list[str]:
        return [T.GROUND_DOWNLINK]

    def start(self, t0_ns: int) -> StepResult:
        emits = []
        for sat in self.sats:
            station = self.world.station_nodes[0] if self.world.station_nodes else "gs_ground"
            emits.append(self._plan_and_uplink(sat, t0_ns, station))
        return StepResult(emits, self._wakeup(t0_ns))

    def step(self, t_ns: int, inbox: list[Envelope]) -> StepResult:
        store = self.dtn.store if self.dtn is not None else None
        if store is None:
            return self._step(t_ns, inbox)
        with store.step_batch():  # one store transaction per step, as a satellite's
            return self._step(t_ns, inbox)

    def _step(self, t_ns: int, inbox: list[Envelope]) -> StepResult:
        emits = []
        if self.gateway is not None:
            self._from_gateway(t_ns)
        for env in inbox:
            try:
                dl = codec.decode(env.topic, env.data)
            except ValueError:
                self.rejected += 1
                continue
            if dl.sat not in self.planned or self.dtn is None:
                self.rejected += 1
                continue
            osse, region = self.world.osse, self.world.gps.region_index
            for data in dl.bundles:
                try:  # what the downlinked bundle carries, once the ground's agent took it
                    o = self.dtn.downlink(data, dl.sat, dl.t_ns)
                except ValueError:
                    self.rejected += 1
                    continue
                if o is None:
                    continue
                self.downlinked.append(KnownObservation(o.t_ns / _NS, o.gp, o.sat))
                inferred = o.recorded_value * float(self.belief.factor(o.gp, osse.slot_of(o.t_ns / _NS)))
                self.kstate.observe(osse, o.gp, o.t_ns, inferred, int(region[o.gp]), src=o.sat)
            # what it planned for that satellite up to the pass is now known as executed (or not)
            self.planned[dl.sat] = [k for k in self.planned[dl.sat] if k.t_s * _NS > dl.t_ns]
            emits.append(self._plan_and_uplink(dl.sat, t_ns, dl.station))
        emits += self._transmit(t_ns)
        return StepResult(emits, self._wakeup(t_ns))

    def finish(self, t_ns: int) -> list[Emit]:
        if self.dtn is None:
            return []
        if self.gateway is not None:
            self._from_gateway(t_ns)
        emits = self._transmit(t_ns)
        if self.gateway is not None:  # the peer's acknowledgments of what is on its way
            self.gateway.flush()
            self._from_gateway(t_ns)
        return emits

    def close(self) -> None:
        """Close the ground's bundle store (after ``finish``)."""
        if self.dtn is not None:
            self.dtn.close()

    # ------------------------------------------------------------------ the bundle agent
    def _from_gateway(self, t_ns: int) -> None:
        """What the gateway brought since the last step: acknowledgments, then the peer's bundles."""
        for bid in self.gateway.take_acks():
            tx = self._to_peer.pop(bid, None)
            if tx is not None:
                self.dtn.acknowledged(tx)
        for data in self.gateway.take_received():
            self.dtn.from_peer(data, t_ns)

    def _transmit(self, t_ns: int) -> list[Emit]:
        if self.dtn is None:
            return []
        ups, to_peer = self.dtn.transmissions(t_ns)
        for tx in to_peer:
            if self.gateway is None:  # (the graph has no peer contact without a gateway)
                raise RuntimeError(f"ground agent sent bundle {tx.bundle_id} to a peer without a gateway")
            self._to_peer[tx.bundle_id] = tx
            self.gateway.submit(tx.bundle_id, tx.bundle_bytes)
        return [Emit(T.GROUND_BUNDLES, codec.encode(S.GroundBundle(station=u.station, sat=u.sat, t_ns=u.t_ns,
                                                                      bundle=u.data)), u.t_ns) for u in ups]

    def _wakeup(self, t_ns: int) -> int | None:
        cands = []
        nxt = self.dtn.next_event_ns() if self.dtn is not None else None
        if nxt is not None:
            cands.append(max(nxt, t_ns + 1))
        if self.gateway is not None:  # look for the peer's bundles and acknowledgments this often
            cands.append(t_ns + self.gateway.poll_ns)
        return min(cands) if cands else None

    def gateway_report(self) -> dict:
        """The ground agent's and the gateway's counters (the run writes them to gateway.json)."""
        d = self.dtn
        out = {"ground_node": f"ipn:{GROUND_NODE}", "agent": dict(sorted(d.counters.items())),
               "rx_policy": dict(sorted(d.agent.rx_counts.items())),
               "events": dict(sorted(d.agent.counters.items())), "held_at_end": d.held(),
               "uplinked": [{"bundle": b, "sat": s, "t_ns": t} for b, s, t in d.uplinked],
               "from_peer": [{"bundle": b, "dest": e, "t_ns": t, "result": r} for b, e, t, r in d.peer_log],
               "awaiting_acknowledgment": len(self._to_peer)}
        if self.gateway is not None:
            out["gateway"] = self.gateway.report()
        return out

    def _next_pass_after(self, sat: str, t_ns: int) -> int | None:
        for s, e, _ in self.passes[sat]:
            if s > t_ns:
                return s
        return None

    def _plan_and_uplink(self, sat: str, t_ns: int, station: str) -> Emit:
        c0 = time.process_time()
        horizon_ns = self.world.scenario.horizon_ns
        nxt = self._next_pass_after(sat, t_ns)
        end_ns = min(horizon_ns, (nxt if nxt is not None else horizon_ns) + self.margin_ns)
        window_s = (end_ns - t_ns) / _NS
        items: list[S.ScheduleItem] = []
        plan = None
        if window_s > 0:
            known = list(self.downlinked)
            for other, ks in self.planned.items():
                if other != sat:
                    # Plans already uplinked are commitments: the other satellite executes them until
                    # its next pass, whatever its rank. Claimed under COMMITTED (sorts before every
                    # satellite name), sat_node.value.prior_state makes the GP worth 0 within 15 min
                    # before or after them for every satellite planned later.
                    known += [KnownObservation(k.t_s, k.gp, COMMITTED, planned=True) for k in ks]
            # what the downlinks told the ground, through its knowledge model and belief noise
            gps = self.world.gps
            knowledge = self.kstate.knowledge(self.world.osse, gps.region_index, gps.ecef_km, t_ns / _NS, known,
                                              self.belief)
            # joint planning: the others are free from the end of their uplinked plans on
            partners = [(o, self.plan_end_ns[o] / _NS) for o in self.sats if o != sat]
            plan = self.world.planner.plan(sat, t_ns / _NS, window_s, knowledge, partners=partners)
            self.plan_end_ns[sat] = end_ns
        if plan is not None:
            self.planned[sat] = [KnownObservation(t_s, int(gp), sat, planned=True) for gp, t_s in plan.as_list()]
            region = self.world.gps.region_index
            items = [S.ScheduleItem(gp=int(gp), t_ns=int(round(t_s * _NS)), value=max(0.0, float(v)),
                                    info_ns=int(round(self.kstate.info_time_s(int(region[gp]), t_ns / _NS) * _NS)))
                     for (gp, t_s), v in zip(plan.as_list(), plan.values)]
        cpu = time.process_time() - c0
        self.scheduler_cpu_s += cpu
        self.version += 1
        sched = S.Schedule(sat=sat, version=self.version, mode="centralized", planned_ns=t_ns,
                           cutoff_ns=t_ns, items=items, solve_cpu_s=cpu)
        up = S.GroundUplink(station=station, sat=sat, t_ns=t_ns, schedule=sched)
        return Emit(T.GROUND_UPLINK, codec.encode(up), t_ns)
