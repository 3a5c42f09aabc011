"""The world cache: load == build; the scenario reaches every satellite's agent."""

from __future__ import annotations

import numpy as np
import pytest

from bringup.scenario.world import World, scenario_key
from tests.keys import TEST_BPSEC_KEY


@pytest.fixture(scope="module")
def world(paper_scenario):
    return World.build(paper_scenario.with_overrides(sats=6, hours=2))


def test_save_load_round_trip(world, tmp_path):
    p = world.save(tmp_path / "w.pkl")
    w2 = World.load(p, world.key)
    assert w2.isl_plan.contacts == world.isl_plan.contacts
    assert w2.ground_plan.contacts == world.ground_plan.contacts
    np.testing.assert_array_equal(w2.osse.values, world.osse.values)
    np.testing.assert_array_equal(w2.access.start_s, world.access.start_s)
    np.testing.assert_allclose(w2.sat_positions_ecef_km(1234.5), world.sat_positions_ecef_km(1234.5))
    with pytest.raises(ValueError, match="another scenario"):
        World.load(p, "0" * 16)


def test_key_changes_with_any_field(paper_scenario):
    assert scenario_key(paper_scenario) != scenario_key(paper_scenario.with_overrides(seed=2))
    assert scenario_key(paper_scenario) == scenario_key(paper_scenario.with_overrides(seed=1))


def test_key_does_not_depend_on_how_the_scenario_was_made(world, tmp_path):
    """Pickled (as world.pkl), or written as TOML and read back: the same scenario, the same key
    (msgspec.to_builtins leaves out an omit_defaults field only when it holds the default object)."""
    import pickle
    import tomllib

    from bringup.scenario.config import _validate
    from bringup.scenario.provenance import scenario_toml

    sc = world.scenario
    again = pickle.loads(pickle.dumps(sc))
    back = _validate(tomllib.loads(scenario_toml(sc)), "<test>")
    assert scenario_key(again) == scenario_key(sc) == scenario_key(back) == world.key
    w2 = World.load(world.save(tmp_path / "w.pkl"), world.key)
    assert scenario_key(w2.scenario) == world.key


def test_satellite_agents_take_the_scenario_send_order_and_hop_tolerance(world):
    """[isl] send_order / hop_tolerance_s reach every satellite's bundle agent (both engines build
    satellites this way); the paper's defaults are the study's strict priority and earliest arrival."""
    import dataclasses

    import msgspec

    from sat_node.dtn.agent import deadline_delays
    from sat_node.satellite import SatelliteLogic

    sat = world.sat_names[0]
    cfg = SatelliteLogic(world, sat, "distributed", bpsec_key=TEST_BPSEC_KEY).agent.config
    assert cfg.priority_delay_s is None and cfg.hop_tolerance_s == 0.0
    sc = world.scenario
    isl = msgspec.structs.replace(sc.isl, send_order="deadline", hop_tolerance_s=30.0)
    w2 = dataclasses.replace(world, scenario=msgspec.structs.replace(sc, isl=isl))
    cfg = SatelliteLogic(w2, sat, "distributed", bpsec_key=TEST_BPSEC_KEY).agent.config
    assert cfg.hop_tolerance_s == 30.0
    assert cfg.priority_delay_s == deadline_delays(cfg.ttl_s_by_priority)
    assert cfg.priority_delay_s[0] == isl.ttl_p1_s and cfg.priority_delay_s[14] == isl.ttl_p4_15_s


def test_satellite_agents_take_the_scenario_forwarding(world):
    """[isl] forwarding: multicast (the default) gives every satellite the multicast agent, unicast the
    one-bundle-per-recipient agent of the study's simulator."""
    import dataclasses

    import msgspec

    from sat_node.dtn.agent import BundleAgent
    from sat_node.dtn.multicast import MulticastAgent
    from sat_node.satellite import SatelliteLogic

    sat = world.sat_names[0]
    assert world.scenario.isl.forwarding == "multicast"
    ag = SatelliteLogic(world, sat, "distributed", bpsec_key=TEST_BPSEC_KEY).agent
    assert type(ag) is MulticastAgent and ag.config.forwarding == "multicast"
    isl = msgspec.structs.replace(world.scenario.isl, forwarding="unicast")
    w2 = dataclasses.replace(world, scenario=msgspec.structs.replace(world.scenario, isl=isl))
    assert type(SatelliteLogic(w2, sat, "distributed", bpsec_key=TEST_BPSEC_KEY).agent) is BundleAgent


def test_satellite_bundles_carry_dtn_time_of_the_scenario_clock(world):
    """A satellite's bundles are created at DTN time (RFC 9171 4.2.6: ms since 2000-01-01T00:00:00Z)
    of the scenario clock: the study's epoch by default, ``--epoch``'s instant (scenario.epoch_utc)
    otherwise - what lets a real DTN node accept them while they live."""
    import dataclasses
    from datetime import UTC, datetime

    import msgspec

    from sat_node.dtn.bpv7 import PAPER_EPOCH_DTN_MS
    from sat_node.satellite import SatelliteLogic

    sat = world.sat_names[0]
    assert SatelliteLogic(world, sat, "distributed", bpsec_key=TEST_BPSEC_KEY).agent.config.epoch_dtn_ms \
        == PAPER_EPOCH_DTN_MS
    sc = world.scenario
    later = msgspec.structs.replace(sc, scenario=msgspec.structs.replace(sc.scenario, epoch_utc="2026-11-27T12:00:00Z"))
    agent = SatelliteLogic(dataclasses.replace(world, scenario=later), sat, "distributed",
                           bpsec_key=TEST_BPSEC_KEY).agent
    want = int((datetime(2026, 11, 27, 12, tzinfo=UTC) - datetime(2000, 1, 1, tzinfo=UTC)).total_seconds()) * 1000
    assert agent.config.epoch_dtn_ms == want
    bid = agent.originate(b"obs", world.sat_names[1], 1, 90 * 10**9)
    assert bid.split("-")[1] == str(want + 90_000)  # the bundle ID: source, creation time [ms], sequence
