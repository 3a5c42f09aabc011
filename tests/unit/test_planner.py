"""The one planner (sat_node.scheduler.planner): its instance against one built by hand from the same
arrays, the GP pre-filter against the exact mask's columns, the persistence view, and the satellite
and the ground segment planning through it."""

from __future__ import annotations

import numpy as np
import pytest

from bringup.scenario.world import World
from ground_station.ground_segment import GroundLogic
from orbit_clock.access import for_mask
from sat_node.satellite import SatelliteLogic
from sat_node.scheduler import (
    Knowledge,
    PersistenceView,
    Planner,
    PlannerSettings,
    build_problem,
    solve_dp,
    solve_nonagile,
)
from sat_node.value import Belief, KnownObservation, prior_state


@pytest.fixture(scope="module")
def world(paper_scenario):
    return World.build(paper_scenario.with_overrides(sats=12, hours=2))


def _busy_starts(world) -> list[tuple[str, float]]:
    """(satellite, replan time [s]) 30 s before each satellite's first pass over a region."""
    out = []
    for sat in world.sat_names:
        starts = world.planner.pass_starts_s(sat, 60.0, world.scenario.scenario.horizon_s - 600.0)
        if len(starts):
            out.append((sat, float(starts[0]) - 30.0))
    assert len(out) >= 3
    return out


def test_persistence_view_reads_later_times_at_the_cut_off(world):
    osse = world.osse
    t_known = 1000.0
    view = PersistenceView(osse, t_known)
    gp = np.arange(10)
    for t in (0.0, 999.0, 1000.0, 1900.0, 5000.0):
        np.testing.assert_array_equal(view.value_at(gp, t), osse.value_at(gp, min(t, t_known)))
        assert view.slot_of(t) == osse.slot_of(min(t, t_known))
    # broadcasting (T, 1) x (1, G), as the planner queries it
    t = np.array([[0.0], [3000.0]])
    np.testing.assert_array_equal(view.value_at(gp[None, :], t),
                                  osse.value_at(gp[None, :], np.minimum(t, t_known)))


def test_instance_equals_one_built_by_hand(world):
    SAT, t0 = _busy_starts(world)[0]
    """Oracle: the steps written out on the same arrays - positions on the DP grid, the exact FOR
    mask on the pre-filter's GPs, the forecast at the persistence time through the belief, the prior
    state of the known observations."""
    sc = world.scenario
    planner = world.planner
    window = 600.0
    belief = Belief.from_scenario(sc, SAT, world.n_gp, world.osse.n_slots)
    ids = planner.candidates(SAT, t0, t0 + window)
    known = [KnownObservation(t0 - 100.0, int(ids[3]), "sat_12"),
             KnownObservation(t0 + 50.0, int(ids[7]), "sat_12", planned=True)]
    view = PersistenceView(world.osse, t0)
    p = planner.instance(SAT, t0, Knowledge(view, known, belief), window_s=window, gp_ids=ids)

    step = float(sc.scheduler.dp_step_s)
    times = t0 + step * np.arange(round(window / step))
    pos = world.constellation.track_ecef_km(SAT, times)
    gp = world.gps.ecef_km[ids]
    forecast = world.osse.value_at(ids[None, :], np.minimum(times, t0)[:, None]).astype(float)
    absval = forecast * belief.factor(ids[None, :], world.osse.slot_of(np.minimum(times, t0))[:, None])
    count, recent = prior_state(known, ids, times, SAT, sc.value.revisit_zero_s)
    want = build_problem(t0_s=t0, step_s=step, sat_pos_km=pos, gp_ecef_km=gp,
                         in_for=for_mask(pos, gp, sc.instrument.for_off_nadir_deg), absval=absval,
                         slew=world.ctx.slew, revisit_zero_s=sc.value.revisit_zero_s, gp_ids=ids,
                         prior_count=count, prior_recent=recent)
    assert p.in_for.any() and p.prior_count.any() and p.prior_recent.any()
    for name in ("sat_pos_km", "gp_ecef_km", "gp_ids", "in_for", "absval", "prior_count", "prior_recent",
                 "init_unit"):
        np.testing.assert_array_equal(getattr(p, name), getattr(want, name), err_msg=name)
    assert (p.t0_s, p.step_s, p.ready_t_s) == (want.t0_s, want.step_s, want.ready_t_s)


def test_prefiltered_plan_equals_the_plan_on_the_exact_columns(world):
    """The pre-filter only adds GPs that are never in the field of regard: the DP's plan is the plan
    on the instance whose columns the exact mask chose (every GP in the FOR at some step)."""
    planner = world.planner
    exact = Planner(planner.constellation, planner.gp_ecef_km, planner.slew, planner.settings,
                    candidates=None)
    for sat, t0 in _busy_starts(world)[:3]:
        k = Knowledge(PersistenceView(world.osse, t0), (), None)
        a = planner.plan(sat, t0, 600.0, k)
        b = exact.plan(sat, t0, 600.0, k)
        assert len(b.gp_ids) > 0
        assert a.as_list() == b.as_list() and a.value == b.value


def test_satellite_and_ground_plan_through_the_world_planner(world):
    """The satellite's plan at its start and the ground's first uplinks are the planner's plans for
    what each knows then: nothing observed, so (the default knowledge model, ``observed``) the
    a-priori forecast itself, read here straight from the field (:class:`_Forecast`), no belief noise."""
    from msgs_json import codec

    assert world.scenario.value.knowledge == "observed"

    sc = world.scenario
    lookahead = float(sc.scheduler.plan_lookahead_s)
    planned = 0
    for SAT, t0 in _busy_starts(world):
        t0_ns = int(t0 * 1e9)
        sat = SatelliteLogic(world, SAT, "distributed", dtn=False)
        sched = codec.decode(*_first(sat.start(t0_ns).emits, "/schedule"))
        k = Knowledge(_Forecast(world.osse), (), None)
        plan = world.planner.plan(SAT, t0_ns / 1e9, lookahead, k)
        assert [(it.gp, it.t_ns) for it in sched.items] == [(g, round(t * 1e9)) for g, t in plan.as_list()]
        planned += len(sched.items)
    assert planned > 0

    SAT = world.sat_names[0]
    nonagile = SatelliteLogic(world, SAT, "nonagile", dtn=False)
    sched = codec.decode(*_first(nonagile.start(0).emits, "/schedule"))
    k = Knowledge(_Forecast(world.osse), (), None)
    plan = world.planner.plan(SAT, 0.0, sc.scenario.horizon_s, k, solver="nonagile")
    assert [(it.gp, it.t_ns) for it in sched.items] == [(g, round(t * 1e9)) for g, t in plan.as_list()]

    ground = GroundLogic(world)
    uplinks = [codec.decode(e.topic, e.data) for e in ground.start(0).emits]
    assert [u.sat for u in uplinks] == world.sat_names
    planned, known = 0, []
    for up in uplinks:  # each satellite's plan respects the plans uplinked before it
        nxt = ground._next_pass_after(up.sat, 0)
        window_s = min(sc.horizon_ns, (nxt if nxt is not None else sc.horizon_ns) + ground.margin_ns) / 1e9
        k = Knowledge(_Forecast(world.osse), list(known), None)
        plan = world.planner.plan(up.sat, 0.0, window_s, k)
        got = [(it.gp, it.t_ns) for it in up.schedule.items]
        assert got == ([(g, round(t * 1e9)) for g, t in plan.as_list()] if plan is not None else [])
        known += [KnownObservation(t_ns / 1e9, gp, "", planned=True) for gp, t_ns in got]
        planned += len(got)
    assert planned > 0


class _Forecast:
    """The a-priori forecast as a value source: what a planner that observed nothing knows."""

    def __init__(self, field):
        self._f = field

    def value_at(self, gp_idx, t_s):
        return self._f.forecast_at(gp_idx, t_s)

    def slot_of(self, t_s):
        return self._f.slot_of(t_s)


def _first(emits, suffix: str):
    e = next(e for e in emits if e.topic.endswith(suffix))
    return e.topic, e.data


def test_solvers_by_name(world):
    planner = world.planner
    SAT, t0 = _busy_starts(world)[0]
    k = Knowledge(world.osse)
    p = planner.instance(SAT, t0, k, window_s=600.0, gp_ids=planner.candidates(SAT, t0, t0 + 600.0))
    assert planner.plan(SAT, t0, 600.0, k).as_list() == solve_dp(p).as_list()
    assert planner.plan(SAT, t0, 600.0, k, solver="nonagile").as_list() == \
        solve_nonagile(p, planner.settings.footprint_km).as_list()
    with pytest.raises(ValueError, match=r"^planner solver 'milp': unknown \(known: dp, nonagile\)$"):
        planner.plan(SAT, t0, 600.0, k, solver="milp")


def test_settings_from_the_scenario(paper_scenario):
    st = PlannerSettings.from_scenario(paper_scenario)
    assert st.for_off_nadir_deg == 55.0 and st.revisit_zero_s == 900.0 and st.footprint_km == 8.0


class _RowByRow:
    """A view that hides ``frozen_after_s``: the planner reads it at every time of the window."""

    def __init__(self, view):
        self._view = view

    def value_at(self, gp_idx, t_s):
        return self._view.value_at(gp_idx, t_s)

    def slot_of(self, t_s):
        return self._view.slot_of(t_s)


def test_frozen_view_is_read_once_with_the_same_instance(world):
    """A persistence view (PersistenceView, RegionPersistenceView) says it reads every time from its
    ``frozen_after_s`` on as that instant; the planner then reads one row for the window. Oracle: the
    same view read row by row gives the same absolute values and the same plan, through a belief and
    for information times before, at and (a view built by hand) after the window's start."""
    from sat_node.knowledge import RegionPersistenceView

    SAT, t0 = _busy_starts(world)[0]
    sat = SatelliteLogic(world, SAT, "distributed", dtn=False)
    info = np.linspace(0.0, t0 + 300.0, world.n_gp)
    views = [PersistenceView(world.osse, t0), RegionPersistenceView(world.osse, np.minimum(info, t0), t0),
             RegionPersistenceView(world.osse, info, t0)]
    assert views[0].frozen_after_s == views[1].frozen_after_s == t0  # read once
    assert views[2].frozen_after_s == t0 + 300.0  # later information: not frozen at the window's start
    for view in views:
        for belief in (sat.belief, None):
            a = world.planner.instance(SAT, t0, Knowledge(view, (), belief))
            b = world.planner.instance(SAT, t0, Knowledge(_RowByRow(view), (), belief))
            assert a.absval.shape == b.absval.shape and a.absval.tobytes() == b.absval.tobytes()
            pa, pb = solve_dp(a), solve_dp(b)
            assert pa.as_list() == pb.as_list() and pa.value == pb.value
