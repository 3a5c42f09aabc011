"""Mixed fleets (bringup/scenario/fleet.py): a Walker shell beside catalogue satellites with their
own payload and radio, through the scenario, the world, the access search, the ISL plan and the
planner.

Oracles: the per-satellite code paths against the established one-value paths run satellite by
satellite (access windows with one field of regard per satellite = the windows of each satellite
alone with its own, and = the brute-force grid; the ISL windows of each pair = the windows with that
pair's shorter range alone; a planner instance's FOR mask = ``for_mask`` at the satellite's own
angle); the scenario's rules checked key by key (one line naming the key).
"""

from __future__ import annotations

import csv
import datetime as dt
import json

import numpy as np
import pytest

from bringup.cli.main import main
from bringup.scenario.config import SCENARIO_DIR, ScenarioError, load_scenario
from bringup.scenario.world import World, for_deg_per_sat, scenario_key
from orbit_clock import access_windows, access_windows_bruteforce, build_constellation, ground_points
from orbit_clock.access import for_mask
from orbit_clock.frames import ecef_to_geodetic
from orbit_clock.isl import isl_windows
from tests.catalogue_files import write_tle

NAMES = ["sat_11", "sat_12", "sat_21", "sat_22", "sat_n40697", "sat_n42063", "sat_n60989"]


def _mixed_text(tle: str, *, epoch: str = "", horizon_s: float = 3600.0, regions: str = "", extra: str = "") -> str:
    """A 4-satellite Walker shell + the TLE file's satellites with their own FOR (30 deg), ISL."""
    return f"""
[scenario]
name = "mixed"
{f'epoch_utc = "{epoch}"' if epoch else ''}
horizon_s = {horizon_s}

[[constellation]]
total_sats = 4
planes = 2
altitude_km = 710.0
inclination_deg = 98.5

[[constellation]]
tle_file = "{tle}"
{extra}
[constellation.instrument]
for_off_nadir_deg = 30.0
footprint_km = 12.0

[constellation.acs]
slew_margin_s = 2.0

[constellation.isl]
rate_bps = 500.0
max_range_km = 4000.0

[acs]
slew_coeffs_s = [6.1974e-6, 1.3904e-3, 1.4165e-1, 4.6231]
slew_margin_s = 0.4232

[regions]
gp_spacing_km = 10.0
{regions or '''
[[regions.list]]
name = "London"
lat_deg = 51.5
lon_deg = -0.1
size_km = 40.0
'''}
"""


def _regions_under_tracks(tle_path, times_s=(200.0, 500.0, 1500.0, 2500.0)) -> str:
    """Regions 150 km beside the catalogue satellites' sub-satellite points at a few times (so that
    the 30-deg satellites have access in a short run)."""
    sc = load_scenario("sentinel2").with_catalogue(tle=[str(tle_path)])
    c = build_constellation(sc)
    out = []
    for t in times_s:
        r = c.positions_ecef_km(np.array([t]))[:, 0, :]
        for k, rr in enumerate(r):
            lat, lon = (float(x) for x in ecef_to_geodetic(rr)[:2])
            lon = (lon + 1.5 + 180.0) % 360.0 - 180.0
            out.append(f'[[regions.list]]\nname = "r{int(t)}_{k}"\nlat_deg = {lat:.4f}\nlon_deg = {lon:.4f}\n'
                       f"size_km = 40.0\n")
    return "\n".join(out)


@pytest.fixture(scope="module")
def mixed(tmp_path_factory):
    d = tmp_path_factory.mktemp("fleet")
    tle = write_tle(d / "s2.tle")
    path = d / "mixed.toml"
    path.write_text(_mixed_text("s2.tle", regions=_regions_under_tracks(tle)))
    return load_scenario(path)


def test_names_order_labels_and_parameters(mixed):
    sc = mixed
    assert sc.sat_names == NAMES and sc.n_sats == 7
    p = sc.sat_params
    assert [q.for_off_nadir_deg for q in p] == [55.0] * 4 + [30.0] * 3
    assert [q.isl_rate_bps for q in p] == [1000.0] * 4 + [500.0] * 3
    assert [q.isl_max_range_km for q in p] == [6000.0] * 4 + [4000.0] * 3
    assert [q.footprint_km for q in p] == [8.0] * 4 + [12.0] * 3
    assert [q.slew_margin_s for q in p] == [0.4232] * 4 + [2.0] * 3
    assert {q.slew_coeffs_s for q in p} == {(6.1974e-6, 1.3904e-3, 1.4165e-1, 4.6231)}  # the scenario's [acs]
    # no epoch given: the newest element set's (SENTINEL-2A 07:09:57.007008), up to the second
    assert sc.epoch == dt.datetime(2026, 10, 1, 7, 9, 58, tzinfo=dt.UTC) and sc.epoch_iso == "2026-10-01T07:09:58Z"


def test_the_example_scenario_loads():
    sc = load_scenario("sentinel2")
    assert sc.sat_names == NAMES and (SCENARIO_DIR / "sentinel2.tle").is_file()


def test_access_with_one_field_of_regard_per_satellite(mixed):
    sc = mixed
    c, g = build_constellation(sc), ground_points(sc)
    lims = for_deg_per_sat(sc)
    both = access_windows(c, g, 0.0, 3600.0, lims)
    assert both.max_off_nadir_deg == [55.0] * 4 + [30.0] * 3
    cat = np.isin(both.sat, [4, 5, 6])
    assert cat.sum() > 5 and (both.min_off_nadir_deg[cat] <= 30.0).all()
    for s in range(7):
        alone = access_windows(c, g, 0.0, 3600.0, float(lims[s]), sats=[s])
        mine = both.sat == s
        assert np.array_equal(alone.gp, both.gp[mine]) and np.array_equal(alone.start_s, both.start_s[mine])
    # a wider FOR would see more: the satellite's own limit is what bounds its windows
    wide = access_windows(c, g, 0.0, 3600.0, 55.0, sats=[4, 5, 6])
    assert len(wide) > cat.sum()
    brute = access_windows_bruteforce(c, g, 0.0, 3600.0, lims, sats=[4, 5, 6])
    assert np.array_equal(brute.gp, both.gp[cat])
    assert np.abs(brute.start_s - both.start_s[cat]).max() < 1.0


def test_isl_windows_take_the_shorter_range_and_the_lower_rate(mixed):
    sc = mixed
    c = build_constellation(sc)
    rng = np.array([q.isl_max_range_km for q in sc.sat_params])
    i, j, st, en = isl_windows(c, 0.0, 3600.0, max_range_km=rng)
    got: dict = {}
    for a, b, x, y in zip(i, j, st, en):
        got.setdefault((int(a), int(b)), []).append((float(x), float(y)))
    n_checked = 0
    for a in range(7):
        for b in range(a + 1, 7):
            pair_rng = min(rng[a], rng[b])
            si, sj, ss, se = isl_windows(c, 0.0, 3600.0, max_range_km=float(pair_rng))
            k = (si == a) & (sj == b)
            want = [(float(x), float(y)) for x, y in zip(ss[k], se[k])]
            assert got.get((a, b), []) == want, (a, b)
            n_checked += bool(want)
    assert n_checked >= 3
    plan = World.build(sc.with_overrides(hours=1.0)).isl_plan
    rate = {n: q.isl_rate_bps for n, q in zip(sc.sat_names, sc.sat_params)}
    assert plan.contacts and all(x.rate_bps == min(rate[x.src], rate[x.dst]) for x in plan.contacts)
    assert any(x.rate_bps == 500.0 for x in plan.contacts)


def test_planner_uses_each_satellites_own_field_of_regard(mixed):
    w = World.build(mixed.with_overrides(hours=1.0))
    pl = w.planner
    assert set(pl.own) == {"sat_n40697", "sat_n42063", "sat_n60989"}
    from sat_node.scheduler.planner import Knowledge, PersistenceView

    k = Knowledge(PersistenceView(w.osse, 0.0))
    seen = 0
    for name in NAMES:
        for t0 in (0.0, 1200.0, 2400.0):
            p = pl.instance(name, t0, k, window_s=600.0)
            lim = 30.0 if name.startswith("sat_n") else 55.0
            pos = w.constellation.track_ecef_km(name, t0 + np.arange(600.0))
            assert np.array_equal(p.in_for, for_mask(pos, w.gps.ecef_km[p.gp_ids], lim))
            assert p.slew.margin_s == (2.0 if name.startswith("sat_n") else 0.4232)
            seen += int(p.in_for.any() and name.startswith("sat_n"))
    assert seen >= 2
    # the non-agile baseline images the satellite's own footprint
    assert pl._settings_of("sat_n40697").footprint_km == 12.0 and pl._settings_of("sat_11").footprint_km == 8.0


def test_world_pickles_and_its_key_follows_the_file(tmp_path):
    tle = write_tle(tmp_path / "s2.tle")
    path = tmp_path / "m.toml"
    path.write_text(_mixed_text("s2.tle"))
    sc = load_scenario(path)
    w = World.cached(sc.with_overrides(hours=0.25), tmp_path / "cache")
    w2 = World.cached(sc.with_overrides(hours=0.25), tmp_path / "cache")  # loaded from the pickle
    t = np.array([0.0, 500.0])
    assert np.array_equal(w.constellation.positions_ecef_km(t), w2.constellation.positions_ecef_km(t))
    k1 = scenario_key(sc)
    text = tle.read_text().replace("SENTINEL-2C", "SENTINEL-2C (renamed)")
    tle.write_text(text)
    sc2 = load_scenario(path)
    assert scenario_key(sc2) != k1 and sc2.sat_params == sc.sat_params
    assert sc2.sat_names == NAMES
    from bringup.scenario import fleet

    assert fleet.resolve(sc2).labels[-1] == "SENTINEL-2C (renamed)"  # the edited file, read again


@pytest.mark.parametrize("change,key,needle", [
    (lambda t: t.replace('name = "mixed"', 'name = "mixed"\nepoch_utc = "2026-10-20T00:00:00Z"'),
     "scenario.epoch_utc", "outside the element sets' validity (7 days"),
    (lambda t: t.replace('tle_file = "s2.tle"', 'tle_file = "s2.tle"\ntotal_sats = 3'),
     "constellation[1].total_sats", "takes no Walker keys"),
    (lambda t: t.replace('tle_file = "s2.tle"', 'tle_file = "s2.tle"\nomm_file = "x.json"'),
     "constellation[1].omm_file", "one file"),
    (lambda t: t.replace('tle_file = "s2.tle"', 'tle_file = "s2.tle"\nnorad_ids = [12345]'),
     "constellation[1].norad_ids", "NORAD 12345 is not in s2.tle"),
    (lambda t: t.replace('tle_file = "s2.tle"', 'tle_file = "none.tle"'),
     "constellation[1].tle_file", "none.tle: cannot read"),
    (lambda t: t.replace('[[constellation]]\ntle_file', '[[constellation]]\ntotal_sats = 2\nplanes = 1\n'
                         'altitude_km = 600.0\ninclination_deg = 50.0\n\n[[constellation]]\ntle_file'),
     "constellation[1].pattern", "a second Walker shell"),
    (lambda t: t.replace("rate_bps = 500.0", "rate_bps = -5.0"), "constellation[1].isl.rate_bps", "> 0"),
    (lambda t: t + '\n[[constellation]]\ntle_file = "s2.tle"\nnorad_ids = [42063]\n',
     "constellation[2].norad_ids", "sat_n42063 is also in constellation group 1"),
    (lambda t: t.replace("for_off_nadir_deg = 30.0", "for_off_nadir_deg = 95.0"),
     "constellation[1].instrument.for_off_nadir_deg", "< 90"),
])
def test_bad_fleets_are_one_line_naming_the_key(tmp_path, change, key, needle):
    write_tle(tmp_path / "s2.tle")
    path = tmp_path / "m.toml"
    path.write_text(change(_mixed_text("s2.tle")))
    with pytest.raises(ScenarioError) as exc:
        load_scenario(path)
    msg = str(exc.value)
    assert "\n" not in msg and msg.startswith(f"{path}: key '{key}'") and needle in msg, msg


def test_norad_ids_select_and_walker_overrides_refused(tmp_path):
    write_tle(tmp_path / "s2.tle")
    path = tmp_path / "m.toml"
    path.write_text(_mixed_text("s2.tle", extra="norad_ids = [60989, 40697]"))
    sc = load_scenario(path)
    assert sc.sat_names == NAMES[:4] + ["sat_n60989", "sat_n40697"]
    assert sc.with_overrides(sats=6).sat_names[:6] == ["sat_11", "sat_12", "sat_13", "sat_21", "sat_22", "sat_23"]
    only = sc.with_catalogue(tle=[str(tmp_path / "s2.tle")])
    with pytest.raises(ScenarioError, match="--sats / --planes size a Walker shell"):
        only.with_overrides(sats=6)


def test_constellation_command_lists_a_mixed_fleet(tmp_path, mixed):
    out = tmp_path / "c.json"
    assert main(["constellation", "--scenario", mixed.source_path, "--out", str(out)]) == 0
    doc = json.loads(out.read_text())
    assert [s["name"] for s in doc["satellites"]] == NAMES and doc["epoch_utc"] == "2026-10-01T07:09:58Z"
    s2a = doc["satellites"][4]
    assert s2a["label"] == "SENTINEL-2A" and s2a["norad"] == 40697 and s2a["for_off_nadir_deg"] == 30.0
    assert s2a["epoch_utc"] == "2026-10-01T07:09:57.007008Z" and doc["satellites"][0]["plane"] == 1
    tle = write_tle(tmp_path / "only.tle")
    out2 = tmp_path / "c.csv"
    assert main(["constellation", "--tle", str(tle), "--format", "csv", "--out", str(out2)]) == 0
    rows = list(csv.DictReader(out2.open()))
    assert [r["name"] for r in rows] == NAMES[4:] and rows[2]["label"] == "SENTINEL-2C"


def test_epoch_without_elements_is_the_studys(tmp_path):
    text = (SCENARIO_DIR / "paper.toml").read_text().replace('epoch_utc = "2000-01-01T11:59:28Z"', "")
    assert "epoch_utc" not in text.split("[constellation]")[0].split("[scenario]")[1].replace("# Scenario epoch", "")
    path = tmp_path / "p.toml"
    path.write_text(text)
    assert load_scenario(path).epoch == load_scenario("paper").epoch == dt.datetime(2000, 1, 1, 11, 59, 28,
                                                                                      tzinfo=dt.UTC)


def test_tle_flag_reaches_the_ros_engines_processes(tmp_path):
    """`run --tle FILE --engine ros`: every process loads the scenario from the run spec, with the
    file (an absolute path) in its overrides, and flies the same satellites at the same epoch."""
    import argparse

    from bringup.cli.common import add_knowledge_args, add_scenario_args, overrides_of, scenario_from_args
    from bringup.engine.ros.run_spec import RunSpec

    tle = write_tle(tmp_path / "s2.tle")
    p = argparse.ArgumentParser()
    add_scenario_args(p)
    add_knowledge_args(p)
    args = p.parse_args(["--scenario", "paper", "--tle", str(tle), "--hours", "0.5"])
    here = scenario_from_args(args)
    spec = RunSpec(factory="a:b", roles=["sat_n40697"], scenario="paper", overrides=overrides_of(args))
    there = msgspec_roundtrip(spec).load_scenario()
    assert here.sat_names == there.sat_names == NAMES[4:]
    assert here.epoch == there.epoch and here.scenario.horizon_s == there.scenario.horizon_s == 1800.0


def msgspec_roundtrip(spec):
    import msgspec

    return msgspec.json.decode(msgspec.json.encode(spec), type=type(spec))
