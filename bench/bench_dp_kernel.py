"""Benchmark the DP scheduler's compiled kernel (sat_node/scheduler/dp_kernels.py) on real instances.

Two steps:

* ``capture``: run a scenario in-process (local engine) with ``solve_dp`` wrapped, and keep the
  instances it was given (every ``--every``-th plus the ``--largest`` biggest by states, so the tail
  is in), each with the plan the product's ``solve_dp`` returned (steps, cols, value) - a corpus
  directory of pickles (not committed: tens of MB).

      .venv/bin/python bench/bench_dp_kernel.py capture --out /tmp/dpc/a -- \\
          --sats 240 --planes 3 --hours 0.25 --planning alone
      .venv/bin/python bench/bench_dp_kernel.py capture --out /tmp/dpc/b -- --hours 1   # paper, joint

* ``time``: for every corpus instance, build the kernel's arrays the way ``solve_dp`` does, and time
  the baseline kernel (``_baseline_forward`` below: a verbatim copy of main's dp_forward before this
  benchmark's changes, called in 64-step chunks like main's solve_dp) against the product kernel
  (called the way the product's solve_dp calls it), in the same process on the same instances,
  interleaved, best of ``--repeat``. Checks that V (bit for bit), the back-pointers and the plan
  are identical, and that the product's ``solve_dp`` still returns the recorded plan.

      .venv/bin/python bench/bench_dp_kernel.py time /tmp/dpc/a /tmp/dpc/b [--repeat 3] [--profile]
          [--all-modes] [--every N]

``--profile`` adds the baseline's scan counters (a replay with counters) and its time split (argsort,
path-bitset row copies, the rest); ``--all-modes`` also forces the path-table and path-walk layouts
(windows longer than the revisit window; captured onboard instances all use path bitsets). The paper
corpus (second capture line) takes ~5 s to regenerate and ~6 MB; the 240-satellite ones ~1 min.
"""

from __future__ import annotations

import argparse
import dataclasses
import gzip
import math
import pickle
import sys
import time
from pathlib import Path

import numpy as np
from numba import njit

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

# ------------------------------------------------------------------------------------ baseline kernel
# main's dp_forward (and its gain helpers) as of 5562ce1, verbatim but for the names and docstrings:
# the baseline the product kernel is timed against and must agree with bit for bit.


@njit(cache=True)
def _b_path_gain(q, g, k, vf, n1, st_k, st_g, bp, revisit_steps):
    cnt = 0
    p = q
    while p >= 0:
        if st_g[p] == g:
            if (k - st_k[p]) < revisit_steps:
                return 0.0
            cnt += 1
        p = bp[p]
    if cnt == 0:
        return vf
    return vf * n1 / (n1 + cnt)


@njit(cache=True)
def _b_table_gain(q, g, k, vf, n1, seen_n, seen_k, revisit_steps):
    cnt = seen_n[q, g]
    if cnt == 0:
        return vf
    if (k - seen_k[q, g]) < revisit_steps:
        return 0.0
    return vf * n1 / (n1 + cnt)


@njit(cache=True)
def _b_bit_gain(q, g, vf, seen_b):
    if (seen_b[q, g >> 6] >> np.uint64(g & 63)) & np.uint64(1):
        return 0.0
    return vf


@njit(cache=True)
def _baseline_forward(k_lo, k_hi, t_off, st_k, st_g, st_u, st_vf, st_n1, root_ok, cos_thr, w_steps,
               revisit_steps, V, bp, order, pref, seen_n, seen_k, seen_b):
    bits = seen_b.shape[0] > 0
    table = (not bits) and seen_n.shape[0] > 0
    ninf = -np.inf
    for k in range(k_lo, k_hi):
        while pref[1] <= k - w_steps:
            kk = pref[1]
            if t_off[kk] < t_off[kk + 1]:
                s0 = order[t_off[kk]]
                if V[s0] > ninf and (pref[0] < 0 or V[s0] > V[pref[0]]):
                    pref[0] = s0
            pref[1] += 1
        for s in range(t_off[k], t_off[k + 1]):
            g = st_g[s]
            vf = st_vf[s]
            n1 = st_n1[s]
            ux = st_u[s, 0]
            uy = st_u[s, 1]
            uz = st_u[s, 2]
            best = ninf
            b = -2
            if root_ok[s]:
                best = vf
                b = -1
            p = pref[0]
            if p >= 0:
                if bits:
                    gain = _b_bit_gain(p, g, vf, seen_b)
                elif table:
                    gain = _b_table_gain(p, g, k, vf, n1, seen_n, seen_k, revisit_steps)
                else:
                    gain = _b_path_gain(p, g, k, vf, n1, st_k, st_g, bp, revisit_steps)
                if V[p] + gain > best:
                    best = V[p] + gain
                    b = p
            for dk in range(1, w_steps):
                kk = k - dk
                if kk < 0:
                    break
                thr = cos_thr[dk]
                if thr > 1.0:
                    continue
                for i in range(t_off[kk], t_off[kk + 1]):
                    q = order[i]
                    vq = V[q]
                    if vq + vf <= best:
                        break
                    dot = ux * st_u[q, 0] + uy * st_u[q, 1] + uz * st_u[q, 2]
                    if dot < thr:
                        continue
                    if bits:
                        gain = _b_bit_gain(q, g, vf, seen_b)
                    elif table:
                        gain = _b_table_gain(q, g, k, vf, n1, seen_n, seen_k, revisit_steps)
                    else:
                        gain = _b_path_gain(q, g, k, vf, n1, st_k, st_g, bp, revisit_steps)
                    if vq + gain > best:
                        best = vq + gain
                        b = q
                    if gain >= vf:
                        break
            V[s] = best
            bp[s] = b
            if bits and b > -2:
                if b >= 0:
                    for w in range(seen_b.shape[1]):
                        seen_b[s, w] = seen_b[b, w]
                seen_b[s, g >> 6] |= np.uint64(1) << np.uint64(g & 63)
            elif table and b > -2:
                if b >= 0:
                    seen_n[s, :] = seen_n[b, :]
                    seen_k[s, :] = seen_k[b, :]
                seen_n[s, g] += 1
                seen_k[s, g] = k
        lo = t_off[k]
        hi = t_off[k + 1]
        if hi > lo:
            idx = np.argsort(-V[lo:hi], kind="mergesort")
            for i in range(hi - lo):
                order[lo + i] = lo + idx[i]



# ------------------------------------------------------------------------------------ profile helpers

@njit(cache=True)
def _scan_stats(t_off, st_k, st_g, st_u, st_vf, st_n1, root_ok, cos_thr, w_steps, revisit_steps, V, bp, order,
                pref, seen_n, seen_k, seen_b):
    """The baseline kernel over the whole window with counters (same decisions, same results): returns
    [candidates read, of which past the value bound, of which within the slew, of which gain 0,
    window steps visited, skipped by cos_thr > 1, window steps with states, reads in step dk = 1,
    window steps whose top candidate passes the value bound]."""
    out = np.zeros(9, dtype=np.int64)
    bits = seen_b.shape[0] > 0
    table = (not bits) and seen_n.shape[0] > 0
    ninf = -np.inf
    for k in range(len(t_off) - 1):
        while pref[1] <= k - w_steps:
            kk = pref[1]
            if t_off[kk] < t_off[kk + 1]:
                s0 = order[t_off[kk]]
                if V[s0] > ninf and (pref[0] < 0 or V[s0] > V[pref[0]]):
                    pref[0] = s0
            pref[1] += 1
        for s in range(t_off[k], t_off[k + 1]):
            g = st_g[s]
            vf = st_vf[s]
            n1 = st_n1[s]
            best = ninf
            b = -2
            if root_ok[s]:
                best = vf
                b = -1
            p = pref[0]
            if p >= 0:
                if bits:
                    gain = _b_bit_gain(p, g, vf, seen_b)
                elif table:
                    gain = _b_table_gain(p, g, k, vf, n1, seen_n, seen_k, revisit_steps)
                else:
                    gain = _b_path_gain(p, g, k, vf, n1, st_k, st_g, bp, revisit_steps)
                if V[p] + gain > best:
                    best = V[p] + gain
                    b = p
            for dk in range(1, w_steps):
                kk = k - dk
                if kk < 0:
                    break
                out[4] += 1
                thr = cos_thr[dk]
                if thr > 1.0:
                    out[5] += 1
                    continue
                if t_off[kk] < t_off[kk + 1]:
                    out[6] += 1
                    if V[order[t_off[kk]]] + vf > best:
                        out[8] += 1
                for i in range(t_off[kk], t_off[kk + 1]):
                    q = order[i]
                    vq = V[q]
                    out[0] += 1
                    if dk == 1:
                        out[7] += 1
                    if vq + vf <= best:
                        break
                    out[1] += 1
                    dot = st_u[s, 0] * st_u[q, 0] + st_u[s, 1] * st_u[q, 1] + st_u[s, 2] * st_u[q, 2]
                    if dot < thr:
                        continue
                    out[2] += 1
                    if bits:
                        gain = _b_bit_gain(q, g, vf, seen_b)
                    elif table:
                        gain = _b_table_gain(q, g, k, vf, n1, seen_n, seen_k, revisit_steps)
                    else:
                        gain = _b_path_gain(q, g, k, vf, n1, st_k, st_g, bp, revisit_steps)
                    if gain == 0.0:
                        out[3] += 1
                    if vq + gain > best:
                        best = vq + gain
                        b = q
                    if gain >= vf:
                        break
            V[s] = best
            bp[s] = b
            if bits and b > -2:
                if b >= 0:
                    for w in range(seen_b.shape[1]):
                        seen_b[s, w] = seen_b[b, w]
                seen_b[s, g >> 6] |= np.uint64(1) << np.uint64(g & 63)
            elif table and b > -2:
                if b >= 0:
                    seen_n[s, :] = seen_n[b, :]
                    seen_k[s, :] = seen_k[b, :]
                seen_n[s, g] += 1
                seen_k[s, g] = k
        lo = t_off[k]
        hi = t_off[k + 1]
        if hi > lo:
            idx = np.argsort(-V[lo:hi], kind="mergesort")
            for i in range(hi - lo):
                order[lo + i] = lo + idx[i]
    return out


@njit(cache=True)
def _sort_only(t_off, V, order):
    T = len(t_off) - 1
    for k in range(T):
        lo = t_off[k]
        hi = t_off[k + 1]
        if hi > lo:
            idx = np.argsort(-V[lo:hi], kind="mergesort")
            for i in range(hi - lo):
                order[lo + i] = lo + idx[i]


@njit(cache=True)
def _copy_only(bp, st_g, st_k, seen_n, seen_k, seen_b):
    bits = seen_b.shape[0] > 0
    table = (not bits) and seen_n.shape[0] > 0
    for s in range(len(bp)):
        b = bp[s]
        g = st_g[s]
        if bits and b > -2:
            if b >= 0:
                for w in range(seen_b.shape[1]):
                    seen_b[s, w] = seen_b[b, w]
            seen_b[s, g >> 6] |= np.uint64(1) << np.uint64(g & 63)
        elif table and b > -2:
            if b >= 0:
                seen_n[s, :] = seen_n[b, :]
                seen_k[s, :] = seen_k[b, :]
            seen_n[s, g] += 1
            seen_k[s, g] = st_k[s]


# ---------------------------------------------------------------------------------------------- timing

def prepare(p, table_cells=None, bit_words=None) -> dict | None:
    """The kernel's inputs, built as solve_dp builds them (a copy of its set-up; None: no states)."""
    from sat_node.acs import angle_between_deg, nadir_unit
    from sat_node.scheduler import dp

    table_cells = dp.TABLE_CELLS if table_cells is None else table_cells
    bit_words = dp.BIT_WORDS if bit_words is None else bit_words
    st_k, st_g, st_u, st_vf, t_off = dp._states(p)
    S = len(st_k)
    if S == 0:
        return None
    st_n1 = (p.prior_count[st_k, st_g] + 1.0).astype(np.float64)
    t_s = p.t0_s + p.step_s * st_k
    a0 = angle_between_deg(p.init_unit[None, :], st_u)
    root_ok = p.slew.time_s(a0) <= (t_s - p.ready_t_s) + 1e-9
    nad = nadir_unit(p.sat_pos_km[st_k])
    max_off = float(np.max(np.degrees(np.arccos(np.clip(np.sum(nad * st_u, axis=1), -1, 1)))))
    w_steps = dp.slew_window_steps(p, max_off)
    amax = dp._max_angles(p.slew, p.step_s, w_steps)
    cos_thr = np.where(amax < 0, 2.0, np.cos(np.radians(np.maximum(amax - 1e-9, 0.0))))
    revisit_steps = p.revisit_zero_s / p.step_s
    words = (p.n_gp + 63) // 64
    within = (p.n_steps - 1) * p.step_s < p.revisit_zero_s
    bshape = (S, words) if within and S * words <= bit_words else (0, 0)
    shape = (S, p.n_gp) if bshape[0] == 0 and S * p.n_gp <= table_cells else (0, 0)
    return {"t_off": t_off, "st_k": st_k, "st_g": st_g, "st_u": st_u, "st_vf": st_vf, "st_n1": st_n1,
            "root_ok": root_ok, "cos_thr": cos_thr, "w_steps": w_steps, "revisit_steps": revisit_steps,
            "shape": shape, "bshape": bshape, "T": p.n_steps, "G": p.n_gp, "words": words}


def _fresh(a):
    S = len(a["st_k"])
    return (np.full(S, -np.inf), np.full(S, -2, dtype=np.int64), np.arange(S, dtype=np.int64),
            np.array([-1, 0], dtype=np.int64), np.zeros(a["shape"], dtype=np.int32),
            np.zeros(a["shape"], dtype=np.int32), np.zeros(a["bshape"], dtype=np.uint64))


def run_baseline(a, chunk_steps=64):
    """main's solve_dp loop: 64-step chunks of the baseline kernel."""
    V, bp, order, pref, seen_n, seen_k, seen_b = out = _fresh(a)
    T = a["T"]
    k = 0
    while k < T:
        k_hi = min(T, k + chunk_steps)
        _baseline_forward(k, k_hi, a["t_off"], a["st_k"], a["st_g"], a["st_u"], a["st_vf"], a["st_n1"],
                          a["root_ok"], a["cos_thr"], a["w_steps"], a["revisit_steps"], V, bp, order, pref,
                          seen_n, seen_k, seen_b)
        k = k_hi
    return out


def run_product(a, budget_s=None):
    """The product kernel, called as the product's solve_dp calls it (no budget: one call; with a
    budget: 64-step chunks)."""
    from sat_node.scheduler import dp

    V, bp, order, pref, seen_n, seen_k, seen_b = out = _fresh(a)
    dp._forward(a["T"], budget_s, time.perf_counter(), a["t_off"], a["st_k"], a["st_g"], a["st_u"], a["st_vf"],
                a["st_n1"], a["root_ok"], a["cos_thr"], a["w_steps"], a["revisit_steps"], V, bp, order, pref,
                seen_n, seen_k, seen_b)
    return out


def _best(fn, a, repeat):
    best = math.inf
    out = None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn(a)
        best = min(best, time.perf_counter() - t)
    return best, out


def time_corpus(recs: list[dict], repeat: int, profile: bool, all_modes: bool = False) -> int:
    from sat_node.scheduler import dp

    rows = []
    bad = []
    for rec in recs:
        p = _problem_from(rec["fields"])
        modes = [("", {})]
        if all_modes:
            modes += [("table", {"bit_words": 0}), ("walk", {"bit_words": 0, "table_cells": 0})]
        for label, kw in modes:
            a = prepare(p, **kw)
            if a is None:
                continue
            run_baseline(a)  # compile / warm
            run_product(a)
            tb = tp = math.inf
            ob = op = None
            for _ in range(repeat):  # interleaved, best of repeat
                t, ob = _best(run_baseline, a, 1)
                tb = min(tb, t)
                t, op = _best(run_product, a, 1)
                tp = min(tp, t)
            oc = run_product(a, budget_s=1e9)  # in 64-step chunks, as with a budget
            for o, how in ((op, "one call"), (oc, "chunked")):
                if not (np.array_equal(ob[0].view(np.int64), o[0].view(np.int64))
                        and np.array_equal(ob[1], o[1])):
                    bad.append((rec["name"], label, f"V/bp differ ({how})"))
            if label == "":
                pl = dp.solve_dp(p, *rec.get("args", ()), **rec.get("kwargs", {}))
                want = rec["plan"]
                if not (np.array_equal(pl.steps, want[0]) and np.array_equal(pl.cols, want[1])
                        and float(pl.value) == want[2]):
                    bad.append((rec["name"], label, "solve_dp plan differs from the recorded one"))
            S = len(a["st_k"])
            row = {"name": rec["name"] + (f" ({label})" if label else ""), "S": S, "T": a["T"], "G": a["G"],
                   "words": a["words"], "w": a["w_steps"],
                   "mode": "bits" if a["bshape"][0] else ("table" if a["shape"][0] else "walk"), "tb": tb, "tp": tp}
            if profile:
                sV, sbp, so, spref, ssn, ssk, ssb = _fresh(a)
                st = _scan_stats(a["t_off"], a["st_k"], a["st_g"], a["st_u"], a["st_vf"], a["st_n1"],
                                 a["root_ok"], a["cos_thr"], a["w_steps"], a["revisit_steps"], sV, sbp, so, spref,
                                 ssn, ssk, ssb)
                V, bp, order = ob[0], ob[1], ob[2]
                o2 = order.copy()
                _sort_only(a["t_off"], V, o2)
                t0 = time.perf_counter()
                _sort_only(a["t_off"], V, o2)
                ts = time.perf_counter() - t0
                _, _, _, _, sn, sk, sb = _fresh(a)
                _copy_only(bp, a["st_g"], a["st_k"], sn, sk, sb)
                _, _, _, _, sn, sk, sb = _fresh(a)
                t0 = time.perf_counter()
                _copy_only(bp, a["st_g"], a["st_k"], sn, sk, sb)
                tc = time.perf_counter() - t0
                row.update(cand=int(st[0]), bound=int(st[1]), slew=int(st[2]), zero=int(st[3]), dk=int(st[4]),
                           dk_skip=int(st[5]), dk_nonempty=int(st[6]), dk_open=int(st[8]), t_sort=ts, t_copy=tc)
            rows.append(row)
    _report(rows, profile)
    print(f"identical: {'yes' if not bad else 'NO'} ({len(rows)} instances, {len(bad)} differ)")
    for b in bad[:20]:
        print("  DIFF", *b)
    return 0 if not bad else 1


def _report(rows, profile):
    if not rows:
        print("no instances")
        return
    S = np.array([r["S"] for r in rows])
    tb = np.array([r["tb"] for r in rows])
    tp = np.array([r["tp"] for r in rows])
    print(f"{len(rows)} instances: states S median {np.median(S):.0f}, p90 {np.percentile(S, 90):.0f}, "
          f"max {S.max()}; T median {np.median([r['T'] for r in rows]):.0f}; G median "
          f"{np.median([r['G'] for r in rows]):.0f} max {max(r['G'] for r in rows)}; words median "
          f"{np.median([r['words'] for r in rows]):.0f}; w_steps {sorted({r['w'] for r in rows})}; modes "
          + ", ".join(f"{m} {sum(r['mode'] == m for r in rows)}" for m in ("bits", "table", "walk")))
    print(f"kernel total: baseline {tb.sum() * 1e3:.1f} ms ({tb.mean() * 1e3:.3f} ms/solve), "
          f"product {tp.sum() * 1e3:.1f} ms ({tp.mean() * 1e3:.3f} ms/solve), speed-up {tb.sum() / tp.sum():.2f}x")
    for m in ("bits", "table", "walk"):
        sel = [r for r in rows if r["mode"] == m]
        if sel and len(sel) < len(rows):
            b = sum(r["tb"] for r in sel)
            q = sum(r["tp"] for r in sel)
            print(f"  {m}: {len(sel)} instances, baseline {b * 1e3:.1f} ms, product {q * 1e3:.1f} ms, {b / q:.2f}x")
    big = np.argsort(-S)[:10]
    print("largest: " + "; ".join(f"S={rows[i]['S']} {rows[i]['tb'] * 1e3:.2f}->{rows[i]['tp'] * 1e3:.2f} ms"
                                  for i in big))
    if profile:
        def per(key):
            return sum(r[key] for r in rows) / S.sum()

        print(f"baseline scan per state: {per('cand'):.1f} candidates read, "
              f"{per('bound'):.1f} past the value bound, {per('slew'):.1f} within the slew, {per('zero'):.1f} of "
              f"them worth 0 (GP already on the path); {per('dk'):.1f} window steps visited, {per('dk_skip'):.1f} "
              f"skipped by cos_thr, {per('dk_nonempty'):.1f} with states, {per('dk_open'):.1f} whose top passes "
              f"the bound")
        ts = sum(r["t_sort"] for r in rows)
        tc = sum(r["t_copy"] for r in rows)
        print(f"baseline time split ({tb.sum() * 1e3:.1f} ms): argsort {ts * 1e3:.1f} ms, row copies "
              f"{tc * 1e3:.1f} ms, rest (scan, fold, call overhead) {(tb.sum() - ts - tc) * 1e3:.1f} ms")
        for m in ("bits", "table", "walk"):
            sel = [r for r in rows if r["mode"] == m]
            if sel:
                print(f"  {m}: {len(sel)} instances, baseline {sum(r['tb'] for r in sel) * 1e3:.1f} ms, copies "
                      f"{sum(r['t_copy'] for r in sel) * 1e3:.1f} ms, sort {sum(r['t_sort'] for r in sel) * 1e3:.1f} ms")


# ---------------------------------------------------------------------------------------------- capture

def _problem_fields(p) -> dict:
    return {f.name: getattr(p, f.name) for f in dataclasses.fields(p) if f.name != "_cache"}


def _problem_from(fields: dict):
    from sat_node.scheduler.problem import SchedulingProblem

    names = {f.name for f in dataclasses.fields(SchedulingProblem)}
    return SchedulingProblem(**{k: v for k, v in fields.items() if k in names})


def capture(out: Path, every: int, largest: int, run_argv: list[str]) -> int:
    import heapq

    from bringup.cli import main as cli
    from sat_node.scheduler import dp, joint, planner

    out.mkdir(parents=True, exist_ok=True)
    orig = dp.solve_dp
    state = {"n": 0, "kept": 0}
    big: list = []  # min-heap of (S, n, record) for the largest ones

    def hooked(p, *a, **kw):
        plan = orig(p, *a, **kw)
        n = state["n"]
        state["n"] += 1
        S = int(np.count_nonzero(p.v_first > 0.0))
        rec = {"fields": _problem_fields(p), "kwargs": kw, "args": a, "S": S,
               "plan": (plan.steps.copy(), plan.cols.copy(), float(plan.value)), "n": n}
        if n % every == 0:
            with gzip.open(out / f"p{n:06d}.pkl.gz", "wb", compresslevel=1) as f:
                pickle.dump(rec, f, protocol=5)
            state["kept"] += 1
        else:
            if len(big) < largest:
                heapq.heappush(big, (S, n, rec))
            elif S > big[0][0]:
                heapq.heapreplace(big, (S, n, rec))
        return plan

    dp.solve_dp = joint.solve_dp = planner.solve_dp = hooked
    try:
        code = cli.main(["run", "--engine", "local", "--no-progress", "--no-plots", *run_argv])
    finally:
        dp.solve_dp = joint.solve_dp = planner.solve_dp = orig
    for S, n, rec in big:
        with gzip.open(out / f"p{n:06d}.pkl.gz", "wb", compresslevel=1) as f:
            pickle.dump(rec, f, protocol=5)
    print(f"capture: {state['n']} solve_dp calls, kept {state['kept']} (every {every}) + {len(big)} largest "
          f"in {out}; run exit {code}")
    return 0


def load_corpus(dirs: list[str]) -> list[dict]:
    recs = []
    for d in dirs:
        for f in sorted(Path(d).glob("p*.pkl.gz")):
            with gzip.open(f, "rb") as fh:
                rec = pickle.load(fh)
            rec["name"] = f"{Path(d).name}/{f.name}"
            recs.append(rec)
    return recs


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    c = sub.add_parser("capture")
    c.add_argument("--out", required=True, type=Path)
    c.add_argument("--every", type=int, default=5)
    c.add_argument("--largest", type=int, default=40)
    t = sub.add_parser("time")
    t.add_argument("dirs", nargs="+")
    t.add_argument("--repeat", type=int, default=3)
    t.add_argument("--profile", action="store_true", help="scan counters and the time split of the baseline")
    t.add_argument("--all-modes", action="store_true",
                   help="also force the path-table and path-walk layouts (long windows' cases)")
    t.add_argument("--every", type=int, default=1, help="every n-th instance only (plus the 10 largest)")
    run_argv: list[str] = []
    if "--" in argv:
        i = argv.index("--")
        argv, run_argv = argv[:i], argv[i + 1:]
    args = ap.parse_args(argv)
    if args.cmd == "capture":
        return capture(args.out, args.every, args.largest, run_argv)
    recs = load_corpus(args.dirs)
    if args.every > 1:
        big = set(sorted(range(len(recs)), key=lambda i: -recs[i]["S"])[:10])
        recs = [r for i, r in enumerate(recs) if i % args.every == 0 or i in big]
    return time_corpus(recs, args.repeat, args.profile, args.all_modes)


if __name__ == "__main__":
    sys.exit(main())
