"""Shared by the whole-run knowledge tests (tests/system/test_gp_twin.py, test_knowledge_flow.py): the
paper scenario reduced to 12 satellites and 1 h on the 15-min field written to a file with its
a-priori forecast, and its runs through the CLI, each (model, mode, engine, truth file) made once a
session - both files start from the same run A of the unchanged field."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scenario_edit import raw_scenario, to_toml

SATS, HOURS = 12, 1.0


class FieldRuns:
    """Run folders of the reduced scenario on field files, by (model, mode, engine, truth)."""

    def __init__(self, tmp: Path):
        from ground_station import osse_from_scenario, write_value_grid
        from orbit_clock import ground_points

        self.tmp = tmp
        sc = self.scenario("observed")
        self.gp_region = ground_points(sc).region_index
        self.field = osse_from_scenario(sc, ground_points(sc))
        self.forecast = write_value_grid(self.field, tmp / "forecast.npz", which="forecast")
        self.truth_a = write_value_grid(self.field, tmp / "truth-a.npz")
        self._runs: dict[tuple, Path] = {}

    @staticmethod
    def scenario(model: str):
        from bringup.scenario.config import load_scenario

        return load_scenario("paper").with_overrides(sats=SATS, hours=HOURS, knowledge=model, transiency_min=15.0)

    def truth(self, values: np.ndarray, name: str) -> Path:
        """A truth file with these values (the field's GPs, slots, regions and forecast)."""
        from ground_station import write_value_grid
        from ground_station.osse import OsseField

        f = self.field
        g = OsseField(values=values, slot_s=f.slot_s, lat_deg=f.lat_deg, lon_deg=f.lon_deg,
                      region_index=f.region_index, region_names=f.region_names, forecast=f.forecast)
        return write_value_grid(g, self.tmp / f"{name}.npz")

    def run(self, model: str, mode: str = "distributed", engine: str = "local", truth: Path | None = None) -> Path:
        """The run folder (bag, report.json) of this model, mode and engine on ``truth`` (default: A)."""
        truth = Path(truth or self.truth_a)
        key = (model, mode, engine, str(truth))
        if key not in self._runs:
            tag = f"{model}-{mode}-{engine}-{truth.stem}"
            raw = raw_scenario(self.scenario(model))
            raw["value"].update(osse_source="file", osse_file=str(truth), osse_forecast_file=str(self.forecast))
            sc = self.tmp / f"{tag}.toml"
            sc.write_text(to_toml(raw))
            out = self.tmp / tag
            cmd = [sys.executable, "-m", "bringup.cli", "run", "--scenario", str(sc), "--mode", mode, "--engine",
                   engine, "--out", str(out), "--no-plots", "--no-progress"]
            r = subprocess.run(cmd, capture_output=True, text=True, timeout=900, check=False)
            assert r.returncode == 0, r.stderr[-3000:]
            self._runs[key] = out
        return self._runs[key]


@pytest.fixture(scope="session")
def field_runs(tmp_path_factory) -> FieldRuns:
    return FieldRuns(tmp_path_factory.mktemp("field_runs"))
