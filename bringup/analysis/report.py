"""report.json from a run's envelopes (docs/design.md section 6), the same function for a live run and a bag.

Inputs: the envelopes of a run (observations, bundle events, schedules), the run's metadata
(scenario, mode, engine, seed, horizon, n_sats, n_gp) and the runtime figures. Everything but
``runtime.*`` is a pure function of the envelopes, so ``constellation report BAG`` rebuilds the
report written by the run.

Definitions:
* value.cumulative - Eq. 1 of the study over every executed observation in time order (ties by
  satellite name): ``recorded / (times seen + 1)``, 0 if the GP was seen within
  ``revisit_zero_s``; ``recorded`` is the OSSE value the instrument measured (Observation.
  recorded_value).
* observations.duplicates_15min - observations of a GP seen (by anyone) less than revisit_zero_s
  before; observations.duplicate_fraction - their share.
* value.assumed_error_mean - mean over observations with a true Eq. 1 value > 0 of
  |assumed - true| / true, where assumed is what the planner expected (Observation.assumed_value).
* value.assumed_error - mean, median, sum-based, same-slot / other-slot: bringup/analysis/assumed_error.py.
* value.first_look_share - the share of value.cumulative that came from the first look at each GP.
* coverage.gp_observed_fraction - distinct GPs observed / GPs of the scenario;
  coverage.looks_per_gp - observations / GPs of the scenario.
* knowledge.info_age_s.{mean,median,p90} - over executed looks that carry it
  (``Observation.info_ns``), the look's time minus the time of the newest information about its
  region the planner had when it planned the look (sat_node/knowledge.py); ``knowledge.model`` the
  run's knowledge model and ``knowledge.info_age_s.hist`` counts per ``hist_edges_s`` bin.
* osse.rank_corr_15min, osse.rank_corr_60min, osse.transiency_min - the truth field's rank
  statistics (ground_station/osse_stats.py); the other osse.*, ground.*, looks.*: case_figures.py.
* dtn.* - sat_node/dtn/stats.py over the bundle events (first delivery per bundle counts).
* operations.* - time in mode, value lost to faults, commands: bringup/analysis/operations.py.
* partial, horizon_reached_s - a report of a run that reached its horizon (the bag holds the run's
  closing /run/meta record and its file is complete) has ``partial`` false and
  ``horizon_reached_s`` = ``horizon_s``; one rebuilt from a bag that ends early (the run failed or
  a process was killed; bringup/recording/bag_reader.py recovers a cut file) has ``partial`` true, the
  last sim time the bag holds, and a ``recording`` section saying what was recovered and lost.
* messages_rejected_in_report, report_rejections - payloads the report does not count: ones that
  do not decode, and observations outside the run (a GP index not below the scenario's ``n_gp``, a
  time after the horizon, a recorded value outside the OSSE's VALUE_MIN..VALUE_MAX
  (ground_station/osse.py), a ``sat`` other than its topic's), by reason.
* security.* - what the run's processes rejected before acting on it (no MAC under the run key,
  a MAC that does not verify, malformed, an ack from no host of the run), from the /run/meta
  record the ROS clock writes: :func:`security_figures`.
* integrity.status, integrity.detail - whether the bag's content is what its run sealed
  (bringup/recording/bag_seal.py): ``verified``, or ``unverified`` (no seal, another user's key,
  or read past a failed check with ``--unverified``); a bag whose seal fails is refused unless
  the caller reads it anyway.
* consensus.* - ISL-delayed implicit consensus (Nag et al. section 4), see
  :func:`consensus_figures`: for each pair of successive passes of different satellites over a
  region, whether the earlier satellite's observations reached the later one (bundle delivered)
  before it planned the pass (the ``planned_ns`` of the schedule version its first observation of
  the pass came from), and how many duplicate observations (same GP within ``revisit_zero_s``) the
  later satellite made of GPs whose news it did not have when planning ("late news").

Why one module: ReportBuilder decodes each envelope once, as the run writes it (the recorder beside a
local run) or as a bag is read; every section's decoding stays in its ``add`` so a live run's report
and a bag's come from the same code (the figures themselves live in their own modules).

Oracle: the value, duplicate, first-look, assumed-error and coverage figures of a bag of nine
observations worked out by hand (tests/unit/test_report_value.py); the consensus figures on a
hand-worked pair of passes (tests/faults/test_faults_link.py); out-of-range payloads and partial bags
in tests/faults/test_hostile_inputs.py and tests/faults/test_recorder_kill.py;
the report built beside the run equals ``build_report`` over the same envelopes
(tests/unit/test_record_process.py), and the report rebuilt from a run's bag equals the run's own,
on both engines (tests/system/test_engines_equal.py).

Why one module: the report is one pure function of a run's envelopes, the same live and from a bag;
the figure families that stand alone live beside it (assumed_error.py, case_figures.py, cadence.py).
"""

from __future__ import annotations

import json
import math
from collections import defaultdict
from dataclasses import MISSING, dataclass, fields

import numpy as np

from bringup.analysis.assumed_error import assumed_error_figures
from bringup.analysis.case_figures import case_figures, ground_meta
from bringup.analysis.operations import ACKS, OPS, operations_figures
from bringup.analysis.security_figures import security_figures
from bringup.errors import UserError
from bringup.recording.bag import BagReader
from bringup.recording.bag_seal import check_bag
from ground_station.osse import VALUE_MAX, VALUE_MIN
from msgs_json import codec
from msgs_json import schemas as S
from msgs_json.envelope import Envelope
from msgs_json.topics import sat_of_topic
from sat_node.dtn.agent import BundleEvent
from sat_node.dtn.stats import dtn_report
from sat_node.value import ValueLedger

__all__ = ["REPORT_TOPIC_SUFFIXES", "ReportBuilder", "RunMeta", "build_report", "consensus_figures", "flatten",
           "report_from_bag", "security_figures", "true_values"]

_NS = 1_000_000_000
REPORT_TOPIC_SUFFIXES = ("/observations", "/dtn/events", "/dtn/counters", "/schedule", "/ground/uplink", *OPS, ACKS)


# RunMeta's field types (as annotated) -> does a JSON value have it
_META_TYPES = {
    "str": lambda v: isinstance(v, str),
    "int": lambda v: type(v) is int,
    "float": lambda v: type(v) in (int, float) and math.isfinite(v),
    "dict": lambda v: isinstance(v, dict),
    "None": lambda v: v is None,
    "list": lambda v: isinstance(v, list),
}


@dataclass
class RunMeta:
    scenario: str
    mode: str
    engine: str
    seed: int
    horizon_s: float
    n_sats: int
    n_gp: int
    revisit_zero_s: float = 900.0
    knowledge: str = ""
    osse: dict | None = None  # the truth field's rank figures (ground_station/osse_stats.py)
    regions_never_in_view: list | None = None  # in no satellite's field of regard over the horizon
    slot_s: float = 900.0  # the OSSE's time resolution (slot) [s]
    provenance: dict | None = None  # what the run was made from (bringup/scenario/provenance.py)
    ground: dict | None = None  # the ground network's passes (orbit_clock/ground_passes.py pass_figures)

    @classmethod
    def for_world(cls, world, mode: str, engine: str) -> RunMeta:
        """The metadata of a run of ``world`` (bringup.scenario.world.World)."""
        sc = world.scenario
        return cls(scenario=sc.name, mode=mode, engine=engine, seed=sc.scenario.seed, horizon_s=sc.scenario.horizon_s,
                   n_sats=len(world.sat_names), n_gp=world.n_gp, revisit_zero_s=sc.value.revisit_zero_s,
                   knowledge=sc.value.knowledge, osse=dict(world.osse.meta.get("rank") or {}),
                   regions_never_in_view=regions_never_in_view(world),
                   slot_s=float(world.osse.slot_s), ground=ground_meta(world))

    def to_json(self) -> str:
        return json.dumps(self.__dict__, sort_keys=True)

    @classmethod
    def from_json(cls, text: str) -> RunMeta:
        return cls.from_dict(json.loads(text))

    @classmethod
    def from_dict(cls, d) -> RunMeta:
        """A RunMeta from a /run/meta record's ``meta`` mapping; ValueError naming the bad key
        (unknown keys are ignored: a later writer may add some)."""
        if not isinstance(d, dict):
            raise ValueError(f"'meta' is {type(d).__name__}, not an object")
        kw = {}
        for f in fields(cls):
            if f.name not in d:
                if f.default is not MISSING:
                    continue
                raise ValueError(f"meta.{f.name} is missing")
            v = d[f.name]
            if not any(_META_TYPES.get(t, lambda _v: True)(v) for t in str(f.type).split(" | ")):
                raise ValueError(f"meta.{f.name} = {str(v)[:80]!r} is not {f.type.replace('float', 'a finite number')}")
            kw[f.name] = v
        if (kw["horizon_s"] <= 0 or kw["n_sats"] < 1 or kw["n_gp"] < 0 or kw["seed"] < 0 or kw.get("revisit_zero_s", 0) < 0
                or kw.get("slot_s", 1.0) <= 0):
            raise ValueError(f"meta out of range: horizon_s {kw['horizon_s']}, n_sats {kw['n_sats']}, "
                             f"n_gp {kw['n_gp']}, seed {kw['seed']}, slot_s {kw.get('slot_s')}")
        return cls(**kw)


_KIND = {"created": "created", "forwarded": "forwarded", "delivered": "delivered", "dropped": "dropped",
         "copy_discarded": "discarded"}


def _bundle_event(msg):
    """The agent's event record (what sat_node/dtn/stats.py reads) of a msgs_json bundle event."""
    kind = _KIND[type(msg).__struct_config__.tag]
    reason = getattr(msg, "reason", "")
    if kind == "dropped" and getattr(msg, "detail", "") in ("hop_limit",):
        reason = msg.detail
    deadline = msg.creation_ns + msg.lifetime_ns if kind == "created" else 0
    return BundleEvent(msg.t_ns, kind, msg.sat, msg.bundle_id, msg.priority, msg.dst, msg.creation_ns, reason, deadline)


def build_report(envelopes, meta: RunMeta, runtime: dict | None = None, security: dict | None = None) -> dict:
    """The report dict (nested, docs/design.md keys) from envelopes (any iterable of Envelope)."""
    b = ReportBuilder()
    for env in envelopes:
        b.add(env)
    return b.build(meta, runtime, security)


class ReportBuilder:
    """``build_report`` in two halves: ``add`` decodes one envelope as it is written (the local
    engine's recorder does this beside the run, bringup/recording/recorder_process.py), ``build`` makes the
    report from what was added. Envelopes off the report's topics are ignored; one that does not
    decode is counted (``messages_rejected_in_report``)."""

    TOPIC_SUFFIXES = REPORT_TOPIC_SUFFIXES  # the topics ``add`` reads; a recorder passes it only these

    def __init__(self) -> None:
        self.obs: list[S.Observation] = []
        self.events: list = []
        self.n_schedules = 0
        self.counters: dict[str, dict] = {}
        self.cpu_by_planner: dict[str, float] = defaultdict(float)
        self.bad = 0
        self.planned: dict[tuple[str, int], int] = {}
        self.created: dict[str, tuple] = {}
        self.delivered: dict[str, tuple[str, int]] = {}
        self.rejected: dict[str, int] = defaultdict(int)  # reason -> payloads not counted
        self.ops_msgs: list = []  # ModeChange and CommandEvent messages (bringup/analysis/operations.py)
        self.uplinks: list[tuple[str, int]] = []  # (satellite, t_ns) of every ground uplink
        self.acks: list = []  # CommandAck messages (bringup/analysis/operations.py)

    def add(self, env) -> None:
        t = env.topic
        try:
            if t.endswith("/observations"):
                o = codec.decode(t, env.data)
                if sat_of_topic(t) != o.sat:  # (under any namespace: msgs_json.topics.design_topic)
                    self.rejected["observation.sat_not_its_topic"] += 1
                    return
                self.obs.append(o)
            elif t.endswith("/dtn/events"):
                m = codec.decode(t, env.data)
                self.events.append(_bundle_event(m))
                if isinstance(m, S.BundleCreated):  # per (bundle, recipient): a multicast bundle has several
                    self.created[(m.bundle_id, m.dst)] = (m.src, m.gp, m.obs_t_ns, m.dst)
                elif isinstance(m, S.BundleDelivered) and (m.bundle_id, m.sat) not in self.delivered:
                    self.delivered[(m.bundle_id, m.sat)] = (m.sat, m.t_ns)
            elif t.endswith("/dtn/counters"):
                m = codec.decode(t, env.data)
                self.counters[m.sat] = m.counters
            elif t.endswith("/schedule"):
                self.n_schedules += 1
                m = codec.decode(t, env.data)
                self.cpu_by_planner[m.sat] += m.solve_cpu_s
                self.planned[(m.sat, m.version)] = m.planned_ns
            elif t == ACKS:
                self.acks.append(codec.decode(t, env.data))
            elif t.endswith(OPS):  # (one under another satellite's topic is not counted)
                self.ops_msgs += [m for m in (codec.decode(t, env.data),) if sat_of_topic(t) == m.sat]
            elif t == "/ground/uplink":
                up = codec.decode(t, env.data)
                self.cpu_by_planner["ground"] += up.schedule.solve_cpu_s
                self.uplinks.append((up.sat, up.t_ns))
        except ValueError:
            self.bad += 1
            self.rejected["undecodable"] += 1

    def _in_run(self, meta: RunMeta) -> tuple[list, dict[str, int]]:
        """The observations that can belong to this run, and how many others by reason."""
        horizon_ns = int(round(meta.horizon_s * _NS))
        keep, out = [], defaultdict(int)
        for o in self.obs:
            if not o.gp < meta.n_gp:
                out["observation.gp_out_of_range"] += 1
            elif o.t_ns > horizon_ns:
                out["observation.after_horizon"] += 1
            elif not VALUE_MIN <= o.recorded_value <= VALUE_MAX:
                out["observation.recorded_value_out_of_range"] += 1
            elif not math.isfinite(o.assumed_value):
                out["observation.assumed_value_not_finite"] += 1
            else:
                keep.append(o)
        return keep, out

    def build(self, meta: RunMeta, runtime: dict | None = None, security: dict | None = None, *,
              reached_s: float | None = None, recording: dict | None = None) -> dict:
        """The report of everything added so far. ``security``: the run's /run/meta security record;
        ``reached_s``: the run ended early, at this sim time (``partial``); ``recording``: what the
        bag's reader found (recovered, lost, warnings)."""
        obs, rejected = self._in_run(meta)
        for k, v in self.rejected.items():
            rejected[k] += v
        events, counters, cpu_by_planner = self.events, self.counters, self.cpu_by_planner
        rep: dict = {
            "scenario": meta.scenario, "mode": meta.mode, "engine": meta.engine, "seed": meta.seed,
            "horizon_s": meta.horizon_s, "n_sats": meta.n_sats,
            "partial": reached_s is not None,
            "horizon_reached_s": meta.horizon_s if reached_s is None else reached_s,
        }
        if recording:
            rep["recording"] = recording
        rep.update(_value_figures(obs, meta))
        rep["value"]["assumed_error"] = assumed_error_figures(true_values(obs, meta.revisit_zero_s), meta.slot_s,
                                                              meta.horizon_s)
        rep["knowledge"] = _knowledge_figures(obs, meta)
        rep.update(case_figures(obs, meta, self.uplinks, rep["knowledge"]["info_age_s"].get("median")))
        if meta.regions_never_in_view:
            rep["coverage"]["regions_never_in_view"] = list(meta.regions_never_in_view)
            rep.setdefault("warnings", []).append(
                f"no satellite has region(s) {', '.join(meta.regions_never_in_view)} in its field of regard "
                "during the horizon: their ground points can only count 0")
        if meta.provenance is not None:
            rep["provenance"] = meta.provenance
        rep["schedules"] = {"count": self.n_schedules}
        rep["dtn"] = _dtn_figures(events)
        n_obs = len({(src, gp, obs) for src, gp, obs, _dst in self.created.values()})
        if n_obs:
            rep["dtn"]["observations"] = n_obs
            rep["dtn"]["transmissions_per_observation"] = rep["dtn"]["transmissions"] / n_obs
        if counters:
            # overheard copies are counted by the satellites (DtnCounters), not sent as events
            over = sum(c.get("discarded.not_next_hop", 0) for c in counters.values())
            rep["dtn"]["copies_discarded"] = rep["dtn"].get("copies_discarded", 0) + over
            det = rep["dtn"].setdefault("copies_discarded_detail", {})
            det["not_next_hop"] = det.get("not_next_hop", 0) + over
            rep["dtn"]["held_at_end"] = sum(c.get("held", 0) for c in counters.values())
        if meta.mode == "distributed":
            rep["consensus"] = consensus_figures(obs, self.created, self.delivered, self.planned, meta.revisit_zero_s)
        if counters:
            rej: dict[str, int] = defaultdict(int)
            for c in counters.values():
                for k, v in c.items():
                    if k.startswith(("rejected.", "tx_failed.", "agent.dropped.", "agent.discarded.")):
                        rej[k] += v
            rep["dtn"]["rejections"] = dict(sorted(rej.items()))
        rep.update(operations_figures(self.ops_msgs, meta.horizon_s, obs, self.acks))  # {} without any
        rep["messages_rejected_in_report"] = sum(rejected.values())
        rep["report_rejections"] = dict(sorted(rejected.items()))
        rep["security"] = security_figures(security)
        rt = dict(runtime or {})
        rt["scheduler_cpu_s_per_sat"] = (sum(cpu_by_planner.values()) / meta.n_sats) if meta.n_sats else None
        rep["runtime"] = rt
        return rep


def regions_never_in_view(world) -> list[str]:
    """Names of the regions none of whose GPs lies in any satellite's access windows (the world's
    access search over the horizon), in scenario order."""
    region_index = np.asarray(world.ctx.gps.region_index)
    seen = set(np.unique(region_index[np.asarray(world.access.gp, dtype=np.int64)]).tolist()) \
        if len(world.access.gp) else set()
    names = [str(n) for n in world.ctx.gps.region_names]
    return [n for i, n in enumerate(names) if i not in seen]


PASS_GAP_S = 120.0  # observations of one satellite closer than this belong to one pass over one area


def _regions_from_passes(obs: list, gap_ns: int) -> dict[int, int]:
    """GP -> area id, from the observations alone: GPs one satellite observes within ``gap_ns`` of
    each other are in one area (union-find). The study's regions are thousands of km apart (several
    minutes of flight), a region's pass takes ~2 min, so each area is one region."""
    parent: dict[int, int] = {}

    def find(x: int) -> int:
        parent.setdefault(x, x)
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    by_sat: dict[str, list] = defaultdict(list)
    for o in obs:
        by_sat[o.sat].append(o)
    for lst in by_sat.values():
        lst.sort(key=lambda o: o.t_ns)
        for a, b in zip(lst, lst[1:]):
            find(a.gp)
            if b.t_ns - a.t_ns <= gap_ns:
                ra, rb = find(a.gp), find(b.gp)
                if ra != rb:
                    parent[max(ra, rb)] = min(ra, rb)
        if lst:
            find(lst[-1].gp)
    return {g: find(g) for g in parent}


def consensus_figures(obs: list, created: dict, delivered: dict, planned: dict, revisit_zero_s: float,
                      *, pass_gap_s: float = PASS_GAP_S) -> dict:
    """ISL-delayed consensus figures (module docstring).

    ``created``: (bundle id, recipient) -> (src, gp, obs_t_ns, dst); ``delivered``: (bundle id,
    recipient) -> (receiver, t_ns) of its first delivery; ``planned``: (sat, schedule version) -> planned_ns.
    A *pass* is a run of one satellite's observations in one area with gaps <= ``pass_gap_s``.
    For successive passes (A then B, A != B) over an area, sorted by their first observation:
    ``informed`` - at least one of A's pass observations was delivered to B at or before B's
    planning time; ``fully_informed`` - all of them were; ``planned_before_earlier_pass`` - B planned
    before A's first observation (no network could have told it); ``no_bundle`` - none of A's
    observations had B as a destination. Duplicates: B's observations of a GP A observed in its pass
    less than ``revisit_zero_s`` before; ``late_news`` when the bundle for that observation had not
    reached B by its planning time, ``despite_news`` otherwise.
    """
    gap_ns = int(round(pass_gap_s * _NS))
    zero_ns = int(round(revisit_zero_s * _NS))
    area = _regions_from_passes(obs, gap_ns)
    passes: list[dict] = []
    by_sat: dict[str, list] = defaultdict(list)
    for o in obs:
        by_sat[o.sat].append(o)
    for sat, lst in by_sat.items():
        lst.sort(key=lambda o: o.t_ns)
        cur = None
        for o in lst:
            a = area[o.gp]
            if cur is None or cur["area"] != a or o.t_ns - cur["obs"][-1].t_ns > gap_ns:
                cur = {"sat": sat, "area": a, "obs": []}
                passes.append(cur)
            cur["obs"].append(o)
    news: dict[tuple[str, str, int, int], int] = {}  # (src, dst, gp, obs_t_ns) -> delivery t_ns at dst
    dests: set[tuple[str, str, int, int]] = set()
    for bid, (src, gp, obs_ns, dst) in created.items():
        dests.add((src, dst, gp, obs_ns))
        d = delivered.get(bid)
        if d is not None and d[0] == dst:
            k = (src, dst, gp, obs_ns)
            news[k] = min(news.get(k, d[1]), d[1])
    by_area: dict[int, list] = defaultdict(list)
    for p in passes:
        by_area[p["area"]].append(p)
    n = informed = full = before = no_bundle = dup = late = despite = 0
    margins = []
    for lst in by_area.values():
        lst.sort(key=lambda p: (p["obs"][0].t_ns, p["sat"]))
        for pa, pb in zip(lst, lst[1:]):
            if pa["sat"] == pb["sat"]:
                continue
            n += 1
            a, b = pa["sat"], pb["sat"]
            first_b = pb["obs"][0]
            t_plan = planned.get((b, first_b.schedule_version), first_b.t_ns)
            keys = [(a, b, o.gp, o.t_ns) for o in pa["obs"]]
            got = [news[k] for k in keys if k in news and news[k] <= t_plan]
            if t_plan < pa["obs"][0].t_ns:
                before += 1
            if not any(k in dests for k in keys):
                no_bundle += 1
            if got:
                informed += 1
                margins.append((t_plan - min(got)) / _NS)
            if len(got) == len(keys):
                full += 1
            seen_a = {o.gp: o.t_ns for o in pa["obs"]}
            for o in pb["obs"]:
                ta = seen_a.get(o.gp)
                if ta is None or o.t_ns - ta >= zero_ns:
                    continue
                dup += 1
                k = (a, b, o.gp, ta)
                if k in news and news[k] <= t_plan:
                    despite += 1
                else:
                    late += 1
    return {
        "areas": len(by_area), "passes": len(passes), "pairs": n,
        "pairs_informed": informed, "pairs_fully_informed": full,
        "pairs_informed_fraction": (informed / n) if n else None,
        "pairs_planned_before_earlier_pass": before, "pairs_no_bundle": no_bundle,
        "news_margin_s_median": float(np.median(margins)) if margins else None,
        "duplicates": dup, "duplicates_late_news": late, "duplicates_despite_news": despite,
    }


def true_values(obs: list, revisit_zero_s: float) -> list[tuple]:
    """[(observation, true Eq. 1 value, was_duplicate)] in time order (ties by satellite, GP)."""
    ledger = ValueLedger(revisit_zero_s)
    out = []
    for o in sorted(obs, key=lambda o: (o.t_ns, o.sat, o.gp)):
        v, recent = ledger.add(o.gp, o.t_ns, o.recorded_value)
        out.append((o, v, recent))
    return out


INFO_AGE_EDGES_S = (0, 60, 300, 600, 900, 1800, 3600, 7200, 14400, 28800)


def _knowledge_figures(obs: list, meta: RunMeta) -> dict:
    ages = np.array([(o.t_ns - o.info_ns) / _NS for o in obs if o.info_ns is not None], dtype=np.float64)
    out: dict = {"model": meta.knowledge or None, "looks_with_info_time": int(ages.size)}
    if ages.size:
        edges = np.array(INFO_AGE_EDGES_S + (np.inf,), dtype=np.float64)
        hist, _ = np.histogram(ages, bins=edges)
        out["info_age_s"] = {"mean": float(ages.mean()), "median": float(np.median(ages)),
                             "p90": float(np.percentile(ages, 90)), "max": float(ages.max()),
                             "hist_edges_s": list(INFO_AGE_EDGES_S), "hist": [int(x) for x in hist]}
    else:
        out["info_age_s"] = {"mean": None, "median": None, "p90": None}
    return out


def _value_figures(obs: list, meta: RunMeta) -> dict:
    rows = true_values(obs, meta.revisit_zero_s)
    total = 0.0
    first = 0.0
    seen: set[int] = set()
    errs = []
    per_sat: dict[str, float] = defaultdict(float)
    for o, v, _ in rows:
        if v > 0:
            errs.append(abs(o.assumed_value - v) / v)
        total += v
        if o.gp not in seen:
            seen.add(o.gp)
            first += v
        per_sat[o.sat] += v
    dup = sum(1 for _, _, d in rows if d)
    observed = {o.gp for o in obs}
    return {
        "value": {
            "cumulative": total,
            "assumed_error_mean": float(np.mean(errs)) if errs else None,
            "assumed_error_median": float(np.median(errs)) if errs else None,
            "first_look_share": (first / total) if total > 0 else None,
            "per_sat": dict(sorted(per_sat.items())),
        },
        "coverage": {
            "gp_observed": len(observed),
            "gp_total": meta.n_gp,
            "gp_observed_fraction": (len(observed) / meta.n_gp) if meta.n_gp else None,
            "looks_per_gp": (len(obs) / meta.n_gp) if meta.n_gp else None,
        },
        "observations": {"count": len(obs), "duplicates_15min": dup, "duplicate_fraction": dup / len(obs) if obs else None},
    }


def _dtn_figures(events: list) -> dict:
    flat = dtn_report(events)
    nested: dict = {}
    for k, v in flat.items():
        parts = k.split(".")
        if parts[0] == "dtn":
            parts = parts[1:]
        d = nested
        for p in parts[:-1]:
            d = d.setdefault(p, {})
        d[parts[-1]] = v
    return nested


def flatten(rep: dict, prefix: str = "") -> dict:
    out = {}
    for k, v in rep.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(flatten(v, key + "."))
        else:
            out[key] = v
    return out


def report_from_bag(bag_path, *, warn=None, unverified_ok: bool = False) -> dict:
    """Rebuild report.json from a bag alone (metadata from its /run/meta records). A bag that ends
    before the run's closing /run/meta record, or whose file was cut, gives a ``partial`` report.
    ``warn(line)``: called with each thing the bag's reader read past (metadata.yaml disagreeing
    with the .mcap, a cut file, payloads not counted, an unverified bag). The bag's seal is checked
    first (bringup/recording/bag_seal.py): one that fails is an IntegrityError unless
    ``unverified_ok``; the report's ``integrity`` says what the check found."""
    integrity = check_bag(bag_path, unverified_ok=unverified_ok)
    with BagReader(bag_path) as bag:
        names = [t.topic for t in bag.topics()]
        if "/run/meta" not in names:
            if not bag.complete:
                raise UserError(f"bag {bag.path}: {bag.recovery}; no /run/meta record survived: "
                                "not enough left to rebuild a report")
            raise UserError(f"{bag_path}: no /run/meta record: not a bag written by `constellation run`")
        meta = None
        runtime = {}
        closed = False
        security = None
        for env in bag.envelopes(["/run/meta"]):
            try:
                d = json.loads(env.data)
                if not isinstance(d, dict):
                    raise ValueError("not a JSON object")
                m = RunMeta.from_dict(d.get("meta"))
                rt = d.get("runtime", None)
                if rt is not None and not isinstance(rt, dict):
                    raise ValueError(f"'runtime' is {type(rt).__name__}, not an object")
                sec = d.get("security", None)
                if sec is not None:
                    security_figures(sec)  # (ValueError naming what is malformed)
            except ValueError as exc:
                raise UserError(f"bag {bag.path}: /run/meta record at t = {env.t_ns} ns: "
                                f"{' '.join(str(exc).split())[:200]}") from None
            if meta is not None and m != meta:
                raise UserError(f"bag {bag.path}: /run/meta records disagree ({meta} then {m} at t = {env.t_ns} ns)")
            meta = m
            if rt is not None:
                runtime, closed = rt, True
            if sec is not None:
                security = sec
        if meta is None:  # (a /run/meta channel whose records are gone or are not envelopes)
            raise UserError(f"bag {bag.path}: /run/meta holds no run record: not enough left to rebuild a report")
        wanted = [t for t in names if t.endswith(REPORT_TOPIC_SUFFIXES)]
        envs: list[Envelope] = list(bag.envelopes(wanted))
        recording = None
        if bag.warnings or not bag.complete:
            recording = {"complete": bag.complete, "recovery": bag.recovery, "warnings": list(bag.warnings)}
        partial = not closed or bag.lost_data
        reached = bag.end_ns / _NS if partial else None
        for line in ([bag.recovery] if bag.recovery else []) + list(bag.warnings):
            if warn is not None:
                warn(f"bag {bag.path}: {line}")
    b = ReportBuilder()
    for env in envs:
        b.add(env)
    rep = b.build(meta, runtime, security, reached_s=reached, recording=recording)
    for line in rep.get("warnings", []):
        if warn is not None:
            warn(line)
    rep["integrity"] = integrity.as_dict()
    if integrity.status != "verified" and warn is not None:  # (said once a report is made of it)
        warn(f"bag {bag_path}: unverified: {integrity.detail}")
    if partial and warn is not None:
        warn(f"partial report: the run reached t = {reached:g} s of its {meta.horizon_s:g} s horizon "
             f"({'no closing /run/meta record' if not closed else 'data lost from the bag'})")
    if rep["messages_rejected_in_report"] and warn is not None:
        warn(f"{rep['messages_rejected_in_report']} payloads not counted: "
             + ", ".join(f"{k} {v}" for k, v in rep["report_rejections"].items()))
    return rep
