"""Knowledge models (sat_node/knowledge.py) and the inference a bundle carries (sat_node/inference.py).

Oracles: a scalar re-computation of the observed model's formula; a field that records every time
it is read (the region-truth model must never read a region later than its information time); two
truth fields differing only in a region nobody observed (the planner inputs must not differ, except
under the oracle model, which must see the difference); two truth fields differing only at the GPs
nobody observed, inside observed regions (the default model's inputs must not differ; region-truth
and oracle, which peek, must differ); a drawn two-GP case where a flood one satellite saw decides
what the next one observes; the former name ``study`` refused in one line, naming the models.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from dp_instances import PAPER_SLEW, gp_ecef, track

from ground_station.osse import OsseField
from sat_node.inference import Inference, decode_inference, encode_inference
from sat_node.knowledge import (
    DEFAULT_MODEL,
    MODELS,
    RENAMED,
    KnowledgeParams,
    KnowledgeState,
    ObservedView,
    RegionPersistenceView,
    check_model,
)
from sat_node.scheduler.planner import Planner, PlannerSettings
from sat_node.value import Belief, KnownObservation


# ------------------------------------------------------------------------------------------ payload
def test_inference_round_trip_and_rounding():
    rng = np.random.default_rng(3)
    for _ in range(200):
        inf = Inference(src=f"sat_{rng.integers(1, 4)}{rng.integers(1, 9)}", gp=int(rng.integers(0, 5000)),
                        t_ns=int(rng.integers(0, 2 ** 62)), value=float(rng.uniform(0, 256)),
                        region=int(rng.integers(0, 5)), omega=float(rng.normal()), delta=float(rng.normal()))
        back = decode_inference(encode_inference(inf))
        assert (back.src, back.gp, back.t_ns, back.region) == (inf.src, inf.gp, inf.t_ns, inf.region)
        assert abs(back.value - inf.value) <= 5e-4 and abs(back.omega - inf.omega) <= 5e-5
        assert abs(back.delta - inf.delta) <= 5e-5
        assert len(encode_inference(inf)) * 8 <= 1645  # inside the study's inference bits


@pytest.mark.parametrize("payload, field", [
    (b"not json", "not JSON"), (b"[1, 2]", "not a JSON object"),
    (b'{"src":"sat_11","gp":1,"t_ns":5,"v":3.0,"r":0,"om":0.0}', "missing 'de'"),
    (b'{"src":"sat_11","gp":-1,"t_ns":5,"v":3.0,"r":0,"om":0.0,"de":0.0}', "'gp'"),
    (b'{"src":"sat_11","gp":1,"t_ns":5.5,"v":3.0,"r":0,"om":0.0,"de":0.0}', "'t_ns'"),
    (b'{"src":"sat_11","gp":1,"t_ns":5,"v":-3.0,"r":0,"om":0.0,"de":0.0}', "'v'"),
    (b'{"src":"sat_11","gp":1,"t_ns":5,"v":3.0,"r":0,"om":NaN,"de":0.0}', "'om'"),
    (b'{"src":"","gp":1,"t_ns":5,"v":3.0,"r":0,"om":0.0,"de":0.0}', "'src'"),
    (b'{"src":"sat_11","gp":true,"t_ns":5,"v":3.0,"r":0,"om":0.0,"de":0.0}', "'gp'"),
    (b"\xff\xfe", "not JSON"),
])
def test_malformed_inference_is_one_value_error(payload, field):
    with pytest.raises(ValueError, match=field):
        decode_inference(payload)


def test_models_are_the_scenario_choices():
    from bringup.scenario.config import KNOWLEDGE_MODELS, RENAMED_KNOWLEDGE, load_scenario

    assert tuple(MODELS) == KNOWLEDGE_MODELS and tuple(RENAMED) == RENAMED_KNOWLEDGE
    assert KnowledgeParams().model == DEFAULT_MODEL == KNOWLEDGE_MODELS[0] == "observed"
    assert load_scenario("paper").value.knowledge == "observed"  # the scenario never peeks by default
    with pytest.raises(ValueError, match="unknown"):
        KnowledgeParams(model="psychic")


def test_the_former_name_is_refused_naming_the_models(tmp_path, capsys):
    """``study`` (now ``region-truth``) is a clear one-line error, never silently mapped: in the flight
    software, in a scenario file, and on the command line."""
    from bringup.cli.main import main
    from bringup.scenario.config import ScenarioError, load_scenario

    for call in (lambda: KnowledgeParams(model="study"), lambda: check_model("study")):
        with pytest.raises(ValueError, match="'study' was renamed 'region-truth'") as exc:
            call()
        assert "\n" not in str(exc.value) and all(m in str(exc.value) for m in MODELS)
    text = Path(load_scenario("paper").source_path).read_text().replace('knowledge = "observed"', 'knowledge = "study"')
    assert 'knowledge = "study"' in text
    (tmp_path / "old.toml").write_text(text)
    with pytest.raises(ScenarioError) as exc:
        load_scenario(tmp_path / "old.toml")
    msg = str(exc.value)
    assert "\n" not in msg and "old.toml" in msg and "value.knowledge" in msg and "region-truth" in msg
    assert main(["run", "--scenario", str(tmp_path / "old.toml"), "--out", str(tmp_path / "o"), "--no-plots"]) == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(err) == 1 and "'study' was renamed 'region-truth'" in err[0]
    with pytest.raises(SystemExit) as ex:
        main(["run", "--knowledge", "study", "--out", str(tmp_path / "o"), "--no-plots"])
    assert ex.value.code == 2
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert "argument --knowledge" in last and "'study' was renamed 'region-truth'" in last and "observed" in last
    assert not (tmp_path / "o" / "report.json").exists()


# ------------------------------------------------------------------------------------------ fields
def _field(values: np.ndarray, forecast: np.ndarray | None = None, regions=None) -> OsseField:
    n_gp = values.shape[1]
    reg = np.zeros(n_gp, int) if regions is None else np.asarray(regions)
    return OsseField(values=values, slot_s=900.0, lat_deg=np.zeros(n_gp), lon_deg=np.linspace(0, 1, n_gp),
                     region_index=reg, region_names=[f"r{i}" for i in range(int(reg.max()) + 1)],
                     forecast=forecast)


class _Recorder:
    """A field that records the latest time each GP was read at."""

    def __init__(self, field):
        self.field = field
        self.latest = np.full(field.n_gp, -np.inf)

    def value_at(self, gp, t):
        gp, t = np.broadcast_arrays(np.asarray(gp), np.asarray(t, float))
        np.maximum.at(self.latest, gp.ravel(), t.ravel())
        return self.field.value_at(gp, t)

    def slot_of(self, t):
        return self.field.slot_of(t)


def test_study_view_never_reads_a_region_after_its_information_time():
    rng = np.random.default_rng(1)
    f = _field(rng.integers(1, 257, (24, 30)).astype(np.int16), regions=np.repeat([0, 1, 2], 10))
    rec = _Recorder(f)
    info = np.repeat([600.0, 0.0, 4000.0], 10)
    view = RegionPersistenceView(rec, info, t_now_s=5000.0)
    t = np.arange(5000.0, 8000.0, 7.0)
    v = view.value_at(np.arange(30)[None, :], t[:, None])
    assert np.all(rec.latest <= info)
    assert np.array_equal(v[:, 0], np.full(len(t), f.values[0, 0]))       # region 0 read at 600 s (slot 0)
    assert np.array_equal(v[:, 25], np.full(len(t), f.values[4, 25]))     # region 2 at 4000 s (slot 4)


def _observed_scalar(f, region, xyz, obs, insight, p: KnowledgeParams, t_now, g, t):
    """The module docstring's formula, one (GP, time) at a time."""
    num = w = 0.0
    for og, ot, ov in obs:
        if region[og] != region[g]:
            continue
        d = math.log(max(ov, 1.0) / f.forecast[int(ot // 900), og])
        k = math.exp(-0.5 * float(np.sum((xyz[g] - xyz[og]) ** 2)) / p.spread_km ** 2 - (t - ot) / p.memory_s)
        num += k * d
        w += k
    dd = num / max(1.0, w)
    if region[g] in insight:
        ti, om, de = insight[region[g]]
        age = t - ti
        dd += (1 - min(1.0, w)) * (om + de * min(age, p.memory_s) / 3600.0) * math.exp(-age / p.memory_s)
    dd = max(-math.log(256), min(math.log(256), dd))
    return min(256.0, max(1.0, f.forecast[int(t // 900), g] * math.exp(dd)))


def test_observed_view_equals_the_formula_on_random_observations():
    rng = np.random.default_rng(7)
    n_gp = 40
    regions = np.repeat([0, 1], 20)
    f = _field(rng.integers(1, 257, (8, n_gp)).astype(np.int16), rng.integers(1, 257, (8, n_gp)).astype(np.int16),
               regions)
    xyz = np.column_stack([rng.uniform(0, 60, n_gp), rng.uniform(0, 60, n_gp), np.zeros(n_gp)])
    p = KnowledgeParams(model="observed", spread_km=12.0, memory_s=1500.0)
    ks = KnowledgeState(p, "sat_11")
    obs = []
    for _ in range(25):
        g, t = int(rng.integers(0, n_gp)), float(rng.uniform(0, 3000))
        v = float(rng.uniform(1, 256))
        ks.learn(Inference("sat_21", g, int(t * 1e9), v, int(regions[g]), float(rng.normal()), float(rng.normal())))
        obs.append((g, int(t * 1e9) / 1e9, v))
    t_now = 3100.0
    kn = ks.knowledge(f, regions, xyz, t_now, [], None)
    assert isinstance(kn.value, ObservedView) and kn.belief is None
    times = np.array([3100.0, 3500.0, 6000.0])
    got = kn.value.value_at(np.arange(n_gp)[None, :], times[:, None])
    insight = {r: x for r, x in ks.insight.items()}
    for i, t in enumerate(times):
        for g in range(n_gp):
            want = _observed_scalar(f, regions, xyz, obs, insight, p, t_now, g, t)
            assert got[i, g] == pytest.approx(want, rel=1e-9), (g, t)
    # a row of GPs by a column of times (how the planner asks) gives, bit for bit, what the same
    # pairs give asked flat (the view computes per-GP and per-time factors unbroadcast); asked one
    # GP at a time, the kernel sums (a matrix product of another shape) may round differently
    gg, tt = np.meshgrid(np.arange(n_gp), times)
    flat = kn.value.value_at(gg.ravel(), tt.ravel()).reshape(gg.shape)
    one = np.array([[kn.value.value_at(np.array([g]), np.array([t]))[0] for g in range(n_gp)] for t in times])
    assert np.array_equal(got, flat) and np.allclose(got, one, rtol=1e-12, atol=0)


def test_observed_view_reuses_a_region_only_for_the_same_gps():
    """One view asked in turn for several GP sets (whole regions, as the planner's instances are, and
    parts of them, repeated) gives each time, bit for bit, what a fresh view gives for that set: a
    region's sums are taken again only for exactly the GPs they were made for."""
    rng = np.random.default_rng(3)
    n_gp = 90
    regions = np.repeat([0, 1, 2], 30)
    f = _field(rng.integers(1, 257, (8, n_gp)).astype(np.int16), rng.integers(1, 257, (8, n_gp)).astype(np.int16),
               regions)
    xyz = np.column_stack([rng.uniform(0, 60, n_gp), rng.uniform(0, 60, n_gp), np.zeros(n_gp)])
    ks = KnowledgeState(KnowledgeParams(model="observed", spread_km=12.0, memory_s=1500.0), "sat_11")
    for _ in range(400):
        g, t = int(rng.integers(0, n_gp)), float(rng.uniform(0, 3000))
        ks.learn(Inference("sat_21", g, int(t * 1e9), float(rng.uniform(1, 256)), int(regions[g]), 0.1, 0.0))
    times = np.array([3100.0, 3500.0, 6000.0])
    view = ks.knowledge(f, regions, xyz, 3100.0, [], None).value
    sets = [np.arange(0, 60), np.arange(30, 90), np.arange(0, 90), np.arange(5, 25), np.arange(30, 90),
            np.sort(rng.choice(n_gp, 50, replace=False)), np.arange(0, 60)]
    for ids in sets:
        fresh = ks.knowledge(f, regions, xyz, 3100.0, [], None).value
        got = view.value_at(ids[None, :], times[:, None])
        assert got.tobytes() == fresh.value_at(ids[None, :], times[:, None]).tobytes(), ids
    assert len(view._ref_cache) >= 5  # whole regions were kept and taken again


def test_observed_view_is_exact_at_a_fresh_look_and_forgets():
    n_gp = 3
    fc = np.full((8, n_gp), 20, np.int16)
    f = _field(np.full((8, n_gp), 20, np.int16), fc)
    xyz = np.array([[0.0, 0, 0], [3.0, 0, 0], [500.0, 0, 0]])
    p = KnowledgeParams(model="observed", spread_km=10.0, memory_s=1200.0)
    ks = KnowledgeState(p, "sat_11")
    ks.learn(Inference("sat_11", 0, 1000 * 10 ** 9, 200.0, 0))
    kn = ks.knowledge(f, np.zeros(n_gp, int), xyz, 1000.0, [], None)
    v = kn.value.value_at(np.arange(n_gp), np.full(n_gp, 1000.0))
    assert v[0] == pytest.approx(200.0)                       # the GP just seen: what was seen
    assert 20.0 < v[1] < 200.0                                # its neighbour moves with it
    assert v[2] == pytest.approx(20.0, rel=1e-6)              # far away: the forecast
    late = kn.value.value_at(np.array([0]), np.array([1000.0 + 20 * 1200.0]))
    assert late[0] == pytest.approx(20.0, rel=1e-6)           # long after: the forecast again


# ------------------------------------------------------------------- only what reached the planner
def _two_fields(rng, from_slot: int):
    """Two truth fields equal except in region 1 (nobody observed it) from ``from_slot`` on, one
    forecast."""
    a = rng.integers(1, 257, (24, 60)).astype(np.int16)
    b = a.copy()
    b[from_slot:, 30:] = 257 - a[from_slot:, 30:]
    fc = rng.integers(1, 257, (24, 60)).astype(np.int16)
    reg = np.repeat([0, 1], 30)
    return _field(a, fc, reg), _field(b, fc, reg), reg


@pytest.mark.parametrize("model, from_slot", [("region-truth", 1), ("observed", 1), ("observed", 0), ("oracle", 1)])
def test_unobserved_region_changes_no_input_except_under_the_oracle(model, from_slot):
    """``region-truth`` may know the epoch state (the forecast is issued with it): its fields differ after
    the epoch only; ``observed`` knows only the forecast: its fields may differ from the start."""
    rng = np.random.default_rng(11)
    fa, fb, reg = _two_fields(rng, from_slot)
    xyz = np.column_stack([np.arange(60.0) * 4, np.zeros(60), np.zeros(60)])
    belief = Belief(seed=1, sat_name="sat_11", n_gp=60, n_slots=24)
    ks = KnowledgeState(KnowledgeParams(model=model), "sat_11")
    for g, t in ((3, 100.0), (12, 900.0), (20, 2000.0)):  # region 0 only
        ks.learn(Inference("sat_21", g, int(t * 1e9), float(fa.values[int(t // 900), g]), 0))
    times = np.arange(2500.0, 9000.0, 60.0)
    ids = np.arange(60)
    va = ks.knowledge(fa, reg, xyz, 2500.0, [], belief).value.value_at(ids[None, :], times[:, None])
    vb = ks.knowledge(fb, reg, xyz, 2500.0, [], belief).value.value_at(ids[None, :], times[:, None])
    if model == "oracle":
        assert not np.array_equal(va[:, 30:], vb[:, 30:])   # the oracle reads the truth: the test can fail
    else:
        assert np.array_equal(va, vb)
    # once region 1 is observed, its news reaches the planner (region-truth and observed alike)
    ks.learn(Inference("sat_21", 40, int(2400 * 1e9), float(fb.values[2, 40]), 1))
    vb2 = ks.knowledge(fb, reg, xyz, 2500.0, [], belief).value.value_at(ids[None, :], times[:, None])
    assert not np.array_equal(vb2[:, 30:], va[:, 30:])


@pytest.mark.parametrize("model", ["observed", "region-truth", "oracle"])
def test_unobserved_gps_of_an_observed_region_change_no_input_only_under_the_default(model):
    """The ground-point twin at the planner's input: region 0 is observed at three GPs; field B is A
    with every *other* GP changed (v -> 257 - v) from slot 1 on, the forecast the same. ``observed``
    (forecast + what reached it) gives identical values everywhere; ``region-truth`` (the region's
    truth at its information time) and ``oracle`` read the changed GPs, so the comparison can fail."""
    rng = np.random.default_rng(5)
    a = rng.integers(1, 257, (24, 60)).astype(np.int16)
    seen = np.array([3, 12, 20])
    b = a.copy()
    other = np.setdiff1d(np.arange(60), seen)
    b[1:, other] = 257 - a[1:, other]
    fc = rng.integers(1, 257, (24, 60)).astype(np.int16)
    reg = np.repeat([0, 1], 30)
    fa, fb = _field(a, fc, reg), _field(b, fc, reg)
    xyz = np.column_stack([np.arange(60.0) * 4, np.zeros(60), np.zeros(60)])
    belief = Belief(seed=1, sat_name="sat_11", n_gp=60, n_slots=24)

    def values(f):
        ks = KnowledgeState(KnowledgeParams(model=model), "sat_11")
        for g, t in zip(seen, (1000.0, 1900.0, 2000.0)):  # own looks: the instrument reads field f there
            ks.observe(f, int(g), int(t * 1e9), float(f.values[int(t // 900), g]), 0)
        ids = np.arange(60)
        times = np.arange(2500.0, 9000.0, 60.0)
        return ks.knowledge(f, reg, xyz, 2500.0, [], belief).value.value_at(ids[None, :], times[:, None])

    va, vb = values(fa), values(fb)
    if model == "observed":
        assert np.array_equal(va, vb)
    else:
        assert not np.array_equal(va[:, other[other < 30]], vb[:, other[other < 30]])


# ------------------------------------------------------------------------------ the drawn case
class _TwoBody:
    """track_ecef_km of the two-body stand-in: every satellite on the same track (B plans alone)."""

    def track_ecef_km(self, name, t_s):
        return track(np.asarray(t_s, float))


@pytest.mark.parametrize("model", ["region-truth", "observed"])
def test_a_flood_seen_by_one_satellite_makes_the_next_choose_it(model):
    """Two GPs under sat B's track, B has time for one look. The forecast (and the field at the epoch)
    prefers GP 1; a flood appears at GP 0 after the epoch. Sat A saw it; its bundle's inference makes
    B choose GP 0. Without the bundle B chooses GP 1."""
    gp = gp_ecef(np.array([0.3, -0.3]), np.array([0.0, 0.0]))
    n_slots = 8
    truth = np.tile(np.array([[50, 60]], np.int16), (n_slots, 1))
    truth[1:, 0] = 250                                          # the flood, from slot 1 on
    fc = np.tile(np.array([[50, 60]], np.int16), (n_slots, 1))
    f = _field(truth, fc)
    f.lat_deg[:] = [0.3, -0.3]
    settings = PlannerSettings(dp_step_s=1.0, plan_lookahead_s=10.0, for_off_nadir_deg=55.0, revisit_zero_s=900.0,
                               footprint_km=8.0)
    planner = Planner(_TwoBody(), gp, PAPER_SLEW, settings)
    t_b = 2 * 900.0 + 100.0                                    # B plans in slot 2, both GPs in view
    # shift the track so that B passes over the GPs at t_b (track passes lat 0 at t = 0)
    planner.constellation = type("C", (), {"track_ecef_km": lambda self, n, t: track(np.asarray(t) - t_b - 3.0)})()
    params = KnowledgeParams(model=model)
    xyz = gp

    def plan(with_bundle: bool):
        ks = KnowledgeState(params, "sat_22")
        if with_bundle:
            t_a = 900.0 + 300.0                                 # A saw GP 0 in slot 1
            seen = Inference("sat_21", 0, int(t_a * 1e9), 250.0 * 0.97, 0, omega=math.log(250 * 0.97 / 50))
            ks.learn(decode_inference(encode_inference(seen)))  # through the bundle payload
        kn = ks.knowledge(f, np.zeros(2, int), xyz, t_b, [], None if model == "observed" else
                          Belief(seed=1, sat_name="sat_22", n_gp=2, n_slots=n_slots, sigma_min=0.0, sigma_max=0.0))
        p = planner.plan("sat_22", t_b, 10.0, kn)
        return [g for g, _ in p.as_list()]

    assert plan(False) == [1]
    assert plan(True) == [0]


def test_knowledge_state_keeps_each_inference_once_and_the_newest_region_time():
    ks = KnowledgeState(KnowledgeParams(model="region-truth"), "sat_11")
    inf = Inference("sat_12", 4, 5 * 10 ** 9, 10.0, 2)
    assert ks.learn(inf) and not ks.learn(inf)
    ks.learn(Inference("sat_13", 5, 3 * 10 ** 9, 10.0, 2))
    assert len(ks) == 2 and ks.info_time_s(2, 100.0) == 5.0 and ks.info_time_s(1, 100.0) == 0.0
    assert KnowledgeState(KnowledgeParams(model="oracle"), "x").info_time_s(2, 100.0) == 100.0
    # the known observations for Eq. 1 pass through untouched
    known = [KnownObservation(5.0, 4, "sat_12")]
    f = _field(np.ones((4, 6), np.int16), regions=np.array([0, 0, 1, 1, 2, 2]))
    assert ks.knowledge(f, f.region_index, np.zeros((6, 3)), 10.0, known, None).known is known
