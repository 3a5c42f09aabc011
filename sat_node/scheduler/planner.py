"""The one planner: how every scheduler of the constellation turns what it knows into a plan.

The satellite's onboard replans (distributed mode, Nag et al., ICAPS SPARK 2019, section 4), the
ground segment's plans for each satellite (centralized mode, section 5) and the non-agile baseline
all plan here, with the same steps:

1. **Value.** What the planner believes each GP is worth: the value source of its
   :class:`Knowledge` (``value_at(gp, t_s)``, ``slot_of(t_s)``) through its own belief noise
   (:class:`sat_node.value.Belief`). The caller passes the knowledge in; the planner never reads
   the scenario's field itself. Today both callers pass :class:`PersistenceView`, the OSSE forecast
   as it stood at planning time (persistence: the planner cannot know the future flood state);
   the observations it knows of (its own, those delivered by the DTN or downlinked, plans it must
   respect) enter through Eq. 1's prior state (:func:`sat_node.value.prior_state`). An operator's
   tasked GPs (``Knowledge.tasks``, sat_node/operations/tasking.py: what a delivered task command
   told this planner) raise the planned satellite's value there to the task's until its deadline and
   keep them from its predicted partners (tests/unit/test_operations_tasking.py).
2. **GP pre-filter.** The GPs of the regions that may enter the satellite's field of regard in the
   window (a superset, :class:`orbit_clock.access.RegionPrefilter`, passed in as ``candidates``);
   none: no plan.
3. **Instance.** The satellite's positions on the DP grid, the exact FOR mask
   (:func:`orbit_clock.access.for_mask`), the believed value and the prior state
   (:func:`sat_node.scheduler.problem.build_problem`).
4. **Solver.** A named strategy of :data:`SOLVERS`: ``dp`` (the study's dynamic program,
   :func:`sat_node.scheduler.dp.solve_dp`, invariants checked) or ``nonagile`` (nadir only,
   :func:`sat_node.scheduler.nonagile.solve_nonagile`).
5. **Joint planning** (``dp`` with ``PlannerSettings.joint``; the study's Table 1, lines 9-20): the
   satellites whose fields of regard reach a GP the planned satellite may see - within
   ``revisit_zero_s`` of its window's start, the time over which a GP counts once - are planned
   with it from the same knowledge (:func:`sat_node.scheduler.joint.solve_joint`); the planned
   satellite's part is its plan. Onboard the partners are every other satellite of the
   constellation, from nadir at the window's start; the ground names them with the time their
   committed plans end (``partners``). ``PlannerSettings.joint_max_partners`` = K >= 1 (scenario
   key ``scheduler.joint_max_partners``; beyond the study, which plans with every overlapping
   satellite) keeps the K partners that may first see one of the planned satellite's GPs
   earliest (:meth:`Planner.group`); 0 keeps them all. Which satellites pass the planned
   satellite's regions in the window, and from when, the planner asks the pre-filter's pass index
   (``passes``, from the orbits alone) for every satellite at once.

A mixed fleet (bringup/scenario/fleet.py) gives satellites their own field of regard, footprint
and slew model: ``Planner(own=...)`` maps a satellite's name to its :class:`SatPayload`; the
instance of each satellite (its own or a partner's) is built with that satellite's, the others
with the settings' and ``slew``.

A planner holds only the scenario's fixed inputs (orbits, GPs, slew model, settings, pre-filter):
everything that changes between calls - the satellite, the time, the window, the knowledge, the
attitude - is an argument, so one planner serves every satellite and the ground in one process.

How we know it is right (tests/unit/test_planner.py): its instance equals one built by hand from
the same arrays (track, exact FOR mask over every GP, forecast at the persistence time, belief,
prior state); the pre-filtered plan equals the DP on the full instance's columns; the persistence
view reads every later time at the cut-off; the paper run's report and traces are the check that
satellite and ground plan as before (tests/system/test_engines_equal.py for both engines).
tests/unit/test_joint_bound.py: a bounded group is never larger than K, keeps the partners the rule
names on a hand-drawn case, and with K at least the unbounded group's size plans exactly as unbounded.
tests/unit/test_region_passes.py: the partner choice that asks the pre-filter's pass index
(``passes``; best-first when bounded) chooses the same partners with the same instances as the one
that looks at every partner; tests/system/test_partner_choice_run.py: a whole run with it equals one
without it, message by message. tests/unit/test_joint_speed.py: a partner's look made in blocks from
the pass index's bound (several partners' first blocks at once) finds what the whole look finds.
tests/unit/test_fleet.py: in a mixed fleet each satellite's instance has the FOR mask of its own angle
and its own slew model, and the non-agile baseline its own footprint.
"""

from __future__ import annotations

import heapq
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np

from orbit_clock.access import for_mask
from sat_node.acs import SlewModel
from sat_node.diversity import diversity_factor, recent_observed_gps
from sat_node.scheduler.dp import Plan, solve_dp
from sat_node.scheduler.joint import solve_joint
from sat_node.scheduler.nonagile import solve_nonagile
from sat_node.scheduler.problem import SchedulingProblem, build_problem
from sat_node.value import Belief, KnownObservation, prior_state

__all__ = ["SOLVERS", "Knowledge", "PersistenceView", "Planner", "PlannerSettings", "SatPayload", "ValueSource"]


class ValueSource(Protocol):
    """A value field as a planner knows it: values per GP and time, on 15-min slots. A view may
    also say ``frozen_after_s``: from that time on it reads the same at every time (the planner then
    reads one instant for a window that starts there)."""

    def value_at(self, gp_idx, t_s) -> np.ndarray: ...

    def slot_of(self, t_s) -> np.ndarray: ...


class PersistenceView:
    """A field as a planner knows it at ``t_known_s``: every later time reads that instant."""

    def __init__(self, field: ValueSource, t_known_s: float):
        self._field = field
        self._t = float(t_known_s)

    @property
    def t_known_s(self) -> float:
        return self._t

    @property
    def frozen_after_s(self) -> float:
        """Every time from this one on reads the same values and slot (persistence)."""
        return self._t

    def value_at(self, gp_idx, t_s):
        shape = np.broadcast(np.asarray(gp_idx), np.asarray(t_s)).shape
        t = np.broadcast_to(np.asarray(t_s, np.float64), shape)
        return self._field.value_at(gp_idx, np.minimum(t, self._t))

    def slot_of(self, t_s):
        return self._field.slot_of(np.minimum(np.asarray(t_s, np.float64), self._t))


@dataclass(frozen=True)
class Knowledge:
    """What one planner knows when it plans: the value it believes (``value`` seen through
    ``belief``, None: exactly) and the observations it knows of (executed, or planned by others)."""

    value: ValueSource
    known: Sequence[KnownObservation] = ()
    belief: Belief | None = None
    # an operator's tasked GPs (sat_node/operations/tasking.py TaskOverlay): what a delivered task
    # command told this planner, applied to the believed value of each instance (None: no task)
    tasks: object | None = None


@dataclass(frozen=True)
class PlannerSettings:
    """The scenario's planning parameters (units in names)."""

    dp_step_s: float
    plan_lookahead_s: float
    for_off_nadir_deg: float
    revisit_zero_s: float
    footprint_km: float
    joint: bool = False
    joint_budget_solves: int = 0  # the dive only (sat_node/scheduler/joint.py): the search gained nothing here
    joint_max_partners: int = 0  # at most this many partners in a joint plan (Planner.group); 0: all
    # the optional spatial-diversity term (sat_node/diversity.py): weight (0: off), length, window
    diversity_weight: float = 0.0
    diversity_km: float = 8.0
    diversity_window_s: float = 3600.0

    @classmethod
    def from_scenario(cls, sc) -> PlannerSettings:
        return cls(dp_step_s=float(sc.scheduler.dp_step_s),
                   plan_lookahead_s=float(sc.scheduler.plan_lookahead_s),
                   for_off_nadir_deg=float(sc.instrument.for_off_nadir_deg),
                   revisit_zero_s=float(sc.value.revisit_zero_s),
                   footprint_km=float(sc.instrument.footprint_km),
                   joint=bool(sc.scheduler.joint_planning),
                   joint_max_partners=int(sc.scheduler.joint_max_partners),
                   diversity_weight=float(sc.value.spatial_diversity_weight),
                   diversity_km=float(sc.value.spatial_diversity_km),
                   diversity_window_s=60.0 * float(sc.value.spatial_diversity_window_min))


@dataclass(frozen=True)
class SatPayload:
    """One satellite's own payload and bus when it differs from the settings' (a mixed fleet)."""

    for_off_nadir_deg: float
    footprint_km: float
    slew: SlewModel


class PassIndex(Protocol):
    """Which satellites may have some of a set of GPs in their field of regard in an interval, from
    the orbits alone (:class:`orbit_clock.access.RegionPrefilter`)."""

    step_s: float  # the index's sampling step [s]

    def passing(self, gp_ids, sat_idx, t0_s, t1_s: float) -> np.ndarray:
        """(len(sat_idx),) True where ``candidates`` of satellite ``sat_idx[j]`` over [t0_s[j], t1_s]
        holds one of ``gp_ids``."""

    def first_pass_s(self, gp_ids, sat_idx, t0_s, t1_s: float) -> np.ndarray:
        """The first sample time in [t0_s[j], t1_s] at which satellite ``sat_idx[j]`` passes a region
        of ``gp_ids``: a GP in its FOR at time t from t0_s[j] on flags a sample within ``step_s`` of t."""


#: samples of a partner's 10-s look tested in its first block (each next block is twice as long)
_LOOK_BLOCK = 8
#: partners whose first blocks a bounded group tests together (those it may not need included)
_LOOK_BATCH = 8

#: name -> solver(instance, settings) -> Plan (settings: the planned satellite's footprint)
SOLVERS: dict[str, Callable[[SchedulingProblem, PlannerSettings], Plan]] = {
    "dp": lambda p, st: solve_dp(p, check=True),
    "nonagile": lambda p, st: solve_nonagile(p, st.footprint_km),
}


class Planner:
    """Plans for any satellite of ``constellation`` (``track_ecef_km(name, t_s)``, orbit_clock)
    over the GPs ``gp_ecef_km`` [km, ECEF, row = GP id]; ``candidates(sat, t0_s, t1_s)`` is the GP
    pre-filter (None: the exact FOR mask over every GP picks the columns); ``passes`` the same
    pre-filter's pass index (:class:`PassIndex`), which the partner choice of joint planning asks
    for every partner at once instead of ``candidates`` partner by partner, and which orders the
    partners a bounded group looks at (None: every partner, one by one)."""

    def __init__(self, constellation, gp_ecef_km: np.ndarray, slew: SlewModel, settings: PlannerSettings,
                 candidates: Callable[[str, float, float], np.ndarray] | None = None,
                 own: dict[str, SatPayload] | None = None, passes: PassIndex | None = None):
        self.constellation = constellation
        self.gp_ecef_km = gp_ecef_km
        self.slew = slew
        self.settings = settings
        self.candidates = candidates
        self.passes = passes
        self.own = dict(own or {})

    def for_deg(self, sat: str) -> float:
        """Satellite ``sat``'s field of regard [deg]."""
        o = self.own.get(sat)
        return self.settings.for_off_nadir_deg if o is None else o.for_off_nadir_deg

    def _settings_of(self, sat: str) -> PlannerSettings:
        o = self.own.get(sat)
        if o is None:
            return self.settings
        return replace(self.settings, for_off_nadir_deg=o.for_off_nadir_deg, footprint_km=o.footprint_km)

    def plan(self, sat: str, t0_s: float, window_s: float, knowledge: Knowledge, *,
             init_target_km: np.ndarray | None = None, solver: str = "dp",
             partners: Sequence[tuple[str, float]] | None = None) -> Plan | None:
        """The plan of ``sat`` over [t0_s, t0_s + window_s) from ``knowledge`` (None when no GP can
        enter its field of regard); ``init_target_km``: what it points at now (None: nadir).
        ``partners``: for joint planning, [(satellite, free from [s])] (None: every other satellite,
        free now)."""
        if solver not in SOLVERS:
            raise ValueError(f"planner solver {solver!r}: unknown (known: {', '.join(sorted(SOLVERS))})")
        ids = None
        if self.candidates is not None:
            ids = self.candidates(sat, t0_s, t0_s + window_s)
            if len(ids) == 0:
                return None
        p = self.instance(sat, t0_s, knowledge, window_s=window_s, gp_ids=ids, init_target_km=init_target_km)
        if solver == "dp" and self.settings.joint:
            group = self.group(sat, t0_s, window_s, knowledge, p, partners)
            if group:
                return solve_joint([p] + group, budget_solves=self.settings.joint_budget_solves).plans[0]
        return SOLVERS[solver](p, self._settings_of(sat))

    def group(self, sat: str, t0_s: float, window_s: float, knowledge: Knowledge, mine: SchedulingProblem,
              partners: Sequence[tuple[str, float]] | None = None) -> list[SchedulingProblem]:
        """The instances of the satellites planned jointly with ``sat`` (module docstring, step 5):
        each partner free before the group's end - ``t0_s`` plus the longer of the window and
        ``revisit_zero_s`` - over its first ``revisit_zero_s`` once free and the GPs it may see then,
        kept when one of them is a GP ``mine`` may see. In the order of ``partners``.

        With ``settings.joint_max_partners`` = K >= 1, at most K of them: those whose field of
        regard first reaches one of ``mine``'s GPs (those worth something to it) earliest, ties
        broken by satellite name; their instances are built in that order until K share a GP
        worth something to both (a candidate that shares none is passed over, as unbounded). The
        time is on the DP grid, from the 10-s look refined over its last 10 s. The study plans
        with every satellite of overlapping field of regard (Nag et al. 2019, Table 1 lines 9-20,
        ``satsWoverlappingFOR``). Why the earliest: the group's solver gives a contested GP to the
        member that looks at it first (sat_node/scheduler/joint.py, the greedy dive), so a partner
        changes the planned satellite's part only by taking one of its GPs before it - a partner
        that reaches the shared GPs after it loses every contest and leaves its part as planned
        alone. The other candidate, the partners sharing the most GPs, ranks first the neighbours
        trailing on the same ground track, which reach the shared GPs after it and so never change
        its part. Names make the choice deterministic (they sort in plane, slot order). The bound saves the instances and the DP solves of the
        partners left out (one DP per member and per dive round). A partner left out is not
        predicted: the plan may then take GPs that partner will take (news over the DTN, or the
        next replan, settle them).
        """
        st = self.settings
        k = st.joint_max_partners
        end = t0_s + max(window_s, st.revisit_zero_s)
        if partners is None:
            partners = [(n, t0_s) for n in getattr(self.constellation, "names", ()) if n != sat]
        mine_ids = mine.gp_ids[mine.v_first.any(axis=0)]
        if len(mine_ids) == 0:
            return []
        mine_gps = set(mine_ids.tolist())
        mine_km = self.gp_ecef_km[mine_ids]
        rows = self._passing(partners, t0_s, end, mine_ids)
        if k and self.passes is not None:
            out = self._earliest(rows, k, end, knowledge, mine_gps, mine_km)
            return [q for _order, q in sorted(out, key=lambda m: m[0])]
        cands = []  # (first time its FOR reaches one of my GPs [s] (K >= 1 only), name, order, start, ids)
        for order, name, start, lb in rows:
            ids = self.candidates(name, start, end) if self.candidates is not None else None
            if ids is not None and not mine_gps.intersection(ids.tolist()):
                continue
            first_s = self._first_look_s(name, start, end, mine_km, exact=bool(k), from_s=lb)
            if first_s is not None:
                cands.append((first_s, name, order, start, ids))
        if k:
            cands.sort(key=lambda c: (c[0], c[1]))
        out = []  # (order, instance)
        for _first, name, order, start, ids in cands:
            q = self._partner_instance(name, start, end, knowledge, ids)
            if mine_gps.intersection(q.gp_ids[q.v_first.any(axis=0)].tolist()):
                out.append((order, q))
                if len(out) == k:
                    break
        return [q for _order, q in sorted(out, key=lambda m: m[0])]

    def _partner_instance(self, name: str, start: float, end: float, knowledge: Knowledge, ids) -> SchedulingProblem:
        """A partner's part: its first revisit_zero_s once free (a GP counts once over it)."""
        st = self.settings
        return self.instance(name, start, knowledge, window_s=min(end, start + st.revisit_zero_s) - start, gp_ids=ids)

    def _first_look_s(self, name: str, start: float, end: float, mine_km: np.ndarray, exact: bool,
                      from_s: float | None = None) -> float | None:
        """None when the 10-s look (the FOR over my GPs from ``start`` to the group's end) sees none
        of them, else the first time it does on the DP grid (``exact``; else 0.0).

        ``from_s``: a time before which the FOR reaches none of them (the pass index's bound,
        :meth:`_passing`; None: ``start``). The look's samples are tested in blocks in time order,
        from the first at or after ``from_s``, and it stops at the first block that sees one: the
        same first sample as testing them all (a sample's test does not depend on the others;
        tests/unit/test_joint_speed.py compares the two)."""
        return self._first_looks_s([(name, start, from_s)], end, mine_km, exact)[0]

    def _first_looks_s(self, looks, end: float, mine_km: np.ndarray, exact: bool) -> list[float | None]:
        """:meth:`_first_look_s` of several partners [(name, start, from_s)]: their first blocks
        tested together (one propagation and one FOR test for all, when they share a field of
        regard), the later blocks partner by partner."""
        return [self._refined_s(c, mine_km, exact) for c in self._coarse_looks(looks, end, mine_km)]

    def _refined_s(self, look, mine_km: np.ndarray, exact: bool) -> float | None:
        """A look of :meth:`_coarse_looks` as :meth:`_first_look_s` gives it: its later blocks
        tested if the first saw none of my GPs, then the first sample that sees one refined."""
        name, coarse, idx, hit = look
        lo, size = 0, _LOOK_BLOCK
        while lo < len(idx):
            block = idx[lo:lo + size]
            if lo > 0:
                hit = for_mask(self.constellation.track_ecef_km(name, coarse[block]), mine_km,
                               self.for_deg(name)).any(axis=1)
            if hit.any():
                j = int(block[np.argmax(hit)])
                return self._first_in_for_s(name, coarse, j, mine_km) if exact else 0.0
            lo += size
            size *= 2
        return None

    def _coarse_looks(self, looks, end: float, mine_km: np.ndarray) -> list[tuple]:
        """[(name, the look's 10-s samples, the indices of those to test, what its first block of
        them saw)] of :meth:`_first_looks_s`: the first blocks only (:meth:`_refined_s` does the
        rest when the look is needed)."""
        step = self.settings.dp_step_s
        todo = []  # (name, coarse samples, the indices to test)
        for name, start, from_s in looks:
            coarse = np.append(np.arange(start, end, 10.0), end - step)
            todo.append((name, coarse, np.flatnonzero(coarse >= from_s) if from_s is not None
                         else np.arange(len(coarse))))
        first = [t[2][:_LOOK_BLOCK] for t in todo]
        seen = None
        at = getattr(self.constellation, "positions_ecef_km_at", None)
        if len(todo) > 1 and at is not None and len({self.for_deg(t[0]) for t in todo}) == 1:
            idx = np.concatenate([np.full(len(b), self.constellation.index(t[0]), np.int64)
                                  for t, b in zip(todo, first)])
            pos = at(idx, np.concatenate([t[1][b] for t, b in zip(todo, first)]))
            hit = for_mask(pos, mine_km, self.for_deg(todo[0][0])).any(axis=1)
            seen = np.split(hit, np.cumsum([len(b) for b in first])[:-1])
        if seen is None:
            seen = [for_mask(self.constellation.track_ecef_km(t[0], t[1][b]), mine_km, self.for_deg(t[0])).any(axis=1)
                    for t, b in zip(todo, first)]
        return [(name, coarse, idx, hit) for (name, coarse, idx), hit in zip(todo, seen)]

    def _earliest(self, rows, k: int, end: float, knowledge: Knowledge, mine_gps: set, mine_km):
        """The bounded group of :meth:`group` - the first K partners in the order of (the first time
        their FOR reaches one of my GPs, name) whose instance shares a GP worth something with mine -
        looking only at as many partners as that order needs.

        The pass index gives each partner a lower bound of that time (``lb``, :meth:`_passing`).
        Partners are looked at in the order of their bounds; the one with the earliest time among
        those looked at is taken next once every partner not yet looked at has a bound after its
        time (on a tie of time and bound, the tied one is looked at first, so names decide as in
        the full sort). The order, and so the group, is the full sort's; the partners whose bounds
        come after the K-th member's time are never looked at."""
        rows = sorted(rows, key=lambda r: (r[3], r[1]))
        heap: list = []  # (first time, name, order, start)
        out: list = []
        looked: dict[int, tuple] = {}  # row -> its look, made a batch of rows ahead (refined when needed)
        i = 0
        while True:
            while i < len(rows) and (not heap or rows[i][3] <= heap[0][0]):
                order, name, start, _lb = rows[i]
                if i not in looked:
                    batch = range(i, min(len(rows), i + _LOOK_BATCH))
                    looks = [(rows[b][1], rows[b][2], rows[b][3]) for b in batch]
                    looked.update(zip(batch, self._coarse_looks(looks, end, mine_km)))
                first_s = self._refined_s(looked[i], mine_km, exact=True)
                i += 1
                if first_s is not None:
                    heapq.heappush(heap, (first_s, name, order, start))
            if not heap:
                return out
            _first, name, order, start = heapq.heappop(heap)
            ids = self.candidates(name, start, end) if self.candidates is not None else None
            q = self._partner_instance(name, start, end, knowledge, ids)
            if mine_gps.intersection(q.gp_ids[q.v_first.any(axis=0)].tolist()):
                out.append((order, q))
                if len(out) == k:
                    return out

    def _passing(self, partners: Sequence[tuple[str, float]], t0_s: float, end_s: float,
                 mine_ids: np.ndarray) -> list[tuple[int, str, float, float]]:
        """[(order, name, start, lb)] of the ``partners`` free before ``end_s - dp_step_s`` (start:
        the later of ``t0_s`` and their free time) and, with a pass index (``passes``), whose
        regions in [start, end_s] include one of the GPs ``mine_ids`` - the same test as the GP
        pre-filter intersected with them, made for every partner at once. ``lb``: with the index, a
        time no later than the first at which the partner's FOR may reach one of those GPs (the
        sample before its first pass of their regions from ``start``, at least ``start``: the pass
        test's margin holds the satellite's motion over a sample, so a GP in the FOR between two
        samples flags both); without it, ``start``."""
        step = self.settings.dp_step_s
        rows = [(order, name, max(t0_s, float(free_s))) for order, (name, free_s) in enumerate(partners)]
        rows = [r for r in rows if r[2] < end_s - step]
        if self.passes is None or not rows:
            return [(*r, r[2]) for r in rows]
        idx = np.fromiter((self.constellation.index(r[1]) for r in rows), dtype=np.int64, count=len(rows))
        starts = np.fromiter((r[2] for r in rows), dtype=np.float64, count=len(rows))
        keep = np.flatnonzero(self.passes.passing(mine_ids, idx, starts, end_s))
        first = self.passes.first_pass_s(mine_ids, idx[keep], starts[keep], end_s)
        lb = np.maximum(starts[keep], first - self.passes.step_s)
        return [(*rows[j], float(b)) for j, b in zip(keep.tolist(), lb.tolist())]

    def _first_in_for_s(self, name: str, coarse_s: np.ndarray, j: int, gp_km: np.ndarray) -> float:
        """The first time [s] on the DP grid from ``coarse_s[0]`` at which satellite ``name``'s FOR
        reaches one of the GPs ``gp_km``, given that ``coarse_s[j]`` is the first coarse time it does:
        ``coarse_s[j]`` refined over the DP steps after ``coarse_s[j - 1]``."""
        if j == 0:
            return float(coarse_s[0])
        step = self.settings.dp_step_s
        t0 = float(coarse_s[0])
        lo = t0 + step * (np.floor((coarse_s[j - 1] - t0) / step + 1e-9) + 1)
        fine = np.arange(lo, coarse_s[j] + 0.5 * step, step)
        hit = for_mask(self.constellation.track_ecef_km(name, fine), gp_km, self.for_deg(name)).any(axis=1)
        return float(fine[np.argmax(hit)]) if hit.any() else float(coarse_s[j])

    def instance(self, sat: str, t0_s: float, knowledge: Knowledge, *, window_s: float | None = None,
                 step_s: float | None = None, gp_ids=None, init_target_km=None,
                 init_t_s: float | None = None) -> SchedulingProblem:
        """The instance of ``sat`` over [t0_s, t0_s + window_s) on the DP grid (defaults: the
        settings' look-ahead and step).

        GPs: ``gp_ids``, or every GP in the FOR at some step of the window. init_target_km /
        init_t_s: the GP the satellite last pointed at and when (it may slew from then; without
        init_t_s it slews from the window's start).
        """
        st = self.settings
        step = float(step_s or st.dp_step_s)
        window = float(window_s or st.plan_lookahead_s)
        n = max(1, round(window / step))
        times = t0_s + step * np.arange(n)
        sat_pos = self.constellation.track_ecef_km(sat, times)
        all_gp = self.gp_ecef_km if gp_ids is None else self.gp_ecef_km[np.asarray(gp_ids)]
        vis = for_mask(sat_pos, all_gp, self.for_deg(sat))
        if gp_ids is None:
            ids = np.flatnonzero(vis.any(axis=0))
            vis = vis[:, ids]
        else:
            ids = np.asarray(gp_ids, dtype=np.int64)
        value = knowledge.value
        # a view that reads every time from ``frozen_after_s`` on as that instant (a persistence
        # view) has one row for the whole window: computed once, the same numbers as row by row
        frozen = getattr(value, "frozen_after_s", None)
        at = times[:1] if frozen is not None and times[0] >= frozen else times
        forecast = value.value_at(ids[None, :], at[:, None]).astype(np.float64)
        if knowledge.belief is not None and len(ids):
            absval = knowledge.belief.absval(forecast, ids[None, :], value.slot_of(at)[:, None])
        else:
            absval = forecast
        if st.diversity_weight > 0 and len(ids):
            recent = recent_observed_gps(knowledge.known, t0_s, st.diversity_window_s)
            absval = absval * diversity_factor(self.gp_ecef_km[ids], self.gp_ecef_km[recent], st.diversity_weight,
                                               st.diversity_km)[None, :]
        tasks = knowledge.tasks
        if tasks is not None and len(ids) and times[0] <= tasks.last_by_s:
            if len(at) < len(times):  # the tasks' deadlines make the window's rows differ
                absval, at = np.broadcast_to(absval, (len(times), len(ids))), times
            absval = tasks.apply(sat, ids, times, absval)
        if len(at) < len(times):
            absval = absval[0]  # (G,): build_problem spreads it over the window
        count, recent = prior_state(knowledge.known, ids, times, sat, st.revisit_zero_s)
        init_pos = None
        if init_target_km is not None and init_t_s is not None:
            init_pos = self.constellation.track_ecef_km(sat, np.array([float(init_t_s)]))[0]
        return build_problem(t0_s=t0_s, step_s=step, sat_pos_km=sat_pos, gp_ecef_km=self.gp_ecef_km[ids],
                             in_for=vis, absval=absval, slew=self.own[sat].slew if sat in self.own else self.slew,
                             revisit_zero_s=st.revisit_zero_s,
                             gp_ids=ids, prior_count=count, prior_recent=recent,
                             init_target_km=init_target_km, init_sat_pos_km=init_pos,
                             ready_t_s=init_t_s if init_pos is not None else None, sat_name=sat)

    def pass_starts_s(self, sat: str, t0_s: float, t1_s: float, step_s: float = 10.0) -> np.ndarray:
        """Times [s] (on a step_s grid) when some GP enters the satellite's FOR after none was in it."""
        times = np.arange(t0_s, t1_s, step_s)
        pos = self.constellation.track_ecef_km(sat, times)
        vis = for_mask(pos, self.gp_ecef_km, self.for_deg(sat)).any(axis=1)
        rise = np.flatnonzero(vis & ~np.concatenate([[False], vis[:-1]]))
        return times[rise]
