"""The region pass index (orbit_clock/access.py ``RegionPrefilter``) and the partner choice that asks it
(sat_node/scheduler/planner.py ``Planner.group`` with ``passes``).

Oracles: the pre-filter as first written (the angle test on the samples of one interval, computed
here again from the ephemeris), per-satellite ``candidate_gp_ids`` for ``passing``, the exact FOR
mask on a 1-s grid for the bound ``first_pass_s`` gives, and the partner choice partner by partner
(a planner without ``passes``: every partner looked at, the full sort) for the one that asks the
index: the same partners with the same instances, bounded and unbounded.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from bringup.scenario.world import OrbitContext
from orbit_clock import build_constellation, ground_points
from orbit_clock.access import RegionPrefilter, for_central_angle_rad, for_mask
from orbit_clock.frames import WGS84_B_KM
from sat_node.scheduler import Knowledge, PersistenceView, Planner


@pytest.fixture(scope="module")
def paper(paper_scenario):
    sc = paper_scenario.with_overrides(hours=2)
    c = build_constellation(sc)
    g = ground_points(sc)
    return c, g, RegionPrefilter(c, g, sc.scenario.horizon_s, 55.0)


def _first_written(c, g, horizon_s, for_deg, step_s, sat, t0_s, t1_s) -> np.ndarray:
    """The pre-filter's GP ids as first written: the angle test on the interval's samples alone."""
    t = np.arange(0.0, horizon_s + step_s, step_s)
    pos = c.positions_ecef_km(t)
    r = np.linalg.norm(pos, axis=2)
    unit = pos / r[..., None]
    n_reg = len(g.region_names)
    region_gps = [np.flatnonzero(g.region_index == k).astype(np.int64) for k in range(n_reg)]
    region_unit, half = np.zeros((n_reg, 3)), np.zeros(n_reg)
    for k in range(n_reg):
        pts = g.ecef_km[region_gps[k]]
        ctr = pts.mean(axis=0)
        ctr /= np.linalg.norm(ctr)
        region_unit[k] = ctr
        gu = pts / np.linalg.norm(pts, axis=1, keepdims=True)
        half[k] = float(np.max(np.arccos(np.clip(gu @ ctr, -1, 1))))
    lim = for_central_angle_rad(float(r.max()), WGS84_B_KM, for_deg) + half + 8.0 * step_s / WGS84_B_KM \
        + math.radians(1.0)
    i = c.index(sat)
    k0 = max(0, math.floor(t0_s / step_s))
    k1 = min(unit.shape[1] - 1, math.ceil(t1_s / step_s))
    u = unit[i, k0:k1 + 1]
    keep = np.flatnonzero(((u @ region_unit.T) >= np.cos(np.minimum(lim, math.pi))[None, :]).any(axis=0))
    return np.concatenate([region_gps[r] for r in keep]) if len(keep) else np.zeros(0, np.int64)


def test_the_index_keeps_what_the_angle_test_on_the_interval_keeps(paper):
    c, g, pf = paper
    rng = np.random.default_rng(7)
    kept = empty = 0
    for _ in range(300):
        sat = c.names[int(rng.integers(len(c)))]
        t0 = float(rng.uniform(0.0, pf.horizon_s + 100.0))  # (before 0 the slice below would wrap)
        t1 = t0 + float(rng.choice([0.0, 10.0, 600.0, 900.0, 3000.0]))
        got = pf.candidate_gp_ids(sat, t0, t1)
        ref = _first_written(c, g, pf.horizon_s, 55.0, 30.0, sat, t0, t1)
        assert np.array_equal(got, ref), (sat, t0, t1)
        kept += len(got) > 0
        empty += len(got) == 0
    assert kept > 20 and empty > 20  # both answers are exercised


def test_an_index_of_more_than_65535_samples_keeps_the_same(paper):
    """Past 65535 samples the counts are 4 bytes wide (here 2 h at 0.1 s: 72001 samples)."""
    c, g, _pf = paper
    pf = RegionPrefilter(c, g, 7200.0, 55.0, step_s=0.1)
    assert pf.candidate_gp_ids(c.names[0], 0.0, 1.0) is not None and pf._coarse["passes"].dtype == np.uint32
    for sat, t0, t1 in ((c.names[0], 0.0, 7200.0), (c.names[5], 3000.0, 3600.0), (c.names[9], 7000.0, 7300.0)):
        assert np.array_equal(pf.candidate_gp_ids(sat, t0, t1), _first_written(c, g, 7200.0, 55.0, 0.1, sat, t0, t1))


def test_passing_is_the_candidates_holding_one_of_the_gps(paper):
    c, g, pf = paper
    rng = np.random.default_rng(11)
    yes = no = 0
    for _ in range(60):
        n = int(rng.integers(1, 40))
        gp_ids = rng.choice(len(g.ecef_km), size=n, replace=False)
        sats = rng.permutation(len(c))[: int(rng.integers(1, len(c) + 1))]
        t1 = float(rng.uniform(0.0, pf.horizon_s + 60.0))
        starts = t1 - rng.uniform(0.0, 1500.0, size=len(sats))
        got = pf.passing(gp_ids, sats, starts, t1)
        mine = set(gp_ids.tolist())
        ref = [bool(mine.intersection(pf.candidate_gp_ids(c.names[s], float(t0), t1).tolist()))
               for s, t0 in zip(sats, starts)]
        assert got.tolist() == ref
        yes += sum(ref)
        no += len(ref) - sum(ref)
    assert yes > 50 and no > 50
    assert not pf.passing(gp_ids, sats, np.full(len(sats), t1 + 40.0), t1).any()  # empty intervals
    assert pf.passing(np.zeros(0, np.int64), np.arange(3), np.zeros(3), 600.0).tolist() == [False] * 3


def test_the_first_pass_less_a_step_bounds_the_first_time_in_the_for(paper):
    """Oracle: the exact FOR mask over the GPs on a 1-s grid from the interval's start; where the
    satellite does not pass their regions, the mask never holds them."""
    c, g, pf = paper
    rng = np.random.default_rng(5)
    bounded = 0
    for _ in range(40):
        gp_ids = np.sort(rng.choice(len(g.ecef_km), size=int(rng.integers(1, 30)), replace=False))
        sats = rng.permutation(len(c))[:6]
        t0 = float(rng.uniform(0.0, pf.horizon_s - 1500.0))
        starts = t0 + rng.uniform(0.0, 300.0, size=len(sats))
        t1 = t0 + 1200.0
        first = pf.first_pass_s(gp_ids, sats, starts, t1)
        assert np.isfinite(first).tolist() == pf.passing(gp_ids, sats, starts, t1).tolist()
        for s, t_start, f in zip(sats, starts, first):
            t = np.arange(t_start, t1, 1.0)
            seen = np.flatnonzero(for_mask(c.track_ecef_km(int(s), t), g.ecef_km[gp_ids], 55.0).any(axis=1))
            if len(seen):
                assert f - pf.step_s <= t[seen[0]], (s, t_start)
                assert f <= t1 and f >= math.floor(t_start / pf.step_s) * pf.step_s
                bounded += 1
    assert bounded > 10


@pytest.fixture(scope="module")
def dense(paper_scenario):
    sc = paper_scenario.with_overrides(sats=96, hours=1)
    ctx = OrbitContext.from_scenario(sc)
    planner = ctx.planner()
    assert planner.passes is not None  # the scenario's planner asks the index
    return ctx, planner


def _by_satellite(planner: Planner, k: int) -> Planner:
    return Planner(planner.constellation, planner.gp_ecef_km, planner.slew,
                   dataclasses.replace(planner.settings, joint_max_partners=k), candidates=planner.candidates)


def _with_index(planner: Planner, k: int) -> Planner:
    return Planner(planner.constellation, planner.gp_ecef_km, planner.slew,
                   dataclasses.replace(planner.settings, joint_max_partners=k), candidates=planner.candidates,
                   passes=planner.passes)


@pytest.mark.parametrize("k", [0, 1, 2])
def test_the_partner_choice_with_the_index_is_the_one_satellite_by_satellite(dense, k):
    """Every 4th satellite, every 5 min over the first 50 min, onboard (every satellite free now)
    and from the ground (partners free at staggered times): the same partners, the same instances."""
    ctx, planner = dense
    a, b = _with_index(planner, k), _by_satellite(planner, k)
    groups = members = 0
    names = planner.constellation.names
    for sat in names[::4]:
        for t0 in np.arange(0.0, 3000.0, 300.0):
            know = Knowledge(PersistenceView(ctx.osse, float(t0)))
            ids = planner.candidates(sat, t0, t0 + 600.0)
            if len(ids) == 0:
                continue
            mine = planner.instance(sat, t0, know, window_s=600.0, gp_ids=ids)
            for partners in (None, [(n, float(t0) + 120.0 * (j % 6)) for j, n in enumerate(names) if n != sat]):
                ga = a.group(sat, float(t0), 600.0, know, mine, partners)
                gb = b.group(sat, float(t0), 600.0, know, mine, partners)
                assert [q.sat_name for q in ga] == [q.sat_name for q in gb]
                for qa, qb in zip(ga, gb):
                    assert qa.t0_s == qb.t0_s
                    assert np.array_equal(qa.gp_ids, qb.gp_ids) and np.array_equal(qa.in_for, qb.in_for)
                    assert np.array_equal(qa.absval, qb.absval)
                groups += len(ga) > 0
                members += len(ga)
    assert groups > 10 and (k == 1 or members > groups)  # groups were formed, some of several partners
