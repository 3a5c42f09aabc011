"""One satellite's flight software as a lockstep participant (msgs_json/envelope.py contract).

Pure logic, no rclpy: the ROS engine hosts it in a satellite process (bringup/engine/ros/host.py), the
local engine in one process. It owns the satellite's three functions of docs/design.md section 2:

* scheduler - distributed mode: replans every ``scheduler.replan_period_s`` (and, with
  ``scheduler.replan_trigger = "news"``, as soon as delivered news makes a planned look worthless;
  ``"periodic"``: the period only, the study's scheme) over ``plan_lookahead_s`` with the world's planner (sat_node/scheduler/planner.py, the same one the
  ground uses) from what it knows: its own observations and those the DTN delivered (implicit
  consensus, Nag et al. section 4); centralized mode:
  executes the plan the ground uplinked at its last pass and downlinks its observations at each
  pass; non-agile mode: observes what passes under the nadir footprint;
* ACS - tracks the pointing target and reports each slew (/sat_XX/acs/state);
* DTN bundle agent - one BPv7 bundle per executed observation to its recipients (the satellites
  next on scene over the observed region, priority 1 = next; ``isl.forwarding = "multicast"``,
  sat_node/dtn/multicast.py) or one per recipient (``"unicast"``, sat_node/dtn/agent.py), routed by
  CGR and put on the bus by its port (sat_node/dtn/port.py: transmissions, the medium's failure
  reports, bundle events); bundles delivered here update what it knows.

Value knowledge (the :class:`~sat_node.scheduler.planner.Knowledge` it hands the planner): what
reached it only - its own looks and the inferences delivered bundles carry (sat_node/inference.py) -
turned into a value field by the scenario's knowledge model (``value.knowledge``,
sat_node/knowledge.py), plus every observation it knows of for Eq. 1. The instrument records the
true OSSE value at the observation time; the satellite infers it through its own noise and shares
that inference, with its insight about the region, in the observation's bundle. Every plan item and
executed look carries the time of the information it was planned with (``info_ns``).

Timing: an observation planned at t is emitted at the step covering t, stamped t (rule 2 of the
contract); the DTN radio's transmissions are computed in continuous time up to the step time and
emitted stamped with their start times, so no figure depends on the step length.

How we know it is right: the engine-equivalence system test (local vs ROS, identical traces,
tests/system/test_engines_equal.py); its plans are the planner's plans for what it knows
(tests/unit/test_planner.py); what it executes obeys the field of regard and the slew model, by
geometry recomputed independently of the project's code (tests/system/test_observation_physics.py);
hostile or malformed messages are rejected and counted (tests/faults/test_faults_hostile.py).

Transmission status: the ISL medium (dtn_router) reports a transmission that did not get through
(contact ended mid-transmission, e.g. an ISL cut; no contact; radio busy) on ``/sat_XX/dtn/status``;
the port gives it back to the agent, re-routed without that contact, and keeps every transmission
until no such report can come (sat_node/dtn/port.py, from the contract's delivery rule alone).
Oracle: tests/faults/test_faults_link.py (a cut ending a contact mid-transmission; conservation
created = delivered + dropped by reason + held).
"""

from __future__ import annotations

import dataclasses
import hashlib
import time
from collections import Counter
from dataclasses import dataclass

import numpy as np

from msgs_json import codec
from msgs_json import schemas as S
from msgs_json import topics as T
from msgs_json.envelope import Emit, Envelope, LiveState, StepResult
from orbit_clock.contact_plan import node_number
from sat_node import persist
from sat_node.acs import angle_between_deg, nadir_unit, unit_vectors
from sat_node.dtn.agent import AgentConfig
from sat_node.dtn.bpsec import IntegrityError
from sat_node.dtn.bpv7 import BundleError, decode_bundle, dtn_ms_of
from sat_node.dtn.downlink import GROUND_NODE, downlink_bundle
from sat_node.dtn.multicast import new_agent
from sat_node.dtn.port import DtnPort, count_rejection
from sat_node.dtn.rx_policy import admit
from sat_node.dtn.store import BundleStore
from sat_node.inference import Inference, decode_inference, encode_inference
from sat_node.knowledge import KnowledgeParams, KnowledgeState
from sat_node.operations.commands import CommandGuard, is_command
from sat_node.operations.notice import decode_notice, is_notice
from sat_node.operations.onboard import OnboardOperations, operations_for
from sat_node.operations.tasking import TaskBook
from sat_node.value import Belief, KnownLog, KnownObservation

__all__ = ["SatelliteLogic"]

_NS = 1_000_000_000


@dataclass
class _Item:
    gp: int
    t_ns: int
    value: float
    version: int
    info_ns: int | None = None  # time of the information the look was planned with


class SatelliteLogic(OnboardOperations):
    """Participant for satellite ``name``; ``world`` is a bringup.scenario.world.World."""

    def __init__(self, world, name: str, mode: str = "distributed", *, store_path: str | None = None,
                 dtn: bool | None = None, bpsec_key: bytes | None = None, command_key: bytes | None = None,
                 downlink_node: int = GROUND_NODE, ground_bundles: bool = False):
        if mode not in ("distributed", "centralized", "nonagile"):
            raise ValueError(f"mode {mode!r}: expected distributed, centralized or nonagile")
        self.name = name
        self.world = world
        self.mode = mode
        sc = world.scenario
        self.sc = sc
        self.belief = Belief.from_scenario(sc, name, world.n_gp, world.osse.n_slots)
        self.kstate = KnowledgeState(KnowledgeParams.from_scenario(sc), name)
        self.known: KnownLog = KnownLog()  # appended to only (prior_state keeps its columns)
        self._known_keys: set[tuple[int, int, str]] = set()
        self.plan: list[_Item] = []
        self.plan_version = 0
        self.target_km: np.ndarray | None = None  # what the boresight points at (None: nadir)
        self.last_obs_ns = -1
        self.last_obs_gp = -1  # GP of the last observation (one image may cover several, non-agile)
        self.replan_ns = int(round(sc.scheduler.replan_period_s * _NS))
        self.next_replan_ns: int | None = None
        self.scheduler_cpu_s = 0.0
        self._last_cpu_s = 0.0
        self._news_conflict = False
        self.news_replans_due = 0
        self.rejected = 0
        self.dtn = (mode == "distributed") if dtn is None else dtn
        self.pending_downlink: list[S.Observation] = []
        # centralized: each downlinked observation is a bundle to the ground segment (or, with a ground
        # gateway, to the gateway's peer node: sat_node/dtn/downlink.py); ground_bundles: the ground
        # uplinks bundles from the gateway's peer (/ground/bundles), delivered here
        if mode == "centralized" and bpsec_key is None:
            raise ValueError(f"satellite {name}: centralized downlinks are bundles signed with the "
                             "constellation's BPSec key (bpsec_key), given by the deployment")
        self._key = bpsec_key
        self._epoch_dtn_ms = dtn_ms_of(sc.epoch)
        self.downlink_node = int(downlink_node)
        self.ground_bundles = ground_bundles and mode == "centralized"
        self.from_ground: Counter[str] = Counter()  # what became of the bundles the ground uplinked
        # (bundle id, payload bytes, the payload's SHA-256, t_ns)
        self.delivered_from_ground: list[tuple[str, int, str, int]] = []
        self.ground_passes = sorted({int(round(c.start_s * _NS)) for c in world.ground_plan.contacts
                                     if c.src == name})
        self._next_pass_i = 0
        self.agent = None
        self.port = None  # the agent on the lockstep bus (sat_node/dtn/port.py)
        if self.dtn:
            if bpsec_key is None:
                raise ValueError(f"satellite {name}: DTN needs the constellation's BPSec key (bpsec_key), "
                                 "given by the deployment")
            i = sc.isl
            # settle_delay_s=None: the port settles each transmission when no failure report can come
            cfg = AgentConfig.for_policy(
                i.send_order, i.hop_tolerance_s, ttl_s_by_priority={1: i.ttl_p1_s, 3: i.ttl_p2_3_s, 15: i.ttl_p4_15_s},
                bundle_bits=i.bundle_bits, settle_delay_s=None, forwarding=i.forwarding, key=bpsec_key,
                epoch_dtn_ms=dtn_ms_of(sc.epoch))  # creation times: DTN time of the scenario clock
            store = BundleStore(store_path) if store_path else None
            # one contact graph per process, shared by its satellites (World.isl_graph)
            self.agent = new_agent(name, world.isl_graph(cfg.hop_limit), cfg, store=store)
            self.port = DtnPort(name, self.agent)
        self.rejected_by_reason: dict[str, int] = {}
        self.ops = operations_for(sc, name)
        # operator commands (sat_node/operations/commands.py): only in a run that takes some (scripted or
        # live; the deployment then gives this satellite its own command key, satellite_command_key:
        # never the shared BPSec key)
        self.guard = CommandGuard(name, command_key) if command_key is not None else None
        self._ops_emits: list[Emit] = []  # command events of this step's inbox
        self.tasks = TaskBook()  # tasking requests executed here (sat_node/operations/tasking.py)
        hk_s = getattr(getattr(sc, "operations", None), "hk_period_s", 0.0)
        self._hk_ns = round(hk_s * _NS) if hk_s else None  # housekeeping period (None: no housekeeping)
        self._next_hk_ns = 0 if self._hk_ns else None
        self._expected_ns: int | None = None  # the wake-up asked for at the last step

    # ------------------------------------------------------------------ contract
    def subscriptions(self) -> list[str]:
        subs = []
        if self.port is not None:
            subs += self.port.subscriptions()
        if self.mode == "centralized":
            subs.append(T.GROUND_UPLINK)
        if self.ground_bundles:
            subs.append(T.GROUND_BUNDLES)
        if self.guard is not None:
            subs.append(T.GROUND_COMMANDS)
        return subs

    def start(self, t0_ns: int) -> StepResult:
        emits: list[Emit] = []
        if self.mode == "distributed":
            self.next_replan_ns = t0_ns
            emits += self._replan(t0_ns)
        elif self.mode == "nonagile":
            emits += self._plan_nonagile(t0_ns)
        return StepResult(emits, self._wakeup(t0_ns))

    def step(self, t_ns: int, inbox: list[Envelope]) -> StepResult:
        """One lockstep step: the inbox, then the mode rules (sat_node/operations/modes.py), then
        what the mode allows (imaging, replanning), then the radio."""
        store = self.agent.store if self.agent is not None else None
        if store is None:
            return self._step(t_ns, inbox)
        # one store transaction per step (unless a caller's is open: the ROS host's checkpoint, or a
        # local run's batch, bringup/engine/store_batches.py)
        with store.step_batch():
            return self._step(t_ns, inbox)

    def _step(self, t_ns: int, inbox: list[Envelope]) -> StepResult:
        emits: list[Emit] = []
        for env in inbox:
            try:
                self._on_message(env, t_ns)
            except (ValueError, KeyError, TypeError) as exc:  # a bad message never kills the node
                self.rejected += 1
                count_rejection(self.rejected_by_reason, env, exc)
                self.last_error = f"{env.topic}: {exc}"
        emits += self._ops_emits
        self._ops_emits = []
        emits += self._acks_due(t_ns)
        emits += self._operations(t_ns)
        if self.ops.imaging:
            emits += self._execute(t_ns)
        else:  # looks that fall due while it does not image are lost (an uplinked plan, centralized)
            self.plan = [it for it in self.plan if it.t_ns > t_ns]
        periodic = self.next_replan_ns is not None and t_ns >= self.next_replan_ns
        if self.mode == "distributed" and self.ops.imaging and (periodic or self._news_conflict):
            emits += self._replan(t_ns, periodic=periodic)
            if self.agent is not None and periodic:
                emits.append(self._counters_emit(t_ns))
        if self.mode == "centralized":
            emits += self._downlink(t_ns)
        if self.agent is not None:
            emits += self._radio(t_ns)
        if self._next_hk_ns is not None and t_ns >= self._next_hk_ns:
            emits.append(self._housekeeping(t_ns))
            self._next_hk_ns = t_ns - t_ns % self._hk_ns + self._hk_ns
        wake = self._wakeup(t_ns)
        self._expected_ns = wake
        return StepResult(emits, wake)

    def finish(self, t_ns: int) -> list[Emit]:
        store = self.agent.store if self.agent is not None else None
        own_tx = store is not None and store.begin()
        try:
            return self._finish(t_ns)
        finally:
            if own_tx:
                store.commit()

    def _finish(self, t_ns: int) -> list[Emit]:
        emits = self._acks_due(t_ns)
        emits += self._execute(t_ns) if self.ops.imaging else []
        if self.agent is not None:
            emits += self._radio(t_ns)
            emits.append(self._counters_emit(t_ns))
        return emits

    def live_state(self, t_ns: int) -> LiveState:
        """What the satellite shows while a ROS run goes on (msgs_json.envelope.LiveState): where it
        is (the world's SGP4 position, the bag's fix), its plan, what it knows, what it points at and
        its DTN counters. Reads only."""
        r = self.world.sat_positions_ecef_km(t_ns / _NS)[self.world.sat_names.index(self.name)]
        own = sum(1 for k in self.known if k.source == self.name and not k.planned)
        v: dict[str, int | float | str] = {
            "mode": self.mode, "plan.version": self.plan_version, "plan.items": len(self.plan),
            "plan.next_observation_s": round(self.plan[0].t_ns / _NS, 3) if self.plan else -1.0,
            "observations.own": own, "observations.known": len(self.known),
            "pointing": "nadir" if self.target_km is None else "last target",
            "scheduler.cpu_s": round(self.scheduler_cpu_s, 3), "rejected_messages": self.rejected,
            "ops.mode": self.ops.mode,
        }
        for k, n in self.rejected_by_reason.items():
            v[f"rejected.{k}"] = n
        held = 0
        if self.port is not None:
            c = self.port.counters(rejected=self.rejected, rejected_by_reason=self.rejected_by_reason)
            held = c["held"]
            v.update((f"dtn.{k}", n) for k, n in c.items() if k != "rejected_messages" and not k.startswith("rejected."))
            v.update((f"dtn.events.{k}", n) for k, n in self.agent.counters.items())
        msg = f"{own} observations, plan v{self.plan_version} ({len(self.plan)} left)"
        if self.port is not None:
            msg += f", {held} bundles held"
        if self.rejected:
            msg += f", {self.rejected} messages rejected"
        return LiveState(tuple(float(x) for x in r), v, 1 if self.rejected else 0, msg)

    # -- checkpoints (bringup/engine/checkpoint.py calls these; sat_node/persist.py does the work)
    def snapshot(self) -> bytes:
        """Everything this satellite knows besides its stored bundles (sat_node/persist.py)."""
        return persist.snapshot(self)

    def restore(self, blob: bytes) -> None:
        """Put a :meth:`snapshot` back into this satellite, freshly built for the same world and name."""
        persist.restore(self, blob)

    def persistent_connection(self):
        """The bundle store's SQLite connection (None without a store file): the checkpoint row
        goes into it, in the step's transaction."""
        return persist.persistent_connection(self)

    def close(self) -> None:
        """Close the bundle store (after ``finish``; the file keeps every committed step)."""
        store = self.agent.store if self.agent is not None else None
        if store is not None:
            store.close()

    def _counters_emit(self, t_ns: int) -> Emit:
        return self.port.counters_emit(t_ns, rejected=self.rejected, rejected_by_reason=self.rejected_by_reason)

    # ------------------------------------------------------------------ inputs
    def _on_message(self, env: Envelope, t_ns: int) -> None:
        port = self.port
        if port is not None and port.is_mine(env.topic):
            b = port.receive(env, t_ns)
            if b is not None and is_notice(b.payload):  # a neighbour's mode notice
                self._on_notice(decode_notice(b.payload))
            elif b is not None and is_command(b.payload) and self.guard is not None:  # relayed over ISLs
                self._on_command(b.payload, t_ns)
            elif b is not None:  # delivered here: what another satellite observed
                inf = decode_inference(b.payload)
                if not 0 <= inf.gp < self.world.n_gp or inf.region != self.world.region_of_gp(inf.gp):
                    raise ValueError(f"inference payload: GP {inf.gp} / region {inf.region} not of this world")
                self._learn(inf.gp, inf.t_ns, inf.src)
                self.kstate.learn(inf)
                self._check_news(inf.gp, inf.t_ns)
        elif env.topic == T.GROUND_BUNDLES:
            self._on_ground_bundle(codec.decode(env.topic, env.data), t_ns)
        elif env.topic == T.GROUND_COMMANDS:
            self._on_uplinked_command(codec.decode(env.topic, env.data), t_ns)
        elif env.topic == T.GROUND_UPLINK:
            up = codec.decode(env.topic, env.data)
            if up.sat != self.name:
                return
            start = max(t_ns, self.last_obs_ns + 1)
            self.plan_version = up.schedule.version
            self.plan = [_Item(it.gp, it.t_ns, it.value, up.schedule.version, it.info_ns)
                         for it in up.schedule.items if it.t_ns >= start]

    def _check_news(self, gp: int, obs_ns: int) -> None:
        """News that makes a look of the current plan worthless (the GP seen by another satellite
        within revisit_zero_s of it) triggers a replan at this step, before the periodic one: the
        scheduler "replans as news arrives" (Nag et al., section 4)."""
        if self.sc.scheduler.replan_trigger == "periodic":  # the study's scheme: news waits for the period
            return
        zero_ns = int(round(self.sc.value.revisit_zero_s * _NS))
        for it in self.plan:
            if it.gp == gp and it.t_ns > self.last_obs_ns and abs(it.t_ns - obs_ns) < zero_ns:
                self._news_conflict = True
                self.news_replans_due += 1
                return

    def _learn(self, gp: int, obs_ns: int, src: str) -> None:
        key = (gp, obs_ns, src)
        if key not in self._known_keys:
            self._known_keys.add(key)
            self.known.append(KnownObservation(obs_ns / _NS, gp, src))
            if self.tasks.tasks:
                self.tasks.observed(gp, obs_ns, src)

    # ------------------------------------------------------------------ planning
    def _plan(self, t0_ns: int, window_s: float, solver: str = "dp"):
        """The world's planner on what this satellite knows now (its knowledge model over its own
        looks and the delivered inferences, its belief noise, every observation it knows of); it
        points at ``target_km``."""
        t0_s = t0_ns / _NS
        gps = self.world.gps
        knowledge = self.kstate.knowledge(self.world.osse, gps.region_index, gps.ecef_km, t0_s, self.known,
                                          self.belief)
        overlay = self.tasks.overlay(self.name, t0_ns) if self.tasks.tasks else None
        if overlay is not None:  # the GPs of interest of the tasks this satellite executed
            knowledge = dataclasses.replace(knowledge, tasks=overlay)
        partners = None  # every other satellite (the planner's default) unless some told they do not image
        down = self.ops.peers_not_imaging()
        if down:
            partners = [(n, t0_s) for n in self.world.sat_names if n != self.name and n not in down]
        return self.world.planner.plan(self.name, t0_s, window_s, knowledge, init_target_km=self.target_km,
                                       solver=solver, partners=partners)

    def _items(self, plan, t0_ns: int, version: int) -> list[_Item]:
        """A plan's looks as items, each with the information time of its GP's region."""
        if plan is None:
            return []
        t0_s = t0_ns / _NS
        region = self.world.gps.region_index
        info = {}
        out = []
        for (gp, t_s), v in zip(plan.as_list(), plan.values):
            r = int(region[gp])
            if r not in info:
                info[r] = int(round(self.kstate.info_time_s(r, t0_s) * _NS))
            out.append(_Item(int(gp), int(round(t_s * _NS)), float(v), version, info[r]))
        return out

    def _replan(self, t_ns: int, *, periodic: bool = True) -> list[Emit]:
        """Plan [t_ns, t_ns + lookahead) with what is known now. A periodic replan sets the next
        one; a replan for news (``periodic=False``) leaves the periodic schedule as it is."""
        c0 = time.process_time()
        self._news_conflict = False
        horizon_ns = self.world.scenario.horizon_ns
        if periodic:
            self.next_replan_ns = t_ns + self.replan_ns
            window_s = min(self.sc.scheduler.plan_lookahead_s, (horizon_ns - t_ns) / _NS)
        else:  # keep the current plan's end: the next periodic replan takes over from there
            window_s = (min(horizon_ns, (self.next_replan_ns or t_ns) - self.replan_ns
                            + int(self.sc.scheduler.plan_lookahead_s * _NS)) - t_ns) / _NS
        if window_s <= 0:
            return []
        plan = self._plan(t_ns, window_s)
        self._last_cpu_s = time.process_time() - c0
        self.scheduler_cpu_s += self._last_cpu_s
        self.plan_version += 1
        items = self._items(plan, t_ns, self.plan_version)
        self.plan = [it for it in items if it.t_ns > self.last_obs_ns]
        return [self._schedule_emit(t_ns, t_ns)]

    def _plan_nonagile(self, t0_ns: int) -> list[Emit]:
        c0 = time.process_time()
        window_s = (self.world.scenario.horizon_ns - t0_ns) / _NS
        plan = self._plan(t0_ns, window_s, solver="nonagile")
        self._last_cpu_s = time.process_time() - c0
        self.scheduler_cpu_s += self._last_cpu_s
        self.plan_version = 1
        self.plan = self._items(plan, t0_ns, 1)
        return [self._schedule_emit(t0_ns, t0_ns)]

    def _schedule_emit(self, t_ns: int, cutoff_ns: int) -> Emit:
        msg = S.Schedule(sat=self.name, version=self.plan_version, mode=self.mode, planned_ns=t_ns,
                         cutoff_ns=cutoff_ns, solve_cpu_s=self._last_cpu_s,
                         items=[S.ScheduleItem(gp=it.gp, t_ns=it.t_ns, value=max(0.0, it.value), info_ns=it.info_ns)
                                for it in self.plan])
        return Emit(T.schedule_topic(self.name), codec.encode(msg), t_ns)

    # ------------------------------------------------------------------ execution
    def _execute(self, t_ns: int) -> list[Emit]:
        emits: list[Emit] = []
        gps = self.world.gps
        osse = self.world.osse
        while self.plan and self.plan[0].t_ns <= t_ns:
            it = self.plan.pop(0)
            # already past; GPs of one image (the non-agile footprint covers several) come in id order
            if it.t_ns < self.last_obs_ns or (it.t_ns == self.last_obs_ns and it.gp <= self.last_obs_gp):
                continue
            recorded = float(osse.value_at(np.array([it.gp]), np.array([it.t_ns / _NS]))[0])
            # what the satellite infers from its image: the recorded value through its own noise
            inferred = recorded * float(self.belief.factor(it.gp, osse.slot_of(it.t_ns / _NS)))
            target = gps.ecef_km[it.gp]
            angle = self._slew_angle(it.t_ns, target)
            self.target_km = target
            self.last_obs_ns = it.t_ns
            self.last_obs_gp = it.gp
            obs = S.Observation(sat=self.name, gp=it.gp, t_ns=it.t_ns, assumed_value=max(0.0, it.value),
                                recorded_value=recorded, schedule_version=it.version,
                                info_ns=None if it.info_ns is None else min(it.info_ns, it.t_ns))
            emits.append(Emit(T.observations_topic(self.name), codec.encode(obs), it.t_ns))
            state = S.AcsState(sat=self.name, t_ns=it.t_ns, mode="settled", target_gp=it.gp,
                               slew_angle_deg=float(min(180.0, angle)))
            emits.append(Emit(T.acs_state_topic(self.name), codec.encode(state), it.t_ns))
            self._learn(it.gp, it.t_ns, self.name)
            inf = self.kstate.observe(osse, it.gp, it.t_ns, inferred, self.world.region_of_gp(it.gp))
            if self.mode == "centralized":
                self.pending_downlink.append(obs)
            if self.agent is not None:
                if self.ops.reason == "store_full":  # the store refuses new bundles
                    self.ops.bundles_not_stored += 1
                else:
                    emits += self._originate(inf)
        return emits

    def _slew_angle(self, t_ns: int, target: np.ndarray) -> float:
        pos = self.world.constellation.track_ecef_km(self.name, np.array([t_ns / _NS]))[0]
        new = unit_vectors(target - pos)
        old = nadir_unit(pos) if self.target_km is None else unit_vectors(self.target_km - pos)
        return float(angle_between_deg(old[None, :], new[None, :])[0])

    # ------------------------------------------------------------------ DTN
    def _originate(self, inf: Inference) -> list[Emit]:
        payload = encode_inference(inf)
        self.port.originate(payload, self.world.destinations(inf.gp, inf.t_ns / _NS, self.name), inf.t_ns,
                            gp=inf.gp)
        return []

    def _radio(self, t_ns: int) -> list[Emit]:
        return self.port.radio(t_ns)

    # ------------------------------------------------------------------ centralized
    def _downlink(self, t_ns: int) -> list[Emit]:
        emits: list[Emit] = []
        while self._next_pass_i < len(self.ground_passes) and self.ground_passes[self._next_pass_i] <= t_ns:
            pass_ns = self.ground_passes[self._next_pass_i]
            self._next_pass_i += 1
            station = self._station_at(pass_ns)
            obs = [o for o in self.pending_downlink if o.t_ns <= pass_ns]
            bundles = [downlink_bundle(o, self._key, self._epoch_dtn_ms, self.downlink_node) for o in obs]
            msg = S.GroundDownlink(station=station, sat=self.name, t_ns=pass_ns, observations=obs,
                                   bundles=bundles)
            self.pending_downlink = [o for o in self.pending_downlink if o.t_ns > pass_ns]
            emits.append(Emit(T.GROUND_DOWNLINK, codec.encode(msg), pass_ns))
        return emits

    def _on_ground_bundle(self, msg: S.GroundBundle, t_ns: int) -> None:
        """A bundle the ground uplinked (from the gateway's peer): the BIB checked when present,
        bundles of other stacks accepted (the ground applied the gateway's policy), delivered when
        it is for this satellite; every outcome counted in ``from_ground``."""
        if msg.sat != self.name:
            return
        try:
            b = decode_bundle(msg.bundle)
            admit(b, self._key, "accept", counts=self.from_ground)
        except (BundleError, IntegrityError) as exc:
            self.from_ground["refused"] += 1
            self.last_error = f"{T.GROUND_BUNDLES}: {exc}"
            return
        if b.dest[0] != node_number(self.name):
            self.from_ground["not_for_this_satellite"] += 1
            return
        self.from_ground["delivered"] += 1
        digest = hashlib.sha256(b.payload).hexdigest()
        self.delivered_from_ground.append((b.bundle_id, len(b.payload), digest, t_ns))

    def ground_deliveries(self) -> dict | None:
        """What became of the bundles the ground uplinked to this satellite (its counters, and each
        one delivered: id, payload bytes, payload SHA-256, t_ns); None when none came."""
        if not (self.from_ground or self.delivered_from_ground):
            return None
        return {"counters": dict(sorted(self.from_ground.items())),
                "bundles": [{"bundle": b, "payload_bytes": n, "payload_sha256": h, "t_ns": t}
                            for b, n, h, t in self.delivered_from_ground]}

    def _station_at(self, pass_ns: int) -> str:
        for c in self.world.ground_plan.contacts:
            if c.src == self.name and int(round(c.start_s * _NS)) == pass_ns:
                return c.dst
        raise ValueError(f"{self.name}: no ground contact starts at {pass_ns} ns")

    # ------------------------------------------------------------------ timing
    def _wakeup(self, t_ns: int) -> int | None:
        cands = []
        if self.mode == "distributed" and self.next_replan_ns is not None and self.ops.imaging:
            cands.append(self.next_replan_ns)
        if self.mode == "centralized" and self._next_pass_i < len(self.ground_passes):
            cands.append(self.ground_passes[self._next_pass_i])
        if self._next_hk_ns is not None:
            cands.append(self._next_hk_ns)
        fault_ns = self.ops.faults.next_change_ns(t_ns)
        if fault_ns is not None:
            cands.append(fault_ns)
        ack_ns = self._next_ack_ns()  # a command acknowledgement's downlink (sat_node/operations/onboard.py)
        if ack_ns is not None:
            cands.append(ack_ns)
        cands = [c for c in cands if c > t_ns]
        return min(cands) if cands else None
