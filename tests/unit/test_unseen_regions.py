"""A region no satellite can see over the horizon is named - at the start of a run, in report.json
(``coverage.regions_never_in_view``, ``warnings``) and when the report is rebuilt from the bag - instead
of a silent value 0 (bringup/analysis/report.py ``regions_never_in_view``).

Oracle: geometry. One satellite for 72 s sees the region under it at the epoch and cannot see the
region at its antipode, on the other side of the Earth.
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np

from bringup.scenario.config import load_scenario
from bringup.scenario.toml_text import to_toml
from orbit_clock import ecef_to_geodetic
from tests.scenario_edit import raw_scenario


def test_the_antipode_is_named_and_the_run_warns(tmp_path):
    from orbit_clock.propagation import build_constellation

    sc = load_scenario("paper").with_overrides(sats=1, hours=0.02)
    lat, lon, _ = ecef_to_geodetic(build_constellation(sc).positions_ecef_km(np.array([0.0]))[0])
    lat0, lon0 = float(np.ravel(lat)[0]), float(np.ravel(lon)[0])
    raw = raw_scenario(sc)
    raw["regions"]["list"] = [
        {"name": "Below", "lat_deg": lat0, "lon_deg": lon0, "size_km": 40.0},
        {"name": "Antipode", "lat_deg": -lat0, "lon_deg": (lon0 + 360.0) % 360.0 - 180.0, "size_km": 40.0}]
    path = tmp_path / "two.toml"
    path.write_text(to_toml(raw))
    out = tmp_path / "run"
    r = subprocess.run([sys.executable, "-m", "bringup.cli", "run", "--engine", "local", "--scenario", str(path),
                        "--out", str(out), "--no-progress"], capture_output=True, text=True, timeout=300,
                       check=False)
    assert r.returncode == 0, r.stderr
    assert "warning: no satellite has region(s) Antipode in its field of regard" in r.stderr
    rep = json.loads((out / "report.json").read_text())
    assert rep["coverage"]["regions_never_in_view"] == ["Antipode"]
    assert any("Antipode" in w for w in rep["warnings"])
    from bringup.analysis.report import report_from_bag

    warned: list[str] = []
    report_from_bag(out / "bag", warn=warned.append)
    assert any("Antipode" in w for w in warned)
