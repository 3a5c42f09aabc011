"""Shared fixtures: paths to the study's inputs and the scenario; the globe page's ``chromium`` and
``cesium_modules`` (tests/globe_page.py), for tests/browser and tests/containers."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import pytest
from globe_page import cesium_modules, chromium  # noqa: F401

REPO = Path(__file__).resolve().parents[1]
# the study's inputs, kept in the repository (tests/fixtures/paper_inputs/README.md); PAPER_INPUTS overrides
PAPER_INPUTS = Path(os.environ.get("PAPER_INPUTS", REPO / "tests" / "fixtures" / "paper_inputs"))

# Every ROS process a test starts stays on loopback (docs/design.md section 7: network safety).
os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
# Bags the tests' runs write are sealed under a key of the tests' own (bringup/recording/bag_seal.py),
# not under the user's ~/.config key
os.environ.setdefault("AGILE_DTN_SEAL_KEY_FILE",
                      os.path.join(tempfile.gettempdir(), f"agile_dtn_test_seal-{os.geteuid()}", "bag-seal.key"))


def pytest_sessionstart(session) -> None:
    """Free the FastDDS shared-memory files earlier runs on this machine left and no live process
    holds (bringup/engine/ros/shm_cleanup.py: hundreds of them made ROS runs hang at start)."""
    from bringup.engine.ros.shm_cleanup import remove_unheld

    remove_unheld()


@pytest.fixture(scope="session")
def paper_inputs() -> Path:
    if not (PAPER_INPUTS / "contact_plan_3p_8s.csv").exists():
        raise FileNotFoundError(f"the study's inputs are missing: {PAPER_INPUTS} (set PAPER_INPUTS)")
    return PAPER_INPUTS


@pytest.fixture(scope="session")
def paper_scenario():
    from bringup.scenario.config import load_scenario

    return load_scenario("paper")
