"""The globe page in a real browser: CesiumJS in headless Chromium loads a local run's CZML document.

Marker ``browser`` (deselected by default; `.ci/run` runs it after installing Debian's chromium with
scripts/setup_browser.sh). The page, the server and the oracle are tests/globe_page.py's: the entity
count Cesium reports equals the number of satellites, stations, looks, links and transfers the bag
holds, its clock span equals the bag's UTC span; the screenshot is kept as
build/test-artifacts/globe-local-run.png. The same check on a container run's bag is
tests/containers/test_container_run.py::test_globe_page_shows_a_container_runs_bag.
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from globe_page import check_globe_page

pytestmark = pytest.mark.browser


def test_cesium_shows_the_runs_entities_on_its_clock(tmp_path, chromium, cesium_modules):
    out = tmp_path / "run"
    r = subprocess.run([sys.executable, "-m", "bringup.cli", "run", "--engine", "local", "--sats", "12", "--hours",
                        "1", "--out", str(out), "--no-plots", "--no-progress"], capture_output=True, text=True,
                       timeout=600, check=False)
    assert r.returncode == 0, r.stderr
    counts, status = check_globe_page(out / "bag", tmp_path, chromium, cesium_modules, "globe-local-run.png")
    rep = json.loads((out / "report.json").read_text())
    assert counts["looks"] == rep["observations"]["count"] and counts["satellites"] == 12
    print(f"GLOBE local counts={json.dumps(counts)} entities={status['entities']} "
          f"span={status['start']}..{status['stop']} webgl={status['webgl']}")
