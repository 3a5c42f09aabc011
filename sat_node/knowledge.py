"""What a planner knows about the value field, and only through the system: named knowledge models.

The rule of the project (docs/design.md section 1): a planner - a satellite onboard, or the ground
segment - knows only what reached it, down to the single ground point (GP): its own observations,
the inferences bundles delivered to it, and for the ground what was downlinked at passes. A
:class:`KnowledgeState` is that record for one planner (the :class:`~sat_node.inference.Inference`
of every observation it knows of, and the newest information time per region);
:meth:`KnowledgeState.knowledge` turns it into the
:class:`~sat_node.scheduler.planner.Knowledge` the planner plans with. How it values the GPs is a
named strategy (:data:`MODELS`, scenario key ``value.knowledge``):

* ``observed`` - the default, and the only model that knows nothing but what reached the planner:
  it starts from the a-priori forecast (issued at the epoch; it does not hold the events nobody could
  foresee, ground_station/osse.py ``OsseField.forecast``) and updates it from the inferred values
  it knows only (:class:`ObservedView`): in log space, the innovation ``d = ln(v / forecast)`` of
  each observation spreads to the GPs of its region with a Gaussian kernel of
  ``observation_spread_km`` and fades with e-folding time ``observation_memory_min``; where the
  observations' total weight ``W`` is below one, the region insight of the newest inference
  (``omega`` + ``delta`` x time, fading alike; computed by the observer from the looks it knew,
  :meth:`KnowledgeState.region_insight`) fills ``1 - W`` of it::

      D(g, t) = sum_o k(g, o, t) d_o / max(1, W) + (1 - min(1, W)) omega_r(t),   W = sum_o k(g, o, t)
      value(g, t) = clip(forecast(g, t) exp(D), 1, 256)

  so an observed GP, right after its observation, is valued at what was seen, its neighbours move
  with it, and the rest of the region follows the region's insight.
* ``region-truth`` - a sensitivity, never a default: the OSSE truth delayed to the region's
  information time - an upper bound on what a perfect onboard hydrologic model could infer. The
  planner values *every* GP of a region with the true field as it was at the time of its newest
  information about the region (an own look, a delivered bundle's observation, a downlinked
  observation's collection time; before any, the epoch), through its own inference noise
  (:class:`sat_node.value.Belief`) (:class:`RegionPersistenceView`). One look at one GP unlocks the
  truth of all the region's GPs at that time, so it reads ground points nobody observed (the
  ground-point twin test catches it). It takes the region insight of Nag et al. (ICAPS SPARK 2019,
  sections 4-5: each observation's bundle carries the observer's model parameters of the region) as
  if it made the receiver know the whole region exactly.
* ``oracle`` - the behaviour before knowledge models (kept for comparison, never a default): the true
  field as of planning time, for every GP, through the belief noise
  (:class:`~sat_node.scheduler.planner.PersistenceView`). It reads the truth; it is not a planner
  anyone could fly.

The name ``study`` (the former default, now ``region-truth``) is refused with a one-line error that
names the models (:data:`RENAMED`, :func:`check_model`), never mapped silently.

Each model also names the information time of a region for a plan (:meth:`KnowledgeState.info_time_s`):
``observed``/``region-truth`` the newest known observation there (0: the epoch), ``oracle`` the
planning time. Each executed look carries it (``Observation.info_ns``); the report's
``knowledge.info_age_s`` is the look's time minus it.

How we know it is right (tests/unit/test_knowledge.py): two truth fields that differ only in a
region nobody observed give the same planner inputs (``region-truth``, ``observed``) until an
observation of it is known, and different ones under ``oracle``; ``region-truth`` reads the truth at
no time later than the region's information time; the observed view equals a scalar re-computation
of the formula on random observations, is exact at an observation just made, and reverts to the
forecast far away and long after; a flood seen by one satellite makes the next one choose it. The
whole-run checks, both engines: tests/system/test_gp_twin.py (the ground-point twin test: changing
only the GPs a run never observed changes nothing under ``observed``, distributed and centralized,
and changes the plans under ``region-truth`` and ``oracle``) and tests/system/test_knowledge_flow.py
(a whole region changed).
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass

import numpy as np

from sat_node.inference import Inference
from sat_node.knowledge_kernels import gathered_exponent, innovation_grid, kernel_exponent, place_exponent
from sat_node.scheduler.planner import Knowledge, PersistenceView
from sat_node.value import Belief

__all__ = ["DEFAULT_MODEL", "MODELS", "RENAMED", "SLOW_FIELD_TRANSIENCY_MIN", "KnowledgeParams", "KnowledgeState",
           "ObservedView", "RegionPersistenceView", "check_model"]

#: name -> one line of help (scenario validation and the CLI use the names); the first is the default
MODELS: dict[str, str] = {
    "observed": "the a-priori forecast updated by the inferred values that reached the planner (the default)",
    "region-truth": "the OSSE truth delayed to the region's information time: an upper bound on what a perfect "
                    "onboard hydrologic model could infer (a sensitivity, never a default)",
    "oracle": "the true field at planning time for every GP (comparison only: no planner can know it)",
}
DEFAULT_MODEL = "observed"

#: former names -> what became of them (refused with this hint, never mapped silently)
RENAMED: dict[str, str] = {
    "study": "renamed 'region-truth' (a sensitivity that reads the truth of GPs nobody observed); "
             "the default is now 'observed'",
}


def check_model(name: str) -> str:
    """``name`` if it is a knowledge model, else ValueError in one line naming the models."""
    if name in MODELS:
        return name
    known = ", ".join(MODELS)
    if name in RENAMED:
        raise ValueError(f"knowledge model {name!r} was {RENAMED[name]} (models: {known})")
    raise ValueError(f"knowledge model {name!r}: unknown (models: {known})")

#: the slow storm-cell field's transiency (``value.transiency_min = 0``), measured on seeds 1-3:
#: 144-238 min (ground_station/osse_stats.py); what the observed model assumes of it
SLOW_FIELD_TRANSIENCY_MIN = 180.0
_LN_MAX = math.log(256.0)


_scratch = threading.local()


def _buffer(rows: int, cols: int) -> np.ndarray:
    """A (rows, cols) float64 scratch array of this thread, kept between calls (the kernel matrix of
    :meth:`ObservedView._ref`: a fresh array of tens of MB costs its page faults at every plan)."""
    buf = getattr(_scratch, "buf", None)
    if buf is None or buf.size < rows * cols:
        buf = _scratch.buf = np.empty(max(rows * cols, 1))
    return buf[:rows * cols].reshape(rows, cols)


@dataclass(frozen=True)
class KnowledgeParams:
    """A planner's knowledge model and its two parameters (units in names)."""

    model: str = DEFAULT_MODEL
    spread_km: float = 10.0
    memory_s: float = 15.0 * 60.0 / math.log(2.0)

    def __post_init__(self) -> None:
        check_model(self.model)
        if not (self.spread_km > 0 and self.memory_s > 0):
            raise ValueError(f"knowledge: spread_km ({self.spread_km}) and memory_s ({self.memory_s}) must be > 0")

    @classmethod
    def from_scenario(cls, sc) -> KnowledgeParams:
        """``value.knowledge`` and its parameters; the memory defaults to an e-folding time whose
        half-life is the field's transiency."""
        v = sc.value
        memory_min = v.observation_memory_min or (v.transiency_min or SLOW_FIELD_TRANSIENCY_MIN) / math.log(2.0)
        return cls(model=v.knowledge, spread_km=float(v.observation_spread_km), memory_s=60.0 * memory_min)


class RegionPersistenceView:
    """``region-truth``: the true field read at each GP's region information time, never later. ``info_s`` [s]:
    per GP (all GPs of the scenario), the time of the newest information about its region;
    ``t_now_s``: planning time (the belief noise's slot, as :class:`PersistenceView`)."""

    def __init__(self, field, info_s: np.ndarray, t_now_s: float):
        self._field = field
        self._info = np.asarray(info_s, np.float64)
        self._t = float(t_now_s)

    @property
    def frozen_after_s(self) -> float:
        """Every time from the planning time (or the latest information time, if later) on reads the same."""
        return max(self._t, float(self._info.max())) if len(self._info) else self._t

    def value_at(self, gp_idx, t_s):
        gp, t = np.broadcast_arrays(np.asarray(gp_idx), np.asarray(t_s, np.float64))
        return self._field.value_at(gp, np.minimum(t, self._info[gp]))

    def slot_of(self, t_s):
        return self._field.slot_of(np.minimum(np.asarray(t_s, np.float64), self._t))


class ObservedView:
    """``observed``: the forecast updated by observations (module docstring's formula).

    obs: arrays ``gp``, ``t_s``, ``d`` (innovation, ln inferred/forecast) of the known inferences
    with their ``xyz`` [km] positions; ``insight``: region -> (t_s, omega, delta) newest."""

    def __init__(self, field, region_index: np.ndarray, gp_ecef_km: np.ndarray, obs: dict,
                 insight: dict[int, tuple[float, float, float]], params: KnowledgeParams, t_now_s: float):
        self._field = field
        self._region = region_index
        self._xyz = gp_ecef_km
        self._obs = obs
        self._insight = insight
        self._p = params
        self._t = float(t_now_s)
        # (region, its GPs asked for) -> their (sum_o k d_o, sum_o k): the instances of one plan (the
        # planned satellite's and its partners') ask for the same regions' GPs
        self._ref_cache: dict[tuple[int, bytes], tuple[np.ndarray, np.ndarray]] = {}
        self._looks: dict[int, tuple | None] = {}  # region -> its known looks (_region_looks)

    def _ref(self, gps: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per GP: (sum_o k d_o, sum_o k) at the planning time, region by region. A region's numbers
        are kept for the next call that asks for exactly the same GPs of it: the same operations on
        the same arrays give the same numbers (a matrix product's rounding may depend on the rows it
        is given, so only the same rows are taken again; tests/unit/test_knowledge.py)."""
        n = np.zeros(len(gps))
        w = np.zeros(len(gps))
        o = self._obs
        if len(o["gp"]) == 0:
            return n, w
        for r in np.unique(self._region[gps]):
            sel = np.flatnonzero(self._region[gps] == r)
            key = (int(r), gps[sel].tobytes())
            got = self._ref_cache.get(key)
            if got is None:
                looks = self._region_looks(int(r))
                if looks is None:
                    continue
                xyz, t_s, d, places, place_of = looks
                gxyz = np.ascontiguousarray(self._xyz[gps[sel]])
                if places is None:
                    # the kernel's exponent in one compiled pass (sat_node/knowledge_kernels.py: the bits of
                    # -0.5 |dx|^2 / spread^2 - (t - t_o) / memory as numpy made them); exp, @, sum numpy's
                    k = np.exp(kernel_exponent(gxyz, xyz, t_s, self._t, self._p.spread_km ** 2, self._p.memory_s))
                else:  # the same bits, the distance term once per place looked at, in a kept buffer
                    k = gathered_exponent(place_exponent(gxyz, places, self._p.spread_km ** 2), place_of, t_s,
                                          self._t, self._p.memory_s, _buffer(len(sel), len(t_s)))
                    np.exp(k, out=k)
                got = self._ref_cache[key] = (k @ d, k.sum(axis=1))
            n[sel], w[sel] = got
        return n, w

    def _region_looks(self, r: int):
        """(xyz (N, 3), t_s (N,), d (N,), places (U, 3), place_of (N,)) of the known looks in region
        ``r``, contiguous, kept for the view (None: none there): ``places`` the distinct GPs looked at
        and ``place_of`` each look's, so that ``xyz == places[place_of]`` (places None if the looks'
        positions are not their GPs')."""
        if r not in self._looks:
            o = self._obs
            mo = o["region"] == r
            if not mo.any():
                self._looks[r] = None
            else:
                xyz = np.ascontiguousarray(o["xyz"][mo], np.float64)
                # the distinct GPs looked at (in id order; any order gives the same numbers), one look
                # of each, and each look's place: in one pass over the looks (GP ids are small)
                g = np.asarray(o["gp"][mo], np.int64)
                present = np.zeros(int(g.max()) + 1, bool)
                present[g] = True
                one = np.empty(len(present), np.int64)
                one[g] = np.arange(len(g))
                place_of = np.cumsum(present)[g] - 1
                places = np.ascontiguousarray(xyz[one[np.flatnonzero(present)]])
                if places[place_of].tobytes() != xyz.tobytes():
                    places = place_of = None
                self._looks[r] = (xyz, np.ascontiguousarray(o["t_s"][mo], np.float64), o["d"][mo], places,
                                  None if place_of is None else np.ascontiguousarray(place_of, np.int64))
        return self._looks[r]

    def innovation(self, gp_idx, t_s) -> np.ndarray:
        """D(g, t) of the module docstring (t at or after the planning time). ``gp_idx`` and ``t_s``
        broadcast (a planner asks for a row of GPs by a column of times): the per-GP and per-time
        factors are computed on the arrays as given and combined in the broadcast shape, each element
        by the same operations in the same order as element by element."""
        g0 = np.asarray(gp_idx)
        t0 = np.asarray(t_s, np.float64)
        shape = np.broadcast_shapes(g0.shape, t0.shape)
        flat = g0.ravel()
        if flat.size and g0.ndim and bool(np.all(flat[1:] > flat[:-1])):  # distinct and sorted (a planner's)
            n, w = self._ref(flat)
            n0, w0 = n.reshape(g0.shape), w.reshape(g0.shape)
        else:
            uniq, inv = np.unique(g0, return_inverse=True)
            n, w = self._ref(uniq)
            n0, w0 = n[inv].reshape(g0.shape), w[inv].reshape(g0.shape)
        a = np.exp(-np.maximum(t0 - self._t, 0.0) / self._p.memory_s)
        reg0 = self._region[g0]
        # a row of GPs by a column of times (a planner's instance): the (T, G) combination in one
        # compiled pass (sat_node/knowledge_kernels.py innovation_grid: the numbers of the general
        # path below), each region's insight a row of per-time terms its columns read
        if len(shape) == 2 and g0.shape == (1, shape[1]) and t0.shape == (shape[0], 1):
            rows = [np.zeros(shape[0])]
            col_row = np.zeros(shape[1], np.int64)
            for r, (t_i, omega, delta) in self._insight.items():
                m0 = reg0[0] == r
                if m0.any():
                    col_row[m0] = len(rows)
                    rows.append(self._insight_term(t0, t_i, omega, delta).ravel())
            return innovation_grid(np.ascontiguousarray(a.ravel()), np.ascontiguousarray(n0.ravel()),
                                   np.ascontiguousarray(w0.ravel()), np.stack(rows), col_row, _LN_MAX)
        wt = a * w0
        d = a * n0 / np.maximum(1.0, wt)
        om = np.zeros(shape)
        for r, (t_i, omega, delta) in self._insight.items():
            m0 = reg0 == r
            if m0.any():
                f = self._insight_term(t0, t_i, omega, delta)
                m = np.broadcast_to(m0, shape)
                om[m] = np.broadcast_to(f, shape)[m]
        return np.clip(d + (1.0 - np.minimum(1.0, np.broadcast_to(wt, shape))) * om, -_LN_MAX, _LN_MAX)

    def _insight_term(self, t0: np.ndarray, t_i: float, omega: float, delta: float) -> np.ndarray:
        """A region insight's term at times ``t0``: (omega + delta x age [h], the age capped at the
        memory) faded with e-folding time memory."""
        age = t0 - t_i
        return (omega + delta * np.minimum(age, self._p.memory_s) / 3600.0) * np.exp(-age / self._p.memory_s)

    def value_at(self, gp_idx, t_s):
        g0, t0 = np.asarray(gp_idx), np.asarray(t_s, np.float64)
        f = np.broadcast_to(self._field.forecast_at(g0, t0), np.broadcast_shapes(g0.shape, t0.shape))
        return np.clip(f.astype(np.float64) * np.exp(self.innovation(g0, t0)), 1.0, 256.0)

    def slot_of(self, t_s):
        return self._field.slot_of(t_s)


def _empty_columns(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    return np.zeros(n, np.int64), np.zeros(n, np.float64), np.zeros(n, np.float64), np.zeros(n, np.int64)


class KnowledgeState:
    """What one planner (``me``) knows of the field: every inference it learned, the newest
    information time per region, the newest region insight per region. Small and picklable (the
    satellite's checkpoint holds it); the field, GPs and belief are passed in when planning.

    The inferences are numpy columns (a plan reads them without converting a list) and each one's
    innovation is made once, when a plan first needs it; tests/unit/test_knowledge_columns.py keeps
    the list-based state as first written and checks the same insights, views and values."""

    def __init__(self, params: KnowledgeParams, me: str):
        self.params = params
        self.me = me
        self.region_info_s: dict[int, float] = {}
        self.insight: dict[int, tuple[float, float, float]] = {}
        self._keys: set[tuple[str, int, int]] = set()
        # every inference known, in the order learned: (GP, time [s], inferred value, region) columns,
        # numpy arrays filled up to _n (grown by doubling): a plan reads them as arrays, without
        # converting a list of every look known at every plan
        self._n = 0
        self._cols = _empty_columns(0)

    def __len__(self) -> int:
        return self._n

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state["_cols"] = tuple(c[:self._n].copy() for c in self._cols)  # the checkpoint holds no spare room
        state.pop("_d_cache", None)  # (the field's, made again from the columns)
        return state

    def _append(self, gp: int, t_s: float, value: float, region: int) -> None:
        n = self._n
        if n == len(self._cols[0]):
            self._cols = tuple(np.concatenate([c, e]) for c, e in zip(self._cols, _empty_columns(max(64, n))))
        gp_a, t_a, v_a, r_a = self._cols
        gp_a[n], t_a[n], v_a[n], r_a[n] = gp, t_s, value, region
        self._n = n + 1

    def _innovations(self, field) -> np.ndarray:
        """Per inference known, its innovation ``ln(max(v, 1) / forecast)`` in ``field``: computed once
        per inference (a look's never changes), for the ones learned since the last call, kept for
        the same field. The same elementwise operations as on all of them at once (numpy's log is
        elementwise: tests/unit/test_knowledge_columns.py compares batches of every size)."""
        n = self._n
        got = getattr(self, "_d_cache", None)
        if got is None or got[0] is not field:
            got = (field, np.zeros(0), 0)
        _f, d, m = got
        if m < n:
            gp, t, v, _r = (c[m:n] for c in self._cols)
            new = np.log(np.maximum(v, 1.0) / field.forecast_at(gp, t).astype(np.float64))
            if len(d) < n:
                d = np.concatenate([d[:m], new, np.zeros(len(self._cols[0]) - n)])
            else:
                d[m:n] = new
            got = (field, d, n)
        self._d_cache = got
        return d[:n]

    def _columns(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(GP int64, time [s] float64, value float64, region int64) of every inference known: views."""
        n = self._n
        return tuple(c[:n] for c in self._cols)

    def learn(self, inf: Inference) -> bool:
        """Take one inference in (own look, delivered bundle, downlink); False if already known."""
        key = (inf.src, int(inf.gp), int(inf.t_ns))
        if key in self._keys:
            return False
        self._keys.add(key)
        t = inf.t_ns / 1e9
        self._append(int(inf.gp), t, float(inf.value), int(inf.region))
        r = int(inf.region)
        if t > self.region_info_s.get(r, -math.inf):
            self.region_info_s[r] = t
        old = self.insight.get(r)
        if old is None or t > old[0]:
            self.insight[r] = (t, float(inf.omega), float(inf.delta))
        return True

    def observe(self, field, gp: int, t_ns: int, inferred: float, region: int, src: str | None = None) -> Inference:
        """A look of ``src`` (default: this planner) known first-hand - an own look, or for the ground
        an observation it processes from a downlink: its inference, with the region insight that
        includes it (to share), learned."""
        t_s = t_ns / 1e9
        self._append(int(gp), t_s, float(inferred), int(region))
        omega, delta = self.region_insight(field, int(region), t_s)
        self._n -= 1
        inf = Inference(src=src or self.me, gp=int(gp), t_ns=int(t_ns), value=float(inferred), region=int(region),
                        omega=omega, delta=delta)
        self.learn(inf)
        return inf

    def info_time_s(self, region: int, t_now_s: float) -> float:
        """The time of the information a plan made now uses for ``region`` (module docstring)."""
        if self.params.model == "oracle":
            return float(t_now_s)
        return float(self.region_info_s.get(int(region), 0.0))

    def region_insight(self, field, region: int, t_s: float) -> tuple[float, float]:
        """(omega, delta) of ``region`` at ``t_s`` from every inference known (sat_node/inference.py):
        omega = the age-weighted mean of ln(inferred / forecast) there, delta = its change since the
        newest insight held before [1/h] (0 without one within the memory)."""
        gp_all, t_all, v_all, r_all = self._columns()
        sel = np.flatnonzero((r_all == region) & (t_all <= t_s))
        if len(sel) == 0:
            return 0.0, 0.0
        gp = gp_all[sel]
        t = t_all[sel]
        v = v_all[sel]
        d = np.log(np.maximum(v, 1.0) / field.forecast_at(gp, t).astype(np.float64))
        w = np.exp(-(t_s - t) / self.params.memory_s)
        omega = float(np.clip((w @ d) / w.sum(), -_LN_MAX, _LN_MAX))
        delta = 0.0
        prev = self.insight.get(region)
        if prev is not None and 0.0 < t_s - prev[0] <= self.params.memory_s:
            delta = float(np.clip((omega - prev[1]) / ((t_s - prev[0]) / 3600.0), -_LN_MAX, _LN_MAX))
        return omega, delta

    def knowledge(self, field, region_index: np.ndarray, gp_ecef_km: np.ndarray, t_now_s: float,
                  known, belief: Belief | None) -> Knowledge:
        """The :class:`Knowledge` a plan made at ``t_now_s`` uses (``known``: the observations for
        Eq. 1's prior state, as the caller keeps them)."""
        model = self.params.model
        if model == "oracle":
            return Knowledge(PersistenceView(field, t_now_s), known, belief)
        if model == "region-truth":
            info = np.zeros(len(region_index))
            for r, t in self.region_info_s.items():
                info[region_index == r] = min(t, t_now_s)
            return Knowledge(RegionPersistenceView(field, info, t_now_s), known, belief)
        gp, t, _v, _r = self._columns()
        keep = (t <= t_now_s) & (t_now_s - t < 7.0 * self.params.memory_s)  # older ones weigh < 1e-3
        d = self._innovations(field)[keep] if len(gp) else np.zeros(0)
        gp, t = gp[keep], t[keep]
        obs = {"gp": gp, "t_s": t, "d": d, "region": np.asarray(region_index)[gp] if len(gp) else np.zeros(0, int),
               "xyz": gp_ecef_km[gp] if len(gp) else np.zeros((0, 3))}
        insight = {r: x for r, x in self.insight.items() if x[0] <= t_now_s}
        return Knowledge(ObservedView(field, np.asarray(region_index), gp_ecef_km, obs, insight, self.params,
                                      t_now_s), known, None)
