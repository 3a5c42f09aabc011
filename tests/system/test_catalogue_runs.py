"""Whole runs of real satellites (issue 32, item 1): the Sentinel-2 satellites from their TLEs and
from the same elements as CCSDS OMM, and a mixed fleet (a Walker shell + catalogue satellites with
their own field of regard) on both engines.

Oracles:
* formats - TLE and OMM (XML, KVN, JSON) files of the same elements give byte-identical access
  windows and contact plans (``constellation access`` / ``contacts``) and identical runs (report,
  observations and bundle deliveries from the bags);
* skyfield (an independent TLE reader, SGP4 driver, Earth frame and WGS-84 site model): for every
  (satellite, GP) of the run, the off-nadir angle written out from skyfield's ITRS positions on a
  1-s grid gives the same access windows within 2 s;
* engines - the mixed fleet's ROS run (real rclpy nodes over DDS) equals its local run: report
  (runtime and engine aside), observations and deliveries.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tests.catalogue_files import write_omm, write_tle

pytestmark = [pytest.mark.system]

HORIZON_S = 900.0


def _regions(times_s=(200.0, 400.0, 600.0, 800.0)) -> str:
    """Regions 1.5 deg of longitude beside the two satellites' tracks at a few times of the run
    (skyfield's sub-satellite points), so that their 30-deg fields of regard reach them in 15 min."""
    import datetime as dt

    from skyfield.api import EarthSatellite, load, wgs84

    from tests.catalogue_files import S2

    ts = load.timescale()
    sats = [EarthSatellite(l1, l2, n, ts) for n, l1, l2 in S2[:2]]
    newest = max(s.epoch.utc_datetime() for s in sats)
    t0 = newest.replace(microsecond=0) + dt.timedelta(seconds=1)  # the run's epoch (fleet.default_epoch)
    out = []
    for t in times_s:
        for k, s in enumerate(sats):
            p = wgs84.subpoint_of(s.at(ts.from_datetime(t0 + dt.timedelta(seconds=t))))
            lon = (p.longitude.degrees + 1.5 + 180.0) % 360.0 - 180.0
            out.append(f'[[regions.list]]\nname = "r{int(t)}_{k}"\nlat_deg = {p.latitude.degrees:.4f}\n'
                       f"lon_deg = {lon:.4f}\nsize_km = 40.0\n")
    return "\n".join(out)


def _scenario(d: Path, walker: bool) -> Path:
    write_tle(d / "s2.tle")
    shell = """
[[constellation]]
total_sats = 4
planes = 2
altitude_km = 710.0
inclination_deg = 98.5
""" if walker else ""
    text = f"""
[scenario]
name = "{'mixed' if walker else 'sentinel'}"
horizon_s = {HORIZON_S}
{shell}
[[constellation]]
tle_file = "s2.tle"
norad_ids = [40697, 42063]

[constellation.instrument]
for_off_nadir_deg = 30.0

[constellation.isl]
rate_bps = 500.0
max_range_km = 5000.0

[acs]
slew_coeffs_s = [6.1974e-6, 1.3904e-3, 1.4165e-1, 4.6231]
slew_margin_s = 0.4232

[regions]
gp_spacing_km = 10.0

{_regions()}
[[ground.stations]]
name = "svalbard"
lat_deg = 78.2298
lon_deg = 15.4078
"""
    p = d / ("mixed.toml" if walker else "sentinel.toml")
    p.write_text(text)
    return p


def _cli(*args: str, timeout: float = 300) -> subprocess.CompletedProcess:
    r = subprocess.run([sys.executable, "-m", "bringup.cli", *args], capture_output=True, text=True,
                       timeout=timeout, check=False)
    assert r.returncode == 0, r.stderr[-3000:]
    return r


def _run(scenario: Path, out: Path, engine: str, *extra: str) -> Path:
    if engine == "local":  # in this process (the ROS engine's launcher stays a child of its own)
        from bringup.cli.main import main

        assert main(["run", "--scenario", str(scenario), "--engine", engine, "--out", str(out), "--no-plots",
                     "--no-progress", *extra]) == 0
        return out
    _cli("run", "--scenario", str(scenario), "--engine", engine, "--out", str(out), "--no-plots", "--no-progress",
         *extra, timeout=600)
    return out


def _trace(out: Path):
    from bringup.analysis.trace import deliveries_from_bag, observations_from_bag

    rep = json.loads((out / "report.json").read_text())
    rep.pop("runtime"), rep.pop("engine")
    prov = rep.pop("provenance")  # the command line and the element file's name differ by construction
    assert prov["scenario_toml"] and prov["command"].startswith("constellation run")
    return rep, observations_from_bag(out / "bag"), deliveries_from_bag(out / "bag")


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("catalogue")
    sc = _scenario(d, walker=False)
    omm = {fmt: write_omm(d / f"s2.{fmt}", fmt) for fmt in ("xml", "kvn", "json")}
    return d, sc, omm


def test_tle_and_omm_give_identical_windows_plans_and_runs(files):
    d, sc, omm = files
    from bringup.cli.main import main

    outs = {}
    for name, flag in [("tle", ["--tle", str(d / "s2.tle")])] + [(f, ["--omm", str(p)]) for f, p in omm.items()]:
        assert main(["access", "--scenario", str(sc), *flag, "--out", str(d / f"{name}.csv")]) == 0
        assert main(["contacts", "--scenario", str(sc), "--format", "ion", *flag, "--out", str(d / f"{name}.rc")]) == 0
        outs[name] = ((d / f"{name}.csv").read_text(), (d / f"{name}.rc").read_text())
    acc, plan = outs["tle"]
    assert acc.count("\n") > 20 and "sat_n40697" in acc and "sat_n42063" in acc
    assert plan.count("a contact") >= 4 and "100040697" in plan
    for f in ("xml", "kvn", "json"):
        assert outs[f] == outs["tle"], f
    # the scenario's own group (two of the three, FOR 30 deg) and the same as OMM: identical runs
    tle_run = _run(sc, d / "run_tle", "local")
    sc_omm = d / "sentinel_omm.toml"
    sc_omm.write_text(sc.read_text().replace('tle_file = "s2.tle"', 'omm_file = "s2.json"'))
    omm_run = _run(sc_omm, d / "run_omm", "local")
    (rep_t, obs_t, del_t), (rep_o, obs_o, del_o) = _trace(tle_run), _trace(omm_run)
    rep_t.pop("scenario", None), rep_o.pop("scenario", None)
    assert len(obs_t) > 20 and obs_o == obs_t and del_o == del_t and rep_o == rep_t


def test_access_windows_equal_skyfield_within_2_s(files):
    """For every (satellite, GP) of the run: windows where skyfield's off-nadir angle is within the
    30-deg field of regard, from its ITRS positions every second, edges interpolated."""
    from skyfield.api import EarthSatellite, load, wgs84
    from skyfield.framelib import itrs

    from bringup.scenario.config import load_scenario
    from bringup.scenario.world import World
    from tests.catalogue_files import S2

    _d, sc_path, _omm = files
    sc = load_scenario(sc_path)
    w = World.build(sc)
    acc, gps = w.access, w.gps
    assert len(acc) > 20
    ts = load.timescale()
    e = sc.epoch
    t = np.arange(0.0, HORIZON_S + 0.5, 1.0)
    times = ts.utc(e.year, e.month, e.day, e.hour, e.minute, e.second + t)
    site = wgs84.latlon(gps.lat_deg, gps.lon_deg, 0.0).itrs_xyz.km.T  # (n_gp, 3)
    n_cmp = 0
    for k, (name, l1, l2) in enumerate(S2[:2]):
        sat = EarthSatellite(l1, l2, name, ts).at(times).frame_xyz(itrs).km.T  # (n_t, 3)
        los = site[None, :, :] - sat[:, None, :]
        cos_eta = -np.einsum("tk,tgk->tg", sat, los) / (np.linalg.norm(sat, axis=1)[:, None]
                                                         * np.linalg.norm(los, axis=2))
        eta = np.degrees(np.arccos(np.clip(cos_eta, -1, 1)))
        near = np.einsum("tgk,gk->tg", -los, site) > 0
        inside = near & (eta <= 30.0)
        sat_idx = w.sat_names.index(f"sat_n{l1[2:7]}")
        for g in range(len(gps)):
            col = inside[:, g].astype(np.int8)
            edges = np.flatnonzero(np.diff(np.concatenate([[0], col, [0]])))
            want = []
            m = 30.0 - eta[:, g]  # >= 0 inside; edges by linear interpolation between samples
            for a, b in zip(edges[::2], edges[1::2] - 1):
                s0 = t[a] if a == 0 else t[a - 1] + m[a - 1] / (m[a - 1] - m[a])
                s1 = t[b] if b == len(t) - 1 else t[b] + m[b] / (m[b] - m[b + 1])
                want.append((s0, s1))
            m = (acc.sat == sat_idx) & (acc.gp == g)
            got = list(zip(acc.start_s[m], acc.end_s[m]))
            assert len(got) == len(want), (name, g, got, want)
            for (a0, a1), (b0, b1) in zip(got, want):
                assert abs(a0 - b0) < 2.0 and abs(a1 - b1) < 2.0, (name, g, got, want)
                n_cmp += 1
    assert n_cmp > 20


@pytest.mark.ros
def test_mixed_fleet_runs_the_same_on_both_engines(tmp_path):
    sc = _scenario(tmp_path, walker=True)
    local = _run(sc, tmp_path / "local", "local")
    ros = _run(sc, tmp_path / "ros", "ros", "--sats-per-process", "3")
    (rep_l, obs_l, del_l), (rep_r, obs_r, del_r) = _trace(local), _trace(ros)
    sats = {o[0] for o in obs_l}
    assert {"sat_n40697", "sat_n42063"} & sats and {"sat_11", "sat_12", "sat_21", "sat_22"} & sats, sats
    assert len(del_l) > 10
    assert obs_r == obs_l and del_r == del_l and rep_r == rep_l
