"""Eq. 1 value, belief noise and known-observation prior state (sat_node.value)."""

import subprocess
import sys

import numpy as np
import pytest

from sat_node.value import Belief, KnownLog, KnownObservation, ValueLedger, belief_sigma, prior_state, true_value


def _scalar_eq1(absval, t, last, n, rz):
    if last is not None and t - last < rz:
        return 0.0
    return absval / (n + 1)


def test_eq1_against_scalar_loop():
    rng = np.random.default_rng(5)
    absval = rng.integers(1, 257, 400).astype(float)
    t = rng.uniform(0, 21600, 400)
    seen = rng.random(400) < 0.6
    last = np.where(seen, t - rng.uniform(0, 3000, 400), -np.inf)
    n = np.where(seen, rng.integers(1, 5, 400), 0)
    got = true_value(absval, t, last, n, 900.0)
    ref = [_scalar_eq1(a, tt, (la if s else None), nn, 900.0) for a, tt, la, s, nn in zip(absval, t, last, seen, n)]
    np.testing.assert_allclose(got, ref)


def test_revisit_boundary():
    assert true_value(100, 899.999, 0.0, 1, 900.0) == 0.0
    assert true_value(100, 900.0, 0.0, 1, 900.0) == 50.0
    assert true_value(100, 5.0, -np.inf, 0, 900.0) == 100.0


def test_negative_count_refused():
    with pytest.raises(ValueError, match="times_seen"):
        true_value(1.0, 0.0, -np.inf, -1, 900.0)


def test_belief_reproducible_and_distinct():
    a = Belief(seed=1, sat_name="sat_11", n_gp=50, n_slots=24)
    b = Belief(seed=1, sat_name="sat_11", n_gp=50, n_slots=24)
    c = Belief(seed=1, sat_name="sat_12", n_gp=50, n_slots=24)
    d = Belief(seed=2, sat_name="sat_11", n_gp=50, n_slots=24)
    assert a.sigma == b.sigma and np.array_equal(a.z, b.z)
    assert a.sigma != c.sigma and not np.array_equal(a.z, c.z)
    assert a.sigma != d.sigma
    assert 0.02 <= a.sigma <= 0.08 and 0.02 <= c.sigma <= 0.08
    assert belief_sigma(1, "sat_11", 0.02, 0.08) == a.sigma


def test_belief_same_in_another_process():
    code = ("from sat_node.value import Belief; b = Belief(seed=7, sat_name='sat_23', n_gp=4, n_slots=3);"
            "print(repr(b.sigma), repr(float(b.z.sum())))")
    out = [subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
           for _ in range(2)]
    b = Belief(seed=7, sat_name="sat_23", n_gp=4, n_slots=3)
    assert out[0] == out[1] == f"{b.sigma!r} {float(b.z.sum())!r}\n"


def test_belief_noise_statistics():
    b = Belief(seed=3, sat_name="sat_31", n_gp=500, n_slots=24, sigma_min=0.02, sigma_max=0.08)
    true = np.full((500, 24), 100.0)
    gp, slot = np.meshgrid(np.arange(500), np.arange(24), indexing="ij")
    rel = b.absval(true, gp, slot) / 100.0 - 1.0
    n = rel.size
    assert abs(rel.std() - b.sigma) < 3 * b.sigma / np.sqrt(2 * n)
    assert abs(rel.mean()) < 3 * b.sigma / np.sqrt(n)


def test_belief_index_errors():
    b = Belief(seed=1, sat_name="x", n_gp=3, n_slots=2)
    with pytest.raises(IndexError, match="GP index"):
        b.factor(3, 0)
    with pytest.raises(IndexError, match="slot"):
        b.factor(0, 2)
    with pytest.raises(ValueError, match="sigma_min"):
        Belief(seed=1, sat_name="x", n_gp=1, n_slots=1, sigma_min=0.1, sigma_max=0.05)


def test_prior_state_counts_and_tie_break():
    known = [KnownObservation(100.0, 7, "sat_12"), KnownObservation(1200.0, 7, "sat_31"),
             KnownObservation(50.0, 9, "sat_22")]
    times = np.array([0.0, 100.0, 101.0, 999.0, 1000.0, 1200.0, 1201.0])
    # me = sat_21: sat_12 at the same time wins (sorts first); sat_31 at the same time does not
    count, recent = prior_state(known, np.array([7, 8]), times, "sat_21", 900.0)
    assert count[:, 0].tolist() == [0, 1, 1, 1, 1, 1, 2]
    assert recent[:, 0].tolist() == [False, True, True, True, False, False, True]
    assert not count[:, 1].any() and not recent[:, 1].any()
    # me = sat_11 sorts before sat_12: the same-time claim is not before mine
    count2, _ = prior_state(known, np.array([7]), times, "sat_11", 900.0)
    assert count2[1, 0] == 0 and count2[2, 0] == 1


def _prior_state_pairwise(known, gp_ids, times_s, me, revisit_zero_s):
    """The definition, one (time, observation) comparison at a time per GP column (the oracle)."""
    gp_ids = np.asarray(gp_ids, dtype=np.int64)
    times_s = np.asarray(times_s, dtype=np.float64)
    count = np.zeros((len(times_s), len(gp_ids)), dtype=np.int64)
    recent = np.zeros((len(times_s), len(gp_ids)), dtype=bool)
    col = {int(g): j for j, g in enumerate(gp_ids)}
    by_col = {}
    for ob in known:
        j = col.get(int(ob.gp))
        if j is None or (ob.planned and ob.source >= me):
            continue
        by_col.setdefault(j, []).append((float(ob.t_s), ob.source <= me, bool(ob.planned)))
    for j, obs in by_col.items():
        ts = np.array([o[0] for o in obs])
        wins = np.array([o[1] for o in obs])
        planned = np.array([o[2] for o in obs])
        before = (ts[None, :] < times_s[:, None]) | ((ts[None, :] == times_s[:, None]) & wins[None, :])
        count[:, j] = before.sum(axis=1)
        rec = before & ((times_s[:, None] - ts[None, :]) < revisit_zero_s)
        rec |= planned[None, :] & (np.abs(times_s[:, None] - ts[None, :]) < revisit_zero_s)
        recent[:, j] = rec.any(axis=1)
    return count, recent


def test_prior_state_equals_pairwise_definition():
    """Random histories on the DP's grid and on unsorted, repeated times, with observations exactly at
    grid times and at grid times +- revisit_zero_s (the boundaries), all source ranks, plans and GPs
    outside the instance: the run-based prior_state gives the pairwise definition's arrays, from a
    plain list and from a KnownLog that grows between calls."""
    rng = np.random.default_rng(11)
    sats = ["sat_11", "sat_12", "sat_21", "sat_22", "sat_31"]
    for trial in range(60):
        rz = [900.0, 0.0, 899.999, 37.5][trial % 4]
        t0 = float(rng.uniform(0, 20000))
        step = float(rng.choice([10.0, 3.0, 0.1]))
        times = t0 + step * np.arange(int(rng.integers(1, 120)))
        if trial % 3 == 1:
            times = rng.permutation(np.concatenate([times, times[: len(times) // 3]]))
        gp_ids = rng.choice(60, size=int(rng.integers(1, 12)), replace=False)
        known = []
        for _ in range(int(rng.integers(0, 80))):
            kind = rng.integers(4)
            base = float(rng.choice(times))
            t = {0: base, 1: base - rz, 2: base + rz, 3: float(rng.uniform(t0 - 2000, t0 + 2000))}[int(kind)]
            known.append(KnownObservation(t, int(rng.integers(0, 70)), str(rng.choice(sats)),
                                          planned=bool(rng.integers(2))))
        me = str(rng.choice(sats))
        c, r = prior_state(known, gp_ids, times, me, rz)
        c0, r0 = _prior_state_pairwise(known, gp_ids, times, me, rz)
        assert c.dtype == c0.dtype and r.dtype == r0.dtype
        assert np.array_equal(c, c0) and np.array_equal(r, r0), trial
        # the same history as a KnownLog grown in three appends (its columns extended, not rebuilt)
        log = KnownLog()
        for part in (known[: len(known) // 3], known[len(known) // 3: len(known) // 2], known[len(known) // 2:]):
            log.extend(part)
            cl, rl = prior_state(log, gp_ids, times, me, rz)
            cp, rp = _prior_state_pairwise(list(log), gp_ids, times, me, rz)
            assert np.array_equal(cl, cp) and np.array_equal(rl, rp), trial
        if len(log) > 1:  # a change other than an append: the columns follow it
            log[0] = KnownObservation(float(times[0]) - 1.0, int(gp_ids[0]), "sat_00")
            del log[-1]
            cl, rl = prior_state(log, gp_ids, times, me, rz)
            cp, rp = _prior_state_pairwise(list(log), gp_ids, times, me, rz)
            assert np.array_equal(cl, cp) and np.array_equal(rl, rp), trial
    c, r = prior_state([], np.array([1, 2]), np.array([0.0, 1.0]), "sat_11", 900.0)
    assert c.shape == r.shape == (2, 2) and not c.any() and not r.any()
    with pytest.raises(ValueError, match="GP ids must be >= 0"):
        prior_state([KnownObservation(1.0, 3, "sat_11")], np.array([-1, 0]), np.array([0.0]), "sat_12", 900.0)


def test_value_ledger_equals_eq1_on_each_history():
    """One observation at a time, in time order: each one's value is Eq. 1 (true_value) on the
    history of its GP before it; the total is their sum."""
    rng = np.random.default_rng(7)
    for _ in range(20):
        n = 200
        gps = rng.integers(0, 6, n)
        t_ns = np.sort(rng.integers(0, 4 * 3600, n)) * 1_000_000_000  # whole seconds: exact boundaries too
        vals = rng.integers(1, 257, n).astype(float)
        ledger = ValueLedger(900.0)
        total = 0.0
        for i in range(n):
            before = [j for j in range(i) if gps[j] == gps[i]]
            last = t_ns[before[-1]] / 1e9 if before else -np.inf
            want = float(true_value(vals[i], t_ns[i] / 1e9, last, len(before), 900.0))
            got, recent = ledger.add(int(gps[i]), int(t_ns[i]), float(vals[i]))
            assert got == want and recent == (want == 0.0)
            total += want
        assert ledger.total == total


def _runs_numpy(cols, lo, hi, T, G):
    """(T, G) number of runs [lo, hi) of column ``cols`` covering each time: numpy's difference array."""
    diff = np.bincount(lo * G + cols, minlength=(T + 1) * G) - np.bincount(hi * G + cols, minlength=(T + 1) * G)
    return np.cumsum(diff.reshape(T + 1, G)[:T], axis=0)


def test_prior_runs_equals_difference_arrays():
    """The compiled runs (sat_node/value_kernels.py) against numpy's bincount and cumsum: random runs,
    empty ones (lo == hi), runs from 0 and to the end (T), columns hit many times or never."""
    from sat_node.value_kernels import prior_runs

    rng = np.random.default_rng(5)
    for _ in range(200):
        T, G, n = int(rng.integers(1, 40)), int(rng.integers(1, 12)), int(rng.integers(0, 60))
        cols = rng.integers(0, G, n)
        start = rng.integers(0, T + 1, n)
        lo = rng.integers(0, T + 1, n)
        hi = np.maximum(lo, rng.integers(0, T + 1, n))
        count, recent = prior_runs(cols, start, lo, hi, T, G)
        assert count.dtype == np.int64 and recent.dtype == np.bool_
        assert np.array_equal(count, _runs_numpy(cols, start, np.full(n, T), T, G))
        assert np.array_equal(recent, _runs_numpy(cols, lo, hi, T, G) > 0)
