"""Non-agile (nadir-only) baseline: exactly the GPs under the footprint, at the overhead times."""

import numpy as np
import pytest
from dp_instances import OMEGA_RAD_S, PAPER_SLEW, gp_ecef, track

from orbit_clock.frames import WGS84_A_KM
from sat_node.scheduler import build_problem, solve_nonagile


def _problem(gp, n_steps=120, t0_s=-60.0, absval=None):
    times = t0_s + np.arange(n_steps, dtype=float)
    sat = track(times)
    G = len(gp)
    return build_problem(t0_s=t0_s, step_s=1.0, sat_pos_km=sat, gp_ecef_km=gp, in_for=np.ones((n_steps, G), bool),
                         absval=np.full(G, 10.0) if absval is None else absval, slew=PAPER_SLEW,
                         revisit_zero_s=900.0)


def test_footprint_column_only():
    lat = np.linspace(-2.0, 2.0, 9)
    km_deg = np.degrees(1.0 / WGS84_A_KM)
    # column on the track, one 3 km off (inside the 4 km half-footprint), neighbours 8 km off
    lons = [0.0, 3.0 * km_deg, 8.0 * km_deg, -8.0 * km_deg, 4.5 * km_deg]
    lat_all = np.concatenate([lat] * len(lons))
    lon_all = np.concatenate([np.full(9, lo) for lo in lons])
    gp = gp_ecef(lat_all, lon_all)
    p = _problem(gp)
    plan = solve_nonagile(p, footprint_km=8.0)
    assert sorted(plan.cols.tolist()) == list(range(18))  # first two columns only
    # brute force: time of the closest approach of the nadir point on a 0.01 s grid
    tf = np.arange(-60.0, 60.0, 0.01)
    nadir = WGS84_A_KM * track(tf) / np.linalg.norm(track(tf), axis=1, keepdims=True)
    for j, t in zip(plan.cols, plan.t_s):
        d = np.linalg.norm(nadir - gp[j], axis=1)
        assert d.min() <= 4.0
        assert abs(tf[np.argmin(d)] - t) <= 0.5 + 0.01
        assert t == pytest.approx(np.radians(lat_all[j]) / OMEGA_RAD_S, abs=0.51)
    assert plan.value == pytest.approx(180.0)


def test_repeat_under_footprint_is_worth_zero():
    gp = gp_ecef(np.array([0.0]), np.array([0.0]))
    p = _problem(gp)
    p2 = build_problem(t0_s=p.t0_s, step_s=1.0, sat_pos_km=p.sat_pos_km, gp_ecef_km=gp, in_for=p.in_for,
                       absval=p.absval, slew=PAPER_SLEW, revisit_zero_s=900.0,
                       prior_recent=np.ones_like(p.in_for))
    assert solve_nonagile(p, 8.0).value == 10.0
    plan = solve_nonagile(p2, 8.0)
    assert len(plan) == 1 and plan.value == 0.0


def test_bad_footprint():
    with pytest.raises(ValueError, match="footprint_km"):
        solve_nonagile(_problem(gp_ecef(np.array([0.0]), np.array([0.0]))), 0.0)


def test_one_image_covers_several_gps_and_each_is_observed():
    """At the Nyquist grid a nadir footprint covers neighbouring GPs at once: the plan's items share a
    time (in GP order, msgs_json Schedule allows it) and the satellite observes each once."""
    from bringup.scenario.config import load_scenario
    from bringup.scenario.world import World
    from msgs_json import codec
    from sat_node.satellite import SatelliteLogic, _Item

    world = World.build(load_scenario("paper").with_overrides(sats=3, hours=0.5))
    sat = SatelliteLogic(world, world.sat_names[0], "nonagile", dtn=False)
    t = 120 * 10**9
    sat.plan = [_Item(5, t, 10.0, 1), _Item(6, t, 11.0, 1), _Item(9, t + 10**9, 12.0, 1)]
    emits = sat._execute(t)
    obs = [codec.decode(e.topic, e.data) for e in emits if e.topic.endswith("/observations")]
    assert [(o.gp, o.t_ns) for o in obs] == [(5, t), (6, t)]
    sat.plan = [_Item(6, t, 11.0, 2), _Item(9, t + 10**9, 12.0, 2)]  # a replayed item is not observed twice
    emits = sat._execute(t + 10**9)
    assert [codec.decode(e.topic, e.data).gp for e in emits if e.topic.endswith("/observations")] == [9]
