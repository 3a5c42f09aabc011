"""Inter-satellite link (ISL) line of sight and the ISL contact plan.

Model (Nag et al. 2019, section 4; docs/design.md sections 1 and 5): two satellites are in contact while
(a) the segment between them clears the Earth by the grazing height (default 80 km: the atmosphere
below is taken as opaque) and (b) their range is at most the radio's maximum range (default
6000 km). The Earth is the WGS-84 ellipsoid: coordinates are scaled by a/b along z, which maps the
ellipsoid onto the sphere of radius a, and the segment must clear the sphere of radius a + h there
(the scaling stretches heights by at most a/b - 1 = 0.34 %, i.e. 0.3 km at 80 km).

Windows are found on a coarse grid (default 10 s) and each edge is refined by bisection with SGP4
to ``tol_s`` (default 1 ms, orbit_clock.windows); a window shorter than the coarse step can be missed (bench/bench_orbit.py
compares with a 1 s brute-force grid). Only the pairs and times that can be within range are
sampled: a k-d tree (scipy) finds, every 6 grid samples, the pairs within range plus how far two
satellites can close in half that span; the other samples are out of range (their margin is
negative), so the runs are those of the full grid. The work grows with the pairs near each other
(physics: a fixed fraction of the constellation in view of each satellite), not with all pairs
at all times; ``prune=False`` samples everything (the oracle of the fast path). Each window becomes two directed contacts (A->B, B->A) with
rate ``scenario.isl.rate_bps`` and ``range_light_s`` = the mean range over the window (21 samples,
evenly spaced, ends included) divided by c. CGR takes range constant over a contact, so the mean is
used; in-plane neighbours of the paper's constellation keep a near-constant 5.43e3 km, cross-plane
ranges sweep from the 6000 km limit down to a few hundred km and back.

A mixed fleet (bringup/scenario/fleet.py) may give each satellite its own radio: the scenario's
``sat_params`` (isl_rate_bps, isl_max_range_km, in constellation order). A link then closes at the
shorter maximum range of its two ends and runs at the lower rate (both ends must hear each other:
the weaker radio sets the link). The k-d tree pruning bounds with the longest range.

How we know it is right (tests/unit/test_orbit_isl.py): ``los_clear`` against an independent
segment-sphere intersection (quadratic roots) on random geometry (hypothesis); windows against a 1 s
brute-force grid; symmetry (A->B and B->A identical); hand cases (antipodal satellites blocked,
in-plane neighbours of the paper constellation in contact the whole horizon).
tests/unit/test_scale_plans.py: the plans of 96 and 240 satellites against a brute-force line of
sight at random instants; tests/unit/test_speed_paths.py: the pruned search equals the full one;
tests/unit/test_fleet.py: with one range per satellite each pair's windows equal those of the pair's
shorter range alone, and every contact runs at the lower rate of its two ends.
"""

from __future__ import annotations

from itertools import pairwise

import numpy as np

from orbit_clock.contact_plan import Contact, ContactPlan
from orbit_clock.frames import C_KM_S, WGS84_A_KM, WGS84_B_KM
from orbit_clock.propagation import Constellation, build_constellation
from orbit_clock.windows import (
    mean_range_km,
    refine_runs,
    refine_runs_split,
    time_grid,
    true_runs,
    windows_from_margin,
)

__all__ = [
    "isl_contact_plan",
    "isl_windows",
    "los_clear",
    "los_clearance_km",
]

_Z_SCALE = WGS84_A_KM / WGS84_B_KM


def los_clearance_km(p1_km: np.ndarray, p2_km: np.ndarray, grazing_height_km: float = 80.0) -> np.ndarray:
    """Closest approach of the segment p1-p2 to the Earth minus (a + grazing height) [km], in the
    ellipsoid-to-sphere scaled frame; > 0 means line of sight. Broadcasts over leading axes."""
    s = np.array([1.0, 1.0, _Z_SCALE])
    a = np.asarray(p1_km, dtype=float) * s
    b = np.asarray(p2_km, dtype=float) * s
    d = b - a
    dd = np.einsum("...k,...k->...", d, d)
    u = np.clip(-np.einsum("...k,...k->...", a, d) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)
    closest = a + u[..., None] * d
    return np.linalg.norm(closest, axis=-1) - (WGS84_A_KM + grazing_height_km)


def los_clear(p1_km, p2_km, grazing_height_km: float = 80.0) -> np.ndarray:
    """True where the segment clears the Earth + grazing height."""
    return los_clearance_km(p1_km, p2_km, grazing_height_km) > 0.0


def isl_windows(constellation: Constellation, t0_s: float, t1_s: float, *, grazing_height_km: float = 80.0,
                max_range_km=6000.0, step_s: float = 10.0, tol_s: float = 1e-3, refine: bool = True,
                prune: bool = True, workers: int = 1):
    """Undirected ISL windows: (i, j, start_s, end_s) arrays with i < j satellite indices, ordered by
    pair (i, then j), then time. ``max_range_km``: one range [km] or one per satellite (a pair's is
    the shorter of its two).

    ``refine=False`` gives the bare grid (edges at the samples): the brute-force reference.
    ``prune`` (with ``refine``): sample only the pairs and times that can be within ``max_range_km``
    (:func:`_candidate_segments`); the same windows as ``prune=False``, which samples every pair at
    every grid time (tests/unit/test_speed_paths.py compares the two). ``workers`` > 1: the pruned
    search's edges are bisected in that many processes side by side
    (orbit_clock.windows.refine_runs_split: the same numbers).
    """
    n = len(constellation)
    I, J = np.triu_indices(n, k=1)
    t = time_grid(t0_s, t1_s, step_s)
    r = constellation.positions_ecef_km(t)
    rng = np.asarray(max_range_km, dtype=float)
    if rng.ndim:
        if rng.shape != (n,):
            raise ValueError(f"isl_windows: max_range_km must be one range or one per satellite ({n}), got {rng.shape}")
        pair_rng = np.minimum(rng[I], rng[J])
        longest = float(rng.max()) if n else 0.0
    else:
        pair_rng = longest = float(rng)

    def pair_range(idx):
        return pair_rng if np.ndim(pair_rng) == 0 else pair_rng[idx]

    def margin_at(idx, tt):
        a = constellation.positions_ecef_km_at(I[idx], tt)
        b = constellation.positions_ecef_km_at(J[idx], tt)
        return np.minimum(los_clearance_km(a, b, grazing_height_km), pair_range(idx) - np.linalg.norm(a - b, axis=-1))

    if refine and prune and I.size:
        segs = _candidate_segments(constellation, t, r, longest)
        if segs is not None:
            si, ks, ke = _runs_in_segments(r, I, J, *segs, grazing_height_km, pair_rng)
            if workers > 1 and si.size >= _SPLIT_MIN_RUNS:
                st, en = refine_runs_split(t, si, ks, ke, margin_at, tol_s, workers)
            else:
                st, en = refine_runs(t, si, ks, ke, margin_at, tol_s)
            return I[si], J[si], st, en
    margin = np.empty((I.size, t.size))
    chunk = max(1, 4_000_000 // max(1, I.size))
    for c0 in range(0, t.size, chunk):
        a, b = r[I, c0:c0 + chunk], r[J, c0:c0 + chunk]
        margin[:, c0:c0 + chunk] = _margin(a, b, grazing_height_km,
                                           pair_rng if np.ndim(pair_rng) == 0 else pair_rng[:, None])
    if refine:
        k, st, en = windows_from_margin(t, margin, margin_at, tol_s)
    else:
        k, st, en = windows_from_margin(t, margin, margin_at, tol_s=np.inf)
        # without refinement take the grid samples themselves (first/last inside sample)
        _, ks, ke = true_runs(margin > 0)
        st, en = t[ks], t[ke - 1]
    return I[k], J[k], st, en


def _margin(a: np.ndarray, b: np.ndarray, grazing_height_km: float, max_range_km: float) -> np.ndarray:
    """min(line-of-sight clearance, max range - range) [km] of position pairs a, b (..., 3)."""
    rng = np.linalg.norm(a - b, axis=-1)
    return np.minimum(los_clearance_km(a, b, grazing_height_km), max_range_km - rng)


# ISL windows per block of the mean-range computation (isl_contact_plan)
_MEAN_BLOCK = 50_000

# Runs below which the edges are bisected in one process whatever ``workers`` says (a fork costs
# more than a few thousand edges)
_SPLIT_MIN_RUNS = 20_000

# Grid samples per pruning block: the pair distance is looked up at every _BLOCK-th sample
_BLOCK = 6


def _candidate_segments(constellation: Constellation, t: np.ndarray, r: np.ndarray, max_range_km: float):
    """Spans of grid samples where a pair can be within ``max_range_km``: (pair, first, last) int
    arrays, pair = index into ``np.triu_indices(n, 1)``, samples first..last inclusive; None when
    pruning cannot drop anything (an unbounded range).

    The grid is cut into blocks of ``_BLOCK`` samples. A pair within range at some time of a block
    is, at the nearer of the block's two end samples, within range + v_rel * (half the block's
    span), where v_rel bounds how fast a distance between two satellites changes: twice the largest
    Earth-fixed speed at those samples (SGP4 velocities) plus 10 %, plus 0.5 km/s. The pairs that
    close at each end sample come from a k-d tree (scipy ``cKDTree.query_pairs``), so the work grows
    with the pairs near each other, not with all pairs. A block is a candidate for a pair found at
    either of its ends; consecutive candidate blocks form one span. Samples outside the spans are out
    of range, so their margin is negative: the runs of positive margin are those of the spans.
    """
    n, n_t = r.shape[0], t.size
    ends = np.unique(np.append(np.arange(0, n_t, _BLOCK), n_t - 1))  # block b: samples ends[b]..ends[b+1]
    n_blocks = ends.size - 1
    if n_blocks < 1 or not np.isfinite(max_range_km):
        return None
    _r, v = constellation.states_ecef(t[ends])
    v_rel = 2.0 * float(np.max(np.linalg.norm(v, axis=-1))) * 1.1 + 0.5
    half_span_s = 0.5 * float(np.max(np.diff(t[ends])))
    reach = max_range_km + v_rel * half_span_s
    if reach >= 2.0 * float(np.max(np.linalg.norm(r[:, ends], axis=-1))):
        return None  # every pair is always a candidate
    # imported here: the processes that never compute ISL windows (a ROS run's nodes) skip scipy.spatial
    from scipy.spatial import cKDTree

    cand = np.zeros((n * (n - 1) // 2, n_blocks), dtype=bool)
    for k, e in enumerate(ends):
        ij = cKDTree(r[:, e, :]).query_pairs(reach, output_type="ndarray")
        if ij.size == 0:
            continue
        i, j = ij.min(axis=1).astype(np.int64), ij.max(axis=1).astype(np.int64)
        p = i * n - i * (i + 1) // 2 + (j - i - 1)
        if k < n_blocks:
            cand[p, k] = True
        if k > 0:
            cand[p, k - 1] = True
    pair, b0, b1 = true_runs(cand)  # spans of candidate blocks b0 .. b1 - 1
    return pair, ends[b0], ends[b1]


def _runs_in_segments(r: np.ndarray, I: np.ndarray, J: np.ndarray, pair: np.ndarray, first: np.ndarray,
                      last: np.ndarray, grazing_height_km: float, max_range_km):
    """Runs of positive margin (pair, first inside sample, sample after) of the spans of
    :func:`_candidate_segments`, as :func:`orbit_clock.windows.true_runs` gives them on the full
    grid (ordered by pair, then time); ``max_range_km`` one range or one per pair. The samples are
    evaluated one by one by a compiled loop (orbit_clock/isl_kernels.py), which holds no array of
    their number."""
    from orbit_clock.isl_kernels import runs_in_segments

    lim = np.broadcast_to(np.asarray(max_range_km, dtype=float), I.shape)
    si, ks, ke = runs_in_segments(np.ascontiguousarray(r, dtype=float), I.astype(np.int64), J.astype(np.int64),
                                  pair.astype(np.int64), first.astype(np.int64), last.astype(np.int64),
                                  float(_Z_SCALE), float(WGS84_A_KM + grazing_height_km), np.ascontiguousarray(lim))
    order = np.lexsort((ks, si))
    return si[order], ks[order], ke[order]


def isl_contact_plan(scenario, constellation: Constellation | None = None, *, step_s: float = 10.0,
                     tol_s: float = 1e-3, workers: int = 1) -> ContactPlan:
    """Directed ISL contacts (both ways) over the scenario horizon; see the module docstring.
    ``workers`` > 1: the edges' bisection and the mean ranges (SGP4 at scattered points, point by
    point) run in that many processes side by side, the same numbers as one
    (tests/unit/test_isl_split.py)."""
    c = constellation or build_constellation(scenario)
    isl = scenario.isl
    per = getattr(scenario, "sat_params", None)  # one radio per satellite (module docstring)
    rates = np.array([p.isl_rate_bps for p in per]) if per else np.full(len(c), float(isl.rate_bps))
    ranges = np.array([p.isl_max_range_km for p in per]) if per else np.full(len(c), float(isl.max_range_km))
    uniform = bool(len(c)) and (ranges == ranges[0]).all()
    i, j, st, en = isl_windows(c, 0.0, float(scenario.scenario.horizon_s), grazing_height_km=isl.grazing_height_km,
                               max_range_km=float(ranges[0]) if uniform else ranges, step_s=step_s, tol_s=tol_s,
                               workers=workers)
    keep = en > st
    i, j, st, en = i[keep], j[keep], st[keep], en[keep]
    n = 21  # range samples per window, ends included
    # in blocks of windows (each window's mean is its own: the same numbers), so that the sample
    # arrays stay small (2.3 M windows at 1000 satellites x 6 h: 4.7e7 positions at once otherwise)
    def light_times(blocks: range) -> np.ndarray:
        out = []
        for k0 in blocks:
            b = slice(k0, k0 + _MEAN_BLOCK)
            ib, jb = i[b], j[b]
            out.append(mean_range_km(lambda t, ib=ib: c.positions_ecef_km_at(np.repeat(ib, n), t),
                                     lambda t, jb=jb: c.positions_ecef_km_at(np.repeat(jb, n), t),
                                     st[b], en[b], n) / C_KM_S)
        return np.concatenate(out) if out else np.empty(0)

    # the same blocks in one process or cut into consecutive runs of blocks, one per process
    blocks = range(0, st.size, _MEAN_BLOCK)
    if workers > 1 and len(blocks) > 1:
        from orbit_clock.fork_split import run_parts

        cuts = np.linspace(0, len(blocks), min(workers, len(blocks)) + 1).round().astype(int)
        light_s = np.concatenate(run_parts(light_times, [blocks[a:b] for a, b in pairwise(cuts)],
                                           workers=workers))
    else:
        light_s = light_times(blocks)
    contacts = []
    for a, b, s0, s1, lt in zip(i, j, st, en, light_s):
        na, nb = c.names[a], c.names[b]
        s0, s1 = round(float(s0), 3), round(float(s1), 3)
        rate = float(min(rates[a], rates[b]))
        contacts.append(Contact(s0, s1, na, nb, rate, float(lt)))
        contacts.append(Contact(s0, s1, nb, na, rate, float(lt)))
    return ContactPlan(contacts)
