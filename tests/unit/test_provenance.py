"""Provenance (bringup/scenario/provenance.py): a run's report.json and its bag carry the resolved
scenario, version, commit, command, Python and dependency versions; the scenario TOML loads back to
the scenario run; ``constellation --version`` prints pyproject's version."""

from __future__ import annotations

import json
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest
from scenario_edit import raw_scenario

import bringup
from bringup.scenario.config import load_scenario
from bringup.scenario.overrides import apply_sets
from bringup.scenario.provenance import NOT_GIT, git_state, provenance, scenario_toml

ROOT = Path(bringup.__file__).resolve().parents[1]
KEYS = {"scenario_toml", "version", "git_commit", "command", "python", "dependencies", "seed"}


def test_version_is_pyprojects_and_the_cli_prints_it(capsys):
    want = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]
    assert bringup.__version__ == want
    from bringup.cli.main import main

    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0 and capsys.readouterr().out.strip() == f"constellation {want}"


def test_git_commit_is_what_git_says():
    r = subprocess.run(["git", "-C", str(ROOT), "log", "-1", "--format=%H"], capture_output=True, text=True,
                       check=False)
    commit, dirty = git_state()
    if r.returncode == 0:
        assert commit == r.stdout.strip() and dirty in (True, False)
    else:
        assert commit == NOT_GIT


def test_scenario_toml_loads_back_to_the_scenario(paper_scenario, tmp_path):
    sc = apply_sets(paper_scenario.with_overrides(sats=6, hours=0.5, seed=4, knowledge="observed"),
                    ["isl.rate_bps=250", "regions.list[1].size_km=40", "acs.slew_coeffs_s=[1.0, 0.25]"])
    path = tmp_path / "elsewhere" / "s.toml"
    path.parent.mkdir()
    path.write_text(scenario_toml(sc))
    assert raw_scenario(load_scenario(path)) == raw_scenario(sc)


def test_relative_data_files_are_made_absolute(paper_scenario, tmp_path):
    src = tmp_path / "study" / "sc.toml"
    src.parent.mkdir()
    raw = raw_scenario(paper_scenario)
    raw["value"].update(osse_source="file", osse_file="fields/truth.npz")
    from scenario_edit import to_toml

    src.write_text(to_toml(raw))
    sc = load_scenario(src)
    back = load_scenario(_write(tmp_path / "copy.toml", scenario_toml(sc)))
    assert back.value.osse_file == str(src.parent / "fields" / "truth.npz")
    raw_back, raw_sc = raw_scenario(back), raw_scenario(sc)
    raw_back["value"]["osse_file"] = raw_sc["value"]["osse_file"]
    assert raw_back == raw_sc


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def test_provenance_keys(paper_scenario):
    p = provenance(paper_scenario, ["run", "--seed", "3"])
    assert KEYS <= set(p) and p["command"] == "constellation run --seed 3"
    assert p["python"] == ".".join(map(str, sys.version_info[:3]))
    assert p["dependencies"]["numpy"] == __import__("numpy").__version__
    assert p["dependencies"]["sgp4"] and p["seed"] == 1


def test_a_runs_report_and_bag_hold_the_provenance(tmp_path):
    """A local run with --set: report.json's provenance, OUT/scenario.toml, and the report rebuilt
    from the bag alone (`constellation report BAG`) give the same provenance."""
    out = tmp_path / "run"
    cmd = [sys.executable, "-m", "bringup.cli", "run", "--engine", "local", "--sats", "6", "--hours", "0.25",
           "--seed", "2", "--no-plots", "--no-progress", "--set", "isl.rate_bps=250", "--out", str(out)]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=300, check=False)
    assert r.returncode == 0, r.stderr[-2000:]
    rep = json.loads((out / "report.json").read_text())
    p = rep["provenance"]
    assert KEYS <= set(p)
    assert p["command"].endswith("--set isl.rate_bps=250 --out " + str(out)) and p["seed"] == 2
    assert p["version"] == bringup.__version__ and p["git_commit"] == git_state()[0]
    assert (out / "scenario.toml").read_text() == p["scenario_toml"]
    sc = load_scenario(out / "scenario.toml")
    want = apply_sets(load_scenario("paper").with_overrides(sats=6, hours=0.25, seed=2), ["isl.rate_bps=250"])
    assert raw_scenario(sc) == raw_scenario(want) and sc.isl.rate_bps == 250.0
    b = subprocess.run([sys.executable, "-m", "bringup.cli", "report", str(out / "bag")], capture_output=True,
                       text=True, timeout=120, check=False)
    assert b.returncode == 0, b.stderr
    assert json.loads(b.stdout)["provenance"] == p


def test_drawn_regions_round_trip(paper_scenario, tmp_path):
    """Regions given as a bounding box and as GeoJSON polygons (bringup/scenario/regions_geojson.py)
    are written into the scenario TOML and load back the same."""
    from bringup.scenario.regions_geojson import regions_arg

    gj = tmp_path / "basin.geojson"
    gj.write_text(json.dumps({"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {"name": "basin"},
         "geometry": {"type": "Polygon", "coordinates": [[[10.0, 20.0], [10.6, 20.1], [10.3, 20.7], [10.0, 20.0]]]}},
        {"type": "Feature", "properties": {"name": "two"},
         "geometry": {"type": "MultiPolygon", "coordinates": [[[[0.0, 0.0], [0.4, 0.0], [0.4, 0.4], [0.0, 0.0]]],
                                                              [[[1.0, 1.0], [1.3, 1.0], [1.3, 1.2], [1.0, 1.0]]]]}}]}))
    for regions in (regions_arg("10,20,11,21"), regions_arg(str(gj))):
        sc = paper_scenario.with_overrides(regions=regions)
        back = load_scenario(_write(tmp_path / "back.toml", scenario_toml(sc)))
        assert raw_scenario(back) == raw_scenario(sc)
