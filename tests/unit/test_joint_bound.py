"""Joint planning with at most K partners (scenario key ``scheduler.joint_max_partners``,
sat_node/scheduler/planner.py ``Planner.group``): the partners the rule names on a hand-drawn case,
never more than K on a real constellation, the same plans as unbounded when K is at least the
unbounded group's size, and the setting's path from the scenario file and the command line to the
planner (local engine's world, ROS engine's run spec) with one-line errors on bad input."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scenario_edit import raw_scenario

from bringup.scenario.config import ScenarioError, _validate
from bringup.scenario.world import OrbitContext
from sat_node.acs import SlewModel
from sat_node.scheduler import Knowledge, PersistenceView, Planner, PlannerSettings

R_KM = 6378.137
ALT_KM = 710.0


# ---------------------------------------------------------------- a hand-drawn case
#
# Six GPs on the equator, and satellites 710 km above it that each arrive over one longitude at
# a set time and stay (before: parked over lon 180, seeing none of them):
#
#   GP            0     1     2     3     4     5
#   lon         -16    -8     0     8    16    24
#   sat_a (me)        [-----------]                  from t = 0:   sees GPs 1 2 3
#   sat_b                   [-----------]            from t = 300: 2 3 4 -> first sees mine at 300
#   sat_c       [-----------]                        from t = 100: 0 1 2 -> 100
#   sat_d                         [-----------]      from t = 100: 3 4 5 -> 100
#   sat_e       over lon 40 from t = 0: none of mine                    -> not a partner
#   sat_f             [-----------]                  from t = 500: 1 2 3 -> 500 (shares all three)
#
# A GP 8 deg of arc from the sub-satellite point is 49 deg off nadir (inside the 55 deg field of
# regard), one 16 deg away 61 deg (outside). Ranked by the first time they may see one of my GPs,
# ties by name: c, d, b, f - and f, which shares the most, last.

_SAT_AT = {"sat_a": (0.0, 0.0), "sat_b": (8.0, 300.0), "sat_c": (-8.0, 100.0), "sat_d": (16.0, 100.0),
           "sat_e": (40.0, 0.0), "sat_f": (0.0, 500.0)}  # name -> (lon [deg], from t [s])
_GP_LON = [-16.0, -8.0, 0.0, 8.0, 16.0, 24.0]


def _equator(lon_deg, r_km: float) -> np.ndarray:
    lon = np.radians(np.asarray(lon_deg, np.float64))
    return np.stack([r_km * np.cos(lon), r_km * np.sin(lon), np.zeros_like(lon)], axis=-1)


class _HandConstellation:
    def __init__(self, at: dict):
        self.at = at
        self.names = sorted(at)

    def track_ecef_km(self, name, t_s):
        lon, since = self.at[name]
        t = np.atleast_1d(np.asarray(t_s, np.float64))
        return _equator(np.where(t >= since, lon, 180.0), R_KM + ALT_KM)


class _Flat:
    """Every GP worth 100 at every time, one value slot."""

    def value_at(self, gp_idx, t_s):
        return np.full(np.broadcast(np.asarray(gp_idx), np.asarray(t_s)).shape, 100.0)

    def slot_of(self, t_s):
        return np.zeros(np.shape(t_s), np.int64)


def _hand_planner(paper_scenario, k: int, at: dict = _SAT_AT, step_s: float = 10.0) -> Planner:
    st = PlannerSettings(dp_step_s=step_s, plan_lookahead_s=600.0, for_off_nadir_deg=55.0, revisit_zero_s=900.0,
                         footprint_km=8.0, joint=True, joint_max_partners=k)
    gps = _equator(_GP_LON, R_KM)
    return Planner(_HandConstellation(at), gps, SlewModel.from_scenario(paper_scenario), st)


def _hand_group(paper_scenario, k: int, partners=None, **kw) -> list[str]:
    planner = _hand_planner(paper_scenario, k, **kw)
    know = Knowledge(_Flat())
    mine = planner.instance("sat_a", 0.0, know, window_s=600.0)
    return [q.sat_name for q in planner.group("sat_a", 0.0, 600.0, know, mine, partners)]


def test_hand_drawn_case_sees_what_the_drawing_says(paper_scenario):
    """The drawing's fields of regard, as the planner's instances see them over 900 s: the GPs and
    the first step each satellite sees one of GPs 1-3 (mine)."""
    planner = _hand_planner(paper_scenario, 0)
    know = Knowledge(_Flat())
    seen, first = {}, {}
    for s in _SAT_AT:
        q = planner.instance(s, 0.0, know, window_s=900.0)
        seen[s] = q.gp_ids.tolist()
        rows = np.flatnonzero(q.in_for[:, np.isin(q.gp_ids, [1, 2, 3])].any(axis=1))
        first[s] = float(q.times_s[rows[0]]) if len(rows) else None
    assert seen == {"sat_a": [1, 2, 3], "sat_b": [2, 3, 4], "sat_c": [0, 1, 2], "sat_d": [3, 4, 5], "sat_e": [],
                    "sat_f": [1, 2, 3]}
    assert first == {"sat_a": 0.0, "sat_b": 300.0, "sat_c": 100.0, "sat_d": 100.0, "sat_e": None, "sat_f": 500.0}


@pytest.mark.parametrize("k,expected", [
    (0, ["sat_b", "sat_c", "sat_d", "sat_f"]),  # unbounded: every overlapping satellite, in name order
    (1, ["sat_c"]),  # c and d first see mine at 100 s: c by name
    (2, ["sat_c", "sat_d"]),
    (3, ["sat_b", "sat_c", "sat_d"]),  # f, sharing all three GPs but last to reach them, is left out
    (4, ["sat_b", "sat_c", "sat_d", "sat_f"]),
    (9, ["sat_b", "sat_c", "sat_d", "sat_f"]),
])
def test_the_partners_the_rule_names(paper_scenario, k, expected):
    assert _hand_group(paper_scenario, k) == expected


def test_first_times_are_on_the_dp_grid_not_the_coarse_look(paper_scenario):
    """With 1-s DP steps, d arriving at 103 s ranks before c at 107 s, though the 10-s look first
    sees both at 110 s (where the name would put c first)."""
    at = {**_SAT_AT, "sat_c": (-8.0, 107.0), "sat_d": (16.0, 103.0)}
    assert _hand_group(paper_scenario, 1, at=at, step_s=1.0) == ["sat_d"]
    assert _hand_group(paper_scenario, 2, at=at, step_s=1.0) == ["sat_c", "sat_d"]
    at = {**_SAT_AT, "sat_c": (-8.0, 103.0), "sat_d": (16.0, 107.0)}
    assert _hand_group(paper_scenario, 1, at=at, step_s=1.0) == ["sat_c"]


def test_partners_free_later_are_ranked_from_when_they_are_free(paper_scenario):
    """The ground names partners with the time they are free: c and d free at 400 s first see my
    GPs then, after b (300 s); one free at the group's end (900 s) is not a partner."""
    partners = [("sat_b", 0.0), ("sat_c", 400.0), ("sat_d", 400.0), ("sat_f", 900.0)]
    assert _hand_group(paper_scenario, 1, partners) == ["sat_b"]
    assert _hand_group(paper_scenario, 2, partners) == ["sat_b", "sat_c"]
    assert _hand_group(paper_scenario, 0, partners) == ["sat_b", "sat_c", "sat_d"]


# ---------------------------------------------------------------- a real constellation

@pytest.fixture(scope="module")
def dense(paper_scenario):
    """96 satellites in the paper's 3 planes, 1 h: groups of up to 7 members at a pass."""
    sc = paper_scenario.with_overrides(sats=96, hours=1)
    ctx = OrbitContext.from_scenario(sc)
    planner = ctx.planner()
    assert planner.settings.joint and planner.settings.joint_max_partners == 0
    cases = []  # (unbounded group size, sat, t0) 30 s before each pass in the first 50 min
    for sat in sc.sat_names:
        for s in planner.pass_starts_s(sat, 0.0, 3000.0):
            t0 = max(0.0, float(s) - 30.0)
            cases.append((len(_group(planner, sat, t0, ctx.osse)), sat, t0))
    cases.sort(key=lambda c: (-c[0], c[1], c[2]))
    assert cases[0][0] >= 4  # the bound has something to cut
    return ctx, planner, cases


def _knowledge(osse, t0: float) -> Knowledge:
    return Knowledge(PersistenceView(osse, t0))


def _group(planner, sat, t0, osse):
    k = _knowledge(osse, t0)
    mine = planner.instance(sat, t0, k, window_s=600.0, gp_ids=planner.candidates(sat, t0, t0 + 600.0))
    return planner.group(sat, t0, 600.0, k, mine)


def _bounded(planner, k: int) -> Planner:
    return Planner(planner.constellation, planner.gp_ecef_km, planner.slew,
                   dataclasses.replace(planner.settings, joint_max_partners=k), candidates=planner.candidates)


def _first_s(mine, q) -> float:
    """When partner ``q``'s field of regard first reaches a GP worth something to me [s]: the
    earliest of those GPs' first steps in its instance's exact FOR mask."""
    a = set(mine.gp_ids[mine.v_first.any(axis=0)].tolist())
    firsts = [np.flatnonzero(q.in_for[:, j])[0] for j, g in enumerate(q.gp_ids.tolist())
              if g in a and q.in_for[:, j].any()]
    return q.t0_s + q.step_s * min(firsts)


def test_a_bounded_group_is_never_larger_than_k(dense):
    """On the 12 passes of the first 50 min with the largest groups: at most K partners, and they are
    the unbounded group's members whose FOR first reaches one of my GPs earliest (ties by name), in
    its order."""
    ctx, planner, cases = dense
    cut = 0
    for size, sat, t0 in cases[:12]:
        full = _group(planner, sat, t0, ctx.osse)
        k_ = _knowledge(ctx.osse, t0)
        mine = planner.instance(sat, t0, k_, window_s=600.0, gp_ids=planner.candidates(sat, t0, t0 + 600.0))
        ranked = sorted(full, key=lambda q: (_first_s(mine, q), q.sat_name))
        for k in (1, 2, 3):
            got = [q.sat_name for q in _group(_bounded(planner, k), sat, t0, ctx.osse)]
            assert len(got) == min(k, size)
            assert set(got) == {q.sat_name for q in ranked[:k]}
            assert got == [q.sat_name for q in full if q.sat_name in set(got)]
            cut += size > k
    assert cut > 0


def test_k_at_least_the_group_plans_exactly_as_unbounded(dense):
    """With K >= the unbounded group's size the group is the same, so the joint plan is too: the
    same looks at the same times with the same values. (Bounded below it, the plan may differ.)"""
    ctx, planner, cases = dense
    three = next(c for c in cases if c[0] == 3)
    for (size, sat, t0), ks in ((three, (3, 8)), (cases[0], (cases[0][0],))):
        k_ = _knowledge(ctx.osse, t0)
        full = planner.plan(sat, t0, 600.0, k_)
        for k in ks:
            got = _bounded(planner, k).plan(sat, t0, 600.0, k_)
            assert got.as_list() == full.as_list()
            np.testing.assert_array_equal(got.values, full.values)


# ---------------------------------------------------------------- the setting's path

def test_scenario_default_and_override(paper_scenario):
    assert paper_scenario.scheduler.joint_max_partners == 0  # the study's: unbounded
    sc = paper_scenario.with_overrides(joint_max_partners=2)
    assert sc.scheduler.joint_max_partners == 2 and type(sc.scheduler.joint_max_partners) is int
    assert PlannerSettings.from_scenario(sc).joint_max_partners == 2
    assert OrbitContext.from_scenario(sc.with_overrides(sats=6)).planner().settings.joint_max_partners == 2


@pytest.mark.parametrize("value,needle", [
    (-1, ">= 0"),
    (2.0, "Expected `int`"),
    (1001, "<= 1000"),
    ("two", "Expected `int`"),
    (True, "Expected `int`"),
])
def test_bad_values_are_one_line_naming_file_and_key(paper_scenario, value, needle):
    raw = raw_scenario(paper_scenario)
    raw["scheduler"]["joint_max_partners"] = value
    with pytest.raises(ScenarioError, match=needle) as exc:
        _validate(raw, "x.toml")
    msg = str(exc.value)
    assert "\n" not in msg and msg.startswith("x.toml: key 'scheduler.joint_max_partners': ")


def test_a_bound_without_joint_planning_is_refused(paper_scenario):
    raw = raw_scenario(paper_scenario)
    raw["scheduler"]["joint_planning"] = False
    raw["scheduler"]["joint_max_partners"] = 2
    with pytest.raises(ScenarioError, match=r"^x\.toml: key 'scheduler\.joint_max_partners': 2 partners, but "
                                            r"joint_planning is false"):
        _validate(raw, "x.toml")
    raw["scheduler"]["joint_max_partners"] = 0
    assert _validate(raw, "x.toml").scheduler.joint_max_partners == 0


def test_cli_flag_reaches_the_scenario_and_the_ros_run_spec(capsys):
    from bringup.cli.common import overrides_of, scenario_from_args
    from bringup.cli.main import build_parser
    from bringup.engine.ros.run_spec import RunSpec

    args = build_parser().parse_args(["run", "--joint-max-partners", "3", "--hours", "1"])
    assert scenario_from_args(args).scheduler.joint_max_partners == 3
    spec = RunSpec(factory="a:b", roles=["sat_11"], scenario="paper", overrides=overrides_of(args))
    assert spec.load_scenario().scheduler.joint_max_partners == 3
    assert spec.parameters("sat_11")["scheduler.joint_max_partners"] == 3  # the nodes' read-only parameter
    args = build_parser().parse_args(["run", "--hours", "1"])
    assert scenario_from_args(args).scheduler.joint_max_partners == 0
    for bad, why in (("-1", "must be 0..1000"), ("2.5", "expected a whole number")):
        with pytest.raises(SystemExit):
            build_parser().parse_args(["run", "--joint-max-partners", bad])
        err = capsys.readouterr().err.strip().splitlines()
        assert why in err[-1] and "--joint-max-partners" in err[-1]
