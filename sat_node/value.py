"""Observation value (the study's Eq. 1) and each satellite's noisy belief of it.

Nag et al., ICAPS SPARK 2019, section 4 / docs/design.md section 1: the value of observing GP ``g`` at
time ``t`` is

* 0 if ``g`` was seen less than ``revisit_zero_s`` (15 min) before ``t``;
* else ``absval(g, t) / (n + 1)`` where ``n`` is how many times ``g`` was seen before ``t`` and
  ``absval`` is the OSSE value (integer 1..256 per GP per 15-min slot).

"Seen before t" uses every observation the caller knows was executed (by itself or by anyone who
told it); at exactly ``t`` another satellite's look counts as before ours when its name sorts first.

Implicit consensus (:func:`prior_state`): plans of other satellites are claims resolved by a fixed
rank, the satellite name order (``sat_11`` outranks ``sat_12``). A satellite yields to every known
planned look of a satellite that outranks it - the GP is worth 0 to it within ``revisit_zero_s``
*before or after* that look, and counts as seen after it - and ignores the plans of lower-ranked
satellites (they yield to it). Two satellites that know each other's plans therefore never both keep
the same GP within 15 min, and replanning in turns settles after one round (the higher rank does
not move for the lower).

Belief: satellite ``s`` does not know ``absval`` exactly; it believes ``absval * (1 + sigma_s z)``
with ``z ~ N(0, 1)`` i.i.d. per (GP, slot), clipped at 0, and ``sigma_s ~ U(sigma_min, sigma_max)``
(2 %..8 %). Both are drawn from ``numpy.random.default_rng(SeedSequence([seed, crc32(name)]))`` -
first sigma, then the (n_gp, n_slots) matrix of z - so the local and the ROS engine, and a restarted
process, draw the same numbers. (Python's ``hash`` is salted per process and is not used.)

How we know it is right (tests/unit/test_value.py): Eq. 1 against a hand-written scalar loop over
random histories; the 15-min zero at the boundary (899.999 s -> 0, 900 s -> absval/2); belief noise
reproducible across calls and processes, different across satellites, and its sample standard
deviation of (belief/absval - 1) within 3 standard errors of sigma_s; :func:`prior_state` (runs found by
binary search) equal to the pairwise definition on random histories with observations exactly on the
grid times and on grid times +- revisit_zero_s, on unsorted and repeated times; :class:`ValueLedger`
(the true value of executed observations, one at a time) equal to :func:`true_value` evaluated on
each observation's history. The report's value of a bag of nine observations equals Eq. 1 worked
out by hand (tests/unit/test_report_value.py).

The optional spatial-diversity term (value for observing GPs far from recent observations) is the
planner's, off by default: sat_node/diversity.py.
"""

from __future__ import annotations

import zlib
from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np

from sat_node.value_kernels import prior_runs

__all__ = [
    "Belief",
    "KnownLog",
    "KnownObservation",
    "ValueLedger",
    "belief_sigma",
    "name_key",
    "prior_state",
    "true_value",
]


def name_key(name: str) -> int:
    """Stable 32-bit key of a satellite name (CRC-32 of its UTF-8 bytes)."""
    return zlib.crc32(name.encode("utf-8"))


def true_value(absval, t_s, last_seen_t_s, times_seen, revisit_zero_s: float) -> np.ndarray:
    """Eq. 1, vectorized: 0 if seen within revisit_zero_s before t_s, else absval / (times_seen + 1).

    ``last_seen_t_s`` is -inf (or NaN) for a GP never seen; all arguments broadcast.
    """
    absval = np.asarray(absval, dtype=np.float64)
    last = np.asarray(last_seen_t_s, dtype=np.float64)
    n = np.asarray(times_seen, dtype=np.float64)
    if np.any(n < 0):
        raise ValueError("true_value: times_seen must be >= 0")
    recent = np.isfinite(last) & ((np.asarray(t_s, np.float64) - last) < revisit_zero_s)
    return np.where(recent, 0.0, absval / (n + 1.0))


class ValueLedger:
    """Eq. 1 of executed observations, added one at a time in time order (ties: satellite, GP):
    what each one is truly worth given the ones before it, and the running total. The report's
    value (bringup/analysis/report.py true_values) and the recorded value series
    (bringup/recording/metrics_feed.py) both add observations here."""

    def __init__(self, revisit_zero_s: float):
        self.zero_ns = round(revisit_zero_s * 1e9)
        self.last_ns: dict[int, int] = {}
        self.seen: dict[int, int] = {}
        self.total = 0.0

    def add(self, gp: int, t_ns: int, recorded_value: float) -> tuple[float, bool]:
        """(true value of observing ``gp`` at ``t_ns`` with OSSE value ``recorded_value``, whether it
        repeats one within ``revisit_zero_s``); the observation then counts as seen."""
        last = self.last_ns.get(gp)
        recent = last is not None and (t_ns - last) < self.zero_ns
        n = self.seen.get(gp, 0)
        v = 0.0 if recent else recorded_value / (n + 1)
        self.seen[gp] = n + 1
        self.last_ns[gp] = t_ns
        self.total += v
        return v, recent


def belief_sigma(seed: int, sat_name: str, sigma_min: float, sigma_max: float) -> float:
    """The satellite's belief noise sigma [-] ~ U(sigma_min, sigma_max), seeded by (seed, name)."""
    return Belief(seed=seed, sat_name=sat_name, n_gp=0, n_slots=0,
                  sigma_min=sigma_min, sigma_max=sigma_max).sigma


@dataclass
class Belief:
    """One satellite's noisy view of the OSSE absolute value.

    n_gp, n_slots: size of the whole scenario's value grid (all GPs, all 15-min slots), so that the
    same noise matrix is drawn whoever asks.
    """

    seed: int
    sat_name: str
    n_gp: int
    n_slots: int
    sigma_min: float = 0.02
    sigma_max: float = 0.08
    sigma: float = field(init=False)
    z: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if not (0.0 <= self.sigma_min <= self.sigma_max):
            raise ValueError(f"Belief: need 0 <= sigma_min <= sigma_max, got {self.sigma_min}, {self.sigma_max}")
        if self.n_gp < 0 or self.n_slots < 0:
            raise ValueError(f"Belief: n_gp and n_slots must be >= 0, got {self.n_gp}, {self.n_slots}")
        rng = np.random.default_rng(np.random.SeedSequence([int(self.seed), name_key(self.sat_name)]))
        self.sigma = float(rng.uniform(self.sigma_min, self.sigma_max))
        self.z = rng.standard_normal((self.n_gp, self.n_slots))

    @classmethod
    def from_scenario(cls, sc, sat_name: str, n_gp: int, n_slots: int) -> Belief:
        return cls(seed=sc.scenario.seed, sat_name=sat_name, n_gp=n_gp, n_slots=n_slots,
                   sigma_min=sc.value.belief_sigma_min, sigma_max=sc.value.belief_sigma_max)

    def factor(self, gp, slot) -> np.ndarray:
        """Multiplicative belief factor ``max(0, 1 + sigma z)`` for GP index/indices and slot(s)."""
        gp = np.asarray(gp)
        slot = np.asarray(slot)
        if gp.size and (gp.min() < 0 or gp.max() >= self.n_gp):
            raise IndexError(f"Belief({self.sat_name}): GP index out of 0..{self.n_gp - 1}")
        if slot.size and (slot.min() < 0 or slot.max() >= self.n_slots):
            raise IndexError(f"Belief({self.sat_name}): slot out of 0..{self.n_slots - 1}")
        return np.maximum(0.0, 1.0 + self.sigma * self.z[gp, slot])

    def absval(self, true_absval, gp, slot) -> np.ndarray:
        """Believed absolute value for true value(s) at (gp, slot), broadcasting."""
        return np.asarray(true_absval, np.float64) * self.factor(gp, slot)


@dataclass(frozen=True, order=True)
class KnownObservation:
    """An observation a satellite knows of: executed by anyone, or planned (by another satellite)."""

    t_s: float
    gp: int
    source: str
    planned: bool = False


class KnownLog(list):
    """The observations a planner knows of (a list of :class:`KnownObservation`, appended to), with
    their columns as arrays for :func:`prior_state`, extended as the list grows rather than rebuilt
    at every plan (any change other than an append drops them). Any other iterable of observations
    works too (its columns built at each call)."""

    def __getstate__(self):
        return {}  # a checkpoint holds the observations; the columns are rebuilt from them

    def _changed(self) -> None:
        self.__dict__.pop("_columns", None)

    # anything but appending drops the columns (appends extend them at the next read)
    def __setitem__(self, *a):
        self._changed()
        return super().__setitem__(*a)

    def __delitem__(self, *a):
        self._changed()
        return super().__delitem__(*a)

    def insert(self, *a):
        self._changed()
        return super().insert(*a)

    def remove(self, *a):
        self._changed()
        return super().remove(*a)

    def pop(self, *a):
        self._changed()
        return super().pop(*a)

    def clear(self):
        self._changed()
        return super().clear()

    def columns(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(gp int64, t_s float64, source str, planned bool) of every observation, in list order."""
        n = len(self)
        c = self.__dict__.get("_columns")
        if c is None or c[0] > n or (c[0] and self[c[0] - 1] is not c[5]):
            c = (0, np.zeros(0, np.int64), np.zeros(0, np.float64), np.zeros(0, str), np.zeros(0, bool), None)
        have = c[0]
        if have < n:
            new = self[have:]
            c = (n, np.concatenate([c[1], np.fromiter((o.gp for o in new), np.int64, n - have)]),
                 np.concatenate([c[2], np.fromiter((o.t_s for o in new), np.float64, n - have)]),
                 np.concatenate([c[3], np.array([o.source for o in new], dtype=str)]),
                 np.concatenate([c[4], np.fromiter((o.planned for o in new), bool, n - have)]), self[n - 1])
            self.__dict__["_columns"] = c
        return c[1], c[2], c[3], c[4]


def prior_state(known: Iterable[KnownObservation], gp_ids: np.ndarray, times_s: np.ndarray,
                me: str, revisit_zero_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Per (time, GP): how many known observations come before, and whether one is recent.

    Returns ``(count, recent)``, both shape (len(times_s), len(gp_ids)): ``count`` = number of known
    observations of that GP before the time (same-time ones count when their source sorts before
    ``me``); ``recent`` = True when one of those is less than ``revisit_zero_s`` before, or (a plan
    of a satellite that outranks ``me``) less than ``revisit_zero_s`` before or after. Own
    observations (source == me) at the same time count as before.

    Each observation covers a run of consecutive times once the times are sorted (every test below
    is monotone in the time: ``ts < t``, ``fl(t - ts) < r``, ``fl(t - ts) > -r``), so it is found by
    binary search and the runs are summed with a difference array (sat_node/value_kernels.py
    prior_runs): O(N log T + T G) instead of one
    (T, N) comparison per GP column, and the same booleans as the pairwise tests.
    """
    gp_ids = np.asarray(gp_ids, dtype=np.int64)
    times_s = np.asarray(times_s, dtype=np.float64)
    T, G = len(times_s), len(gp_ids)
    if G and gp_ids.min() < 0:
        raise ValueError(f"prior_state: GP ids must be >= 0, got {int(gp_ids.min())}")
    k_gp, k_t, k_src, k_planned = (known.columns() if isinstance(known, KnownLog)
                                   else KnownLog(known).columns())
    col_of = np.full(max(int(gp_ids.max(initial=-1)), int(k_gp.max(initial=-1))) + 1, -1, np.int64)
    col_of[gp_ids] = np.arange(G)
    j = np.where(k_gp >= 0, col_of[np.maximum(k_gp, 0)], -1)
    # own plans and a lower-ranked satellite's yield to us
    keep = (j >= 0) & ~(k_planned & (k_src >= me)) if len(k_gp) else np.zeros(0, bool)
    if not keep.any() or T == 0:
        return np.zeros((T, G), dtype=np.int64), np.zeros((T, G), dtype=bool)
    order = None
    if T > 1 and not np.all(times_s[1:] >= times_s[:-1]):
        order = np.argsort(times_s, kind="stable")
        times_s = times_s[order]
    cols = j[keep]
    ts = k_t[keep]
    wins = k_src[keep] <= me  # counts at equal time
    planned = k_planned[keep]
    r = float(revisit_zero_s)
    # first time the observation is "before": t > ts, or t == ts when it wins the tie
    start = np.where(wins, np.searchsorted(times_s, ts, "left"), np.searchsorted(times_s, ts, "right"))
    # first time with fl(t - ts) >= r (recent ends), and, for plans, first with fl(t - ts) > -r
    end = _first_index(times_s, ts, r, lambda d: d >= r, np.searchsorted(times_s, ts + r, "left"))
    lo = _first_index(times_s, ts, r, lambda d: d > -r, np.searchsorted(times_s, ts - r, "right"))
    rec_lo = np.where(planned, lo, start)
    rec_hi = np.maximum(end, rec_lo)
    count, recent = prior_runs(cols.astype(np.int64), start.astype(np.int64), rec_lo.astype(np.int64),
                               rec_hi.astype(np.int64), T, G)
    if order is not None:
        c2, r2 = np.empty_like(count), np.empty_like(recent)
        c2[order], r2[order] = count, recent
        count, recent = c2, r2
    return count, recent


def _first_index(times: np.ndarray, ts: np.ndarray, r: float, ok, guess: np.ndarray) -> np.ndarray:
    """Per observation, the first index i of sorted ``times`` with ``ok(fl(times[i] - ts))`` (len(times)
    when none), for a test ``ok`` that is monotone in the time; ``guess`` is a binary search on
    ``ts +- r``, moved until it is exact (it is off by at most a rounding step)."""
    T = len(times)
    i = guess.astype(np.int64)
    while True:  # step back while the previous time passes too
        m = i > 0
        m[m] = ok(times[i[m] - 1] - ts[m])
        if not m.any():
            break
        i[m] -= 1
    while True:  # step forward while this time fails
        m = i < T
        m[m] = ~ok(times[i[m]] - ts[m])
        if not m.any():
            break
        i[m] += 1
    return i
