"""Shared fixtures: paths to the study's inputs and the scenario."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
# the study's inputs, kept in the repository (tests/fixtures/paper_inputs/README.md); PAPER_INPUTS overrides
PAPER_INPUTS = Path(os.environ.get("PAPER_INPUTS", REPO / "tests" / "fixtures" / "paper_inputs"))

# Every ROS process a test starts stays on loopback (docs/design.md section 7: network safety).
os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"


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
