"""Joint task assignment for the ``aeossp_standard`` central planner: per-satellite DPs and steal moves.

State: which satellite holds each task (or none) and each satellite's DP path over its own tasks.
A satellite's path is the exact best path (:func:`.dp_kernel.longest_path`, no battery) over the
tasks it may take; the objective is the total weight of distinct held tasks.

Moves, satellite by satellite in a seeded random order, until no move gains or the deadline:

- *replan*: satellite ``A`` replans over the free tasks and its own (block coordinate ascent: never
  loses weight);
- *steal*: ``A`` also may take tasks other satellites hold, at ``alpha`` times their weight
  (each ``alpha`` of ``ALPHAS`` in turn); every satellite that lost a task replans without it, over
  the free tasks (including those ``A`` let go). The move is kept only when the total weight rises;
- *insert*: each task nobody holds, heaviest first, is forced onto each satellite that can see it
  (a steal at ``alpha = 1`` with that task first); kept only when the total weight rises.

Each DP path visits a task at most once (the caller's ``dp`` strikes repeated visits).

The battery is left to the caller (the planner's priced DP and repair per satellite over the
assignment), which is why this search works on weights alone.

How we know it is right: tests/unit/test_aeossp_planner.py: the assignment never holds a task twice,
its total equals the sum over satellites of their paths' distinct weights, it is never below the
start it was given, and on a small case with competing satellites it reaches the brute-force
optimum of the joint assignment.
"""

from __future__ import annotations

import time

import numpy as np

__all__ = ["ALPHAS", "STATS", "assign"]

STATS: dict = {}   # the last search: rounds started (for the benchmark's log)

ALPHAS = (0.0, 0.5, 0.8, 0.95, 1.0)


def _path(dp, cand, gain):
    """(candidate indices of the best path, its distinct task ids)."""
    path = dp(cand, gain)
    tasks = np.unique(cand.task[path]) if path else np.zeros(0, dtype=int)
    return path, tasks


def assign(cands: dict, weights: np.ndarray, holder: np.ndarray, dp, deadline: float,
           seed: int = 0, max_rounds: int = 50) -> np.ndarray:
    """Improve ``holder`` (task -> satellite index in ``sorted(cands)``, -1 none); return the new one.

    ``dp(cand, gain)`` is the per-satellite longest path over candidate gains (a list of indices)."""
    order = sorted(cands)
    STATS.clear()
    holder = holder.copy()
    rng = np.random.default_rng(seed)
    n_sat = len(order)
    held = {q: np.flatnonzero(holder == q) for q in range(n_sat)}
    can = {}                                  # task -> satellites with a candidate for it
    for q, sid in enumerate(order):
        for k in np.unique(cands[sid].task):
            can.setdefault(int(k), []).append(q)

    def move(q, alpha, force=-1):
        """``q`` replans (others' tasks at ``alpha`` x weight, task ``force`` first); losers replan."""
        nonlocal holder
        c = cands[order[q]]
        h = holder[c.task]
        wc = weights[c.task]
        gain = np.where((h < 0) | (h == q), wc, alpha * wc)
        if force >= 0:
            gain = np.where(c.task == force, wc + weights.sum(), gain)
        _p, new_a = _path(dp, c, gain)
        stolen = new_a[(holder[new_a] >= 0) & (holder[new_a] != q)]
        losers = np.unique(holder[stolen])
        trial = holder.copy()
        trial[held[q]] = -1
        trial[new_a] = q
        new_sets = {q: new_a}
        for b in rng.permutation(losers):
            cb = cands[order[b]]
            trial[held[b][trial[held[b]] == b]] = -1
            tb = trial[cb.task]
            _pb, nb = _path(dp, cb, np.where(tb < 0, weights[cb.task], 0.0))
            trial[nb] = b
            new_sets[b] = nb
        before = sum(float(weights[held[s]].sum()) for s in new_sets)
        after = sum(float(weights[t].sum()) for t in new_sets.values())
        if after > before + 1e-9:
            holder = trial
            for s, t in new_sets.items():
                held[s] = t
            return True
        return False

    for _round in range(max_rounds):
        STATS["rounds"] = _round + 1
        improved = False
        for q in rng.permutation(n_sat):
            for alpha in ALPHAS:
                if time.monotonic() > deadline:
                    return holder
                improved |= move(q, alpha)
        free = np.flatnonzero(holder < 0)
        for k in free[np.argsort(-weights[free], kind="stable")]:
            if holder[k] >= 0 or int(k) not in can:
                continue
            for q in rng.permutation(can[int(k)]):
                if time.monotonic() > deadline:
                    return holder
                if move(q, 1.0, int(k)):
                    improved = True
                    break
        if not improved:
            break
    return holder
