"""The ground segment's bundle agent (ground_station/ground_agent.py) and the downlink bundles
(sat_node/dtn/downlink.py), on a local-engine centralized run of six satellites over one hour at a
2026 epoch (polar regions added beside the paper's, so that observations precede passes).

Oracles: the downlink bundle's primary block read with cbor2 by RFC 9171 4.3.1's field order (not the
project's decoder); the ground plan searched by hand for the uplink of a peer's bundle; the ground
learns exactly the observations its downlinks carried (the msgs_json copy in the same message)."""

from __future__ import annotations

from datetime import UTC, datetime

import cbor2
import pytest
from pyd3tn.bundle7 import serialize_bundle7

from bringup.engine.local import run_local
from bringup.scenario.config import load_scenario
from bringup.scenario.participants import all_participants
from bringup.scenario.world import World
from ground_station.ground_agent import GroundAgent
from ground_station.ground_segment import GroundLogic
from msgs_json import codec
from msgs_json import schemas as S
from sat_node.dtn.bpsec import verify_bib
from sat_node.dtn.bpv7 import decode_bundle, dtn_ms_of
from sat_node.dtn.downlink import GROUND_NODE, LIFETIME_S, downlink_bundle, observation_of
from sat_node.dtn.rx_policy import admit
from sat_node.dtn.store import BundleStore
from tests.keys import TEST_BPSEC_KEY

EPOCH = "2026-11-27T14:58:00Z"
POLAR = [dict(name="Tromso", lat_deg=69.65, lon_deg=18.96, size_km=150.0),
         dict(name="Ross", lat_deg=-72.0, lon_deg=170.0, size_km=150.0),
         dict(name="Greenland", lat_deg=72.0, lon_deg=-40.0, size_km=150.0),
         dict(name="Peninsula", lat_deg=-65.0, lon_deg=-62.0, size_km=150.0)]


def gateway_scenario(epoch: str = EPOCH):
    sc = load_scenario("paper")
    regions = [{"name": r.name, "lat_deg": r.lat_deg, "lon_deg": r.lon_deg, "size_km": r.size_km}
               for r in sc.regions.list]
    return sc.with_overrides(sats=6, hours=1, epoch_utc=epoch, regions=regions + POLAR)


@pytest.fixture(scope="module")
def world():
    return World.build(gateway_scenario())


@pytest.fixture(scope="module")
def run(world):
    parts = all_participants(world, "centralized", bpsec_key=TEST_BPSEC_KEY)
    res = run_local(parts, horizon_ns=world.scenario.horizon_ns, max_step_ns=10**10)
    downs = [codec.decode(e.topic, e.data) for e in res.envelopes if e.topic == "/ground/downlink"]
    ground = next(p for p in parts if isinstance(p, GroundLogic))
    return downs, ground


def _obs(sat="sat_11", gp=7, t_ns=1_234_567_890_123):
    return S.Observation(sat=sat, gp=gp, t_ns=t_ns, assumed_value=1.5, recorded_value=2.5, schedule_version=3)


def test_downlink_bundle_fields_by_rfc9171_field_order():
    o = _obs()
    epoch_ms = dtn_ms_of(datetime(2026, 11, 27, 15, tzinfo=UTC))
    raw = downlink_bundle(o, TEST_BPSEC_KEY, epoch_ms)
    blocks = cbor2.loads(raw)  # an indefinite array of blocks (RFC 9171 4.1)
    primary = blocks[0]
    # [version, flags, crc type, destination, source, report-to, [creation, seq], lifetime, crc]
    assert primary[0] == 7
    assert primary[3] == [2, [GROUND_NODE, 1]] and primary[4] == [2, [11, 1]]
    assert primary[6] == [epoch_ms + o.t_ns // 1_000_000, 7]
    assert primary[7] == int(LIFETIME_S * 1000)
    payload = [b for b in blocks[1:] if b[0] == 1][0][4]
    assert observation_of(payload) == o  # the payload is the observation, every field
    b = decode_bundle(raw)
    verify_bib(b, TEST_BPSEC_KEY)  # signed with the constellation's key
    assert decode_bundle(downlink_bundle(o, TEST_BPSEC_KEY, epoch_ms, dest_node=2)).dest == (2, 1)


def test_ground_learns_exactly_what_the_downlink_bundles_carried(run):
    downs, ground = run
    carried = [(o.sat, o.gp, o.t_ns) for d in downs for o in d.observations]
    assert len(carried) > 20  # the polar regions put observations before passes
    assert all(len(d.bundles) == len(d.observations) for d in downs)
    learned = [(k.source, k.gp, round(k.t_s * 1e9)) for k in ground.downlinked]
    assert learned == carried
    assert ground.dtn.counters["downlink.delivered"] == len(carried)
    assert ground.dtn.held() == 0 and ground.rejected == 0


def test_a_downlink_failing_its_bib_is_dropped_and_not_learned(world):
    g = GroundLogic(world, TEST_BPSEC_KEY)
    sat = world.sat_names[0]
    o = _obs(sat=sat, gp=3, t_ns=10**9)
    good = downlink_bundle(o, TEST_BPSEC_KEY, dtn_ms_of(world.scenario.epoch))
    bad = downlink_bundle(o, b"another key of 16+ bytes", dtn_ms_of(world.scenario.epoch))
    station = world.station_nodes[0]
    for data in (bad, good, good):  # forged, then the real one, then a duplicate
        dl = S.GroundDownlink(station=station, sat=sat, t_ns=2 * 10**9, observations=[o], bundles=[data])
        g.step(2 * 10**9, [_env(dl)])
    assert [(k.source, k.gp) for k in g.downlinked] == [(sat, 3)]
    assert g.dtn.counters == {"downlink.dropped.integrity": 1, "downlink.delivered": 1,
                              "downlink.discarded.duplicate": 1}
    assert g.dtn.agent.rx_counts["rx.bib_failed"] == 1


def _env(msg):
    from msgs_json.envelope import Envelope
    return Envelope(msg.t_ns, "sat", 0, "/ground/downlink", codec.encode(msg))


def _next_uplink(world, sat: str, t_s: float) -> float:
    """By hand: the first instant >= t_s in a station-to-``sat`` contact of the world's ground plan."""
    best = None
    for c in world.ground_plan.contacts:
        if c.dst == sat and c.src.startswith("gs_") and c.end_s > t_s:
            t = max(t_s, c.start_s)
            best = t if best is None else min(best, t)
    return best


def test_a_peer_bundle_goes_up_to_the_named_satellite_at_its_next_pass(world):
    ga = GroundAgent(world, TEST_BPSEC_KEY, peer_node=2)
    sat = "sat_22"
    epoch = world.scenario.epoch
    raw = serialize_bundle7("ipn:2.1", "ipn:22.1", b"a command from the ground network", lifetime=7200,
                            creation_timestamp=epoch, sequence_number=1)
    t_in = 60 * 10**9
    assert ga.from_peer(raw, t_in) == "queued"
    ups, to_peer = ga.transmissions(world.scenario.horizon_ns)
    assert to_peer == [] and len(ups) == 1
    up = ups[0]
    assert up.sat == sat and up.station.startswith("gs_")
    assert up.t_ns == pytest.approx(_next_uplink(world, sat, t_in / 1e9) * 1e9, abs=1)
    b = decode_bundle(up.data)
    assert (b.src, b.dest, b.payload) == ((2, 1), (22, 1), b"a command from the ground network")
    assert ga.agent.rx_counts["rx.foreign_accepted"] == 1 and ga.held() == 0
    # the ground admitted it by the gateway's policy and signed it (security source ipn:100.0): the
    # satellite takes it under the constellation's closed policy
    verify_bib(b, TEST_BPSEC_KEY)
    assert admit(b, TEST_BPSEC_KEY, "refuse")[0][0] == 22
    assert ga.agent.rx_counts["rx.foreign_signed"] == 1


def test_peer_bundles_refused_by_policy_or_bib_are_counted(world):
    ga = GroundAgent(world, TEST_BPSEC_KEY, peer_node=2, foreign="refuse")
    raw = serialize_bundle7("ipn:2.1", "ipn:22.1", b"x", lifetime=600,
                            creation_timestamp=world.scenario.epoch, sequence_number=1)
    assert ga.from_peer(raw, 0) == "dropped.integrity"
    assert ga.from_peer(b"\x9f\x00", 0) == "dropped.integrity"  # not a bundle
    o = _obs(sat="sat_22", gp=1, t_ns=0)
    forged = downlink_bundle(o, b"another key of 16+ bytes", dtn_ms_of(world.scenario.epoch), dest_node=22)
    assert ga.from_peer(forged, 0) == "dropped.integrity"
    assert ga.agent.rx_counts["rx.foreign_refused"] == 1 and ga.agent.rx_counts["rx.bib_failed"] == 1
    assert ga.counters["peer.dropped.integrity"] == 3
    accepting = GroundAgent(world, TEST_BPSEC_KEY, peer_node=2)
    nowhere = serialize_bundle7("ipn:2.1", "ipn:5.1", b"x", lifetime=600,
                                creation_timestamp=world.scenario.epoch, sequence_number=2)
    assert accepting.from_peer(nowhere, 0) == "dropped.integrity"  # node 5: no such node here
    assert accepting.agent.rx_counts["rx.unknown_destination"] == 1


def test_a_forwarded_downlink_stays_in_the_store_until_the_peer_acknowledges_it(world, tmp_path):
    path = tmp_path / "ground.sqlite"
    ga = GroundAgent(world, TEST_BPSEC_KEY, store_path=str(path), peer_node=2)
    o = _obs(sat="sat_11", gp=5, t_ns=10**9)
    raw = downlink_bundle(o, TEST_BPSEC_KEY, dtn_ms_of(world.scenario.epoch), dest_node=2)
    assert ga.downlink(raw, "sat_11", 2 * 10**9) == o  # the ground reads what it relays
    ups, to_peer = ga.transmissions(3 * 10**9)
    assert ups == [] and len(to_peer) == 1 and to_peer[0].next_hop == "ipn_2"
    assert decode_bundle(to_peer[0].bundle_bytes).payload == decode_bundle(raw).payload
    assert len(BundleStore(path)) == 1  # sent, not acknowledged: still stored (another connection reads it)
    ga.close()
    again = GroundAgent(world, TEST_BPSEC_KEY, store_path=str(path), peer_node=2)  # a restart finds it
    assert again.held() == 1
    _, to_peer = again.transmissions(4 * 10**9)
    again.acknowledged(to_peer[0])
    assert again.held() == 0 and len(BundleStore(path)) == 0 and again.counters["peer.acknowledged"] == 1


def test_a_centralized_satellites_checkpoint_holds_no_key(world):
    from sat_node.satellite import SatelliteLogic

    s = SatelliteLogic(world, world.sat_names[0], "centralized", bpsec_key=TEST_BPSEC_KEY)
    blob = s.snapshot()
    assert TEST_BPSEC_KEY not in blob
    fresh = SatelliteLogic(world, world.sat_names[0], "centralized", bpsec_key=TEST_BPSEC_KEY)
    fresh.restore(blob)
    assert fresh._key == TEST_BPSEC_KEY  # the key comes from the deployment, as the restarted process's
