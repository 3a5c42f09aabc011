"""The optional spatial-diversity term (sat_node/diversity.py): the factor by hand, and its wiring
into the planner's instance and plans (sat_node/scheduler/planner.py)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from bringup.scenario.world import World
from sat_node.diversity import diversity_factor, recent_observed_gps
from sat_node.scheduler.planner import Knowledge, PersistenceView, Planner
from sat_node.value import KnownObservation


def test_factor_by_hand():
    gp = np.array([[0.0, 0.0, 0.0], [8.0, 0.0, 0.0], [0.0, 30.0, 40.0]])
    rec = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    got = diversity_factor(gp, rec, weight=2.0, length_km=10.0)
    # distances to the nearest recent look: 0, 8, sqrt(30^2 + 39^2)
    want = [1.0, 1.0 + 2.0 * (1 - math.exp(-0.8)), 1.0 + 2.0 * (1 - math.exp(-math.hypot(30.0, 39.0) / 10.0))]
    np.testing.assert_allclose(got, want, rtol=1e-12)
    np.testing.assert_array_equal(diversity_factor(gp, np.zeros((0, 3)), 0.5, 10.0), [1.5] * 3)
    with pytest.raises(ValueError, match="spatial diversity"):
        diversity_factor(gp, rec, -1.0, 10.0)


def test_recent_observed_gps_takes_executed_looks_in_the_window():
    known = [KnownObservation(100.0, 5, "a"), KnownObservation(3000.0, 6, "b"), KnownObservation(3500.0, 7, "c", planned=True),
             KnownObservation(3600.0, 8, "a"), KnownObservation(3601.0, 9, "a"), KnownObservation(3000.0, 6, "c")]
    assert recent_observed_gps(known, 3600.0, 1800.0).tolist() == [6, 8]


@pytest.fixture(scope="module")
def world(paper_scenario):
    return World.build(paper_scenario.with_overrides(sats=6, hours=2))


def _busy(world):
    for sat in world.sat_names:
        starts = world.planner.pass_starts_s(sat, 60.0, world.scenario.scenario.horizon_s - 600.0)
        if len(starts):
            return sat, float(starts[0]) - 30.0
    raise AssertionError("no pass")


def test_the_planner_weighs_each_gp_by_its_factor(world):
    sat, t0 = _busy(world)
    base = world.planner
    k0 = Knowledge(PersistenceView(world.osse, t0), (), None)
    plain = base.plan(sat, t0, 600.0, k0)
    assert len(plain.gp_ids) > 3
    # recent looks at the plan's first GPs
    took = [int(g) for g, _t in plain.as_list()[:3]]
    known = [KnownObservation(t0 - 100.0, g, "sat_99") for g in took]
    k = Knowledge(PersistenceView(world.osse, t0), known, None)
    st = dataclasses.replace(base.settings, diversity_weight=3.0, diversity_km=8.0, diversity_window_s=3600.0)
    weighted = Planner(base.constellation, base.gp_ecef_km, base.slew, st, candidates=base.candidates)
    off = Planner(base.constellation, base.gp_ecef_km, base.slew, dataclasses.replace(st, diversity_weight=0.0),
                  candidates=base.candidates)
    p_w, p_0 = weighted.instance(sat, t0, k), off.instance(sat, t0, k)
    np.testing.assert_array_equal(p_w.gp_ids, p_0.gp_ids)
    f = diversity_factor(base.gp_ecef_km[p_0.gp_ids], base.gp_ecef_km[sorted(set(took))], 3.0, 8.0)
    np.testing.assert_allclose(p_w.absval, p_0.absval * f[None, :], rtol=1e-12)
    # weight 0 is the planner without the term
    assert off.plan(sat, t0, 600.0, k).as_list() == base.plan(sat, t0, 600.0, k).as_list()
    # with the term the looks lie farther from the recent ones
    def mean_dist(plan):
        g = base.gp_ecef_km[[int(x) for x, _ in plan.as_list()]]
        r = base.gp_ecef_km[took]
        return float(np.sqrt(((g[:, None] - r[None]) ** 2).sum(-1)).min(1).mean())
    assert mean_dist(weighted.plan(sat, t0, 600.0, k)) > mean_dist(off.plan(sat, t0, 600.0, k))
