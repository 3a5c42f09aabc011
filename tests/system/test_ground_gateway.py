"""A centralized run with a ground gateway (ground_station/gateway.py, ground_station/ground_agent.py),
the project's own listener (``constellation bundles listen``) as the gateway's peer: a 6-satellite,
1-h run at ``--epoch now`` (local engine, and ROS engine: the gateway in the ground's process,
bringup/engine/ros/ground_gateway.py) whose downlinks go to the peer's node over TCPCLv4, and
bundles that ``constellation bundles send`` delivers to the gateway's listen address reach their
satellites at their next passes.

Oracles: the listener's files (what the peer received, decoded) against the gateway's record of what
it sent (SHA-256 of every bundle, in order) and the ground agent's count of downlinks taken; the
uplink instants against the run's ground plan recomputed from its scenario.toml and searched by hand
(tests/gateway_runs.py)."""

from __future__ import annotations

import json
import socket
import time

import pytest

from msgs_json import schemas as S
from sat_node.dtn.bpv7 import decode_bundle
from sat_node.dtn.downlink import observation_of
from tests.gateway_runs import (
    SATS,
    UPLINK_QUEUE_S,
    cli,
    downlinked,
    finish,
    gateway_json,
    peer_bundles,
    run_world,
    sha256,
    start_run,
    uplink_contact_after,
    wait_for,
)


def _free_port() -> int:
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    p = s.getsockname()[1]
    s.close()
    return p


@pytest.mark.parametrize("engine", ["local", pytest.param("ros", marks=pytest.mark.ros)])
def test_downlinks_reach_the_listener_and_peer_bundles_reach_their_satellites(tmp_path, engine):
    rx = tmp_path / "peer"
    lst = cli("bundles", "listen", "--cl", "tcpcl4", "--at", "127.0.0.1:0", "--out", str(rx),
              "--duration", "300", "--node-id", "ipn:2.0")
    try:
        first = lst.stdout.readline()
        assert first.startswith("listening on tcpcl4://127.0.0.1:"), first
        port = int(first.split()[2].split(":")[-1].rstrip(","))
        gport = _free_port()
        ours = peer_bundles(tmp_path / "to_sats", 2)
        out = tmp_path / "run"
        t0 = time.time()
        run = start_run(out, f"tcpcl4://127.0.0.1:{port}?node=2&listen=127.0.0.1:{gport}", engine)

        def sent() -> bool:  # the gateway's listen address opens when the run starts: retry until it does
            p = cli("bundles", "send", "--cl", "tcpcl4", "--to", f"127.0.0.1:{gport}", "--node-id", "ipn:2.0",
                    *[str(f) for f, _p, _i in ours.values()])
            p.communicate(timeout=60)
            return p.returncode == 0

        assert wait_for(sent, 180, 0.2)  # (the ROS engine's processes start in tens of seconds)
        _o, err = finish(run)
        wall = time.time() - t0
        gj = gateway_json(out)
    finally:
        lst.terminate()
        lst.communicate(timeout=30)
    now_ms = int((time.time() - 946_684_800) * 1000)
    # 1. every downlink the ground took went to the peer, byte-identical to what the gateway sent
    g = gj["gateway"]
    files = sorted(rx.glob("*.bpv7"))
    got = [f.read_bytes() for f in files]
    n_down = gj["agent"].get("downlink.queued", 0)
    assert n_down > 10, gj["agent"]  # the polar regions put observations before passes
    assert gj["agent"].get("downlink.delivered", 0) == 0  # with a gateway every downlink is the peer's
    assert len(got) == g["counters"]["sent"] == n_down == g["counters"]["acknowledged"]
    assert [sha256(b) for b in got] == [s["sha256"] for s in g["sent"]]
    assert gj["held_at_end"] == 0 and gj["awaiting_acknowledgment"] == 0
    for raw in got:  # each an observation of this run, addressed to the peer, unexpired when it arrived
        b = decode_bundle(raw)
        o = observation_of(b.payload)
        assert isinstance(o, S.Observation) and o.sat in SATS and b.src == (int(o.sat[4:]), 1)
        assert b.dest == (2, 1) and b.creation_ms + b.lifetime_ms > now_ms
    assert len({decode_bundle(r).bundle_id for r in got}) == len(got)
    # and they are the bundles the satellites downlinked (the run's bag): same ids, payloads identical
    down = downlinked(out)
    assert sorted((decode_bundle(r).bundle_id, decode_bundle(r).payload) for r in got) == \
        sorted((decode_bundle(r).bundle_id, decode_bundle(r).payload) for r in down)
    # 2. the peer's bundles: taken in, each routed to its satellite's next pass and delivered there
    world = run_world(out)
    arrived = {e["bundle"]: e for e in gj["from_peer"]}
    assert set(arrived) == {bid for _f, _p, bid in ours.values()}
    assert {arrived[bid]["dest"] for _f, _p, bid in ours.values()} == {f"ipn:{s[4:]}.1" for s in SATS}
    up = {u["bundle"]: u for u in gj["uplinked"]}
    delivered = {sat: {b["bundle"] for b in v["bundles"]} for sat, v in gj["delivered_at_satellites"].items()}
    n_expected = n_dropped = 0
    for sat, (_f, payload, bid) in ours.items():
        # at an --epoch now the geometry is the hour's: the ground routes over its own passes only
        # (ground_station/ground_agent.py), so a bundle for a satellite with no pass left in the run
        # after its arrival is dropped at once (no_route), any other is queued for that pass
        c = uplink_contact_after(world, sat, arrived[bid]["t_ns"] / 1e9)
        if c is None:
            assert arrived[bid]["result"] == "dropped.no_route" and bid not in up, arrived[bid]
            n_dropped += 1
            continue
        assert arrived[bid]["result"] == "queued", arrived[bid]
        n_expected += 1
        assert up[bid]["sat"] == sat
        # the pass that is open at its arrival, or the next one; the ground node sends one bundle at a
        # time, so bundles leaving together queue behind each other (each size x 8 / the uplink rate,
        # ~2.6 ms at 1 Mbit/s; tests/gateway_runs.py UPLINK_QUEUE_S)
        assert 0 <= up[bid]["t_ns"] / 1e9 - max(arrived[bid]["t_ns"] / 1e9, c.start_s) < UPLINK_QUEUE_S
        assert bid in delivered[sat]
        assert [b["payload_sha256"] for b in gj["delivered_at_satellites"][sat]["bundles"]
                if b["bundle"] == bid] == [sha256(payload)]
    assert n_expected >= 1
    assert gj["held_at_end"] == len(ours) - n_dropped - n_expected
    assert "ground gateway tcpcl4://" in err
    rep = json.loads((out / "report.json").read_text())["gateway"]  # the summary in the run's report
    assert rep["counters"]["sent"] == len(got) and rep["rx_policy"]["rx.foreign_accepted"] == len(ours)
    assert rep["delivered_at_satellites"] == n_expected
    if engine == "ros":  # the gateway ran in the ground's process, which wrote its part at its finish
        assert (out / "gateway" / "ground.json").exists()
        assert json.loads((out / "report.json").read_text())["runtime"].get("domain_id") is not None
    print(f"gateway tcpcl4 (own listener, {engine} engine): {len(got)} downlinked bundles, {sum(map(len, got))} B, "
          f"{len(ours)} from it, {n_expected} delivered at satellites, run wall {wall:.1f} s")
