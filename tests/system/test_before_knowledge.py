"""Today's defaults changed the study's numbers on purpose (knowledge through the system, the 15-min
field, Nyquist GPs, joint planning); the old behaviour stays one set of settings away, so every
difference can be explained rather than lost.

Oracle: the paper scenario with the settings before those changes - ``oracle`` knowledge (the
truth at planning time), the slow storm-cell field (transiency 0), GPs at the footprint (8 km, 500
GPs), each satellite planned alone, one unicast bundle per recipient, the DP's 1-s step, Svalbard
and Troll - gives the report of the commit before them (local engine, seed
1): cumulative value 41786.93, 3334 observations, 497 of 500 GPs, 22260 bundles created and 21651
delivered (the README's figures before knowledge models).
"""

from __future__ import annotations

import msgspec
import pytest

from bringup.analysis.compare import run_in_process
from bringup.scenario.config import load_scenario

pytestmark = [pytest.mark.system]


def test_old_settings_give_the_old_report():
    sc = load_scenario("paper").with_overrides(knowledge="oracle", transiency_min=0.0, gp_spacing_km=8.0,
                                               joint_planning=False, forwarding="unicast")
    # the DP's 1-s step and the Svalbard + Troll network of those days (the study's 9-s cadence and
    # two passes an orbit came later)
    troll = msgspec.structs.replace(sc.ground.stations[0], name="troll", lat_deg=-72.0117, lon_deg=2.5350, alt_m=1270.0)
    sc = msgspec.structs.replace(sc, scheduler=msgspec.structs.replace(sc.scheduler, dp_step_s=1.0),
                                 ground=msgspec.structs.replace(sc.ground, stations=[sc.ground.stations[0], troll]))
    rep = run_in_process(sc, "distributed")
    assert rep["value"]["cumulative"] == pytest.approx(41786.929, abs=5e-3)
    assert rep["observations"]["count"] == 3334
    assert (rep["coverage"]["gp_observed"], rep["coverage"]["gp_total"]) == (497, 500)
    assert (rep["dtn"]["bundles_created"], rep["dtn"]["bundles_delivered"]) == (22260, 21651)
    assert rep["observations"]["duplicates_15min"] == 0
    assert rep["knowledge"]["model"] == "oracle"
