"""The ground gateway (ground_station/gateway.py) into the RFC 9174 author's TCPCLv4 agent (github
BrianSipos/dtn-demo-agent, driven by tests/interop/tcpcl4_peer.py as in test_tcpcl4_interop.py): a
6-satellite, 1-h centralized run at ``--epoch now`` (local engine) opens one TCPCLv4 session to the
agent, sends it every downlinked bundle, and the bundles the agent sends on that session reach their
satellites at their next passes.

Oracles: the agent's own record of what it received (each bundle's bytes, written by its receive
queue) against the run's bag (the bundles the satellites downlinked: ids and payloads) and the
gateway's SHA-256 of each bundle it sent; the agent's own transfer results (``success``) for the
bundles it sent. Marker ``interop``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time

import pytest
from ion_node import free_port
from test_tcpcl4_interop import HERE, PEER, bus  # noqa: F401 - bus is the D-Bus fixture the agent needs

from sat_node.dtn.bpv7 import decode_bundle
from tests.gateway_runs import (
    SATS,
    UPLINK_QUEUE_S,
    downlinked,
    finish,
    gateway_json,
    peer_bundles,
    run_world,
    sha256,
    start_run,
    uplink_contact_after,
)

pytestmark = pytest.mark.interop


def test_downlinks_into_the_tcpcl4_agent_and_its_bundles_to_the_satellites(bus, tmp_path):  # noqa: F811
    port = free_port()
    ours = peer_bundles(tmp_path / "to_sats", 9)
    rx = tmp_path / "agent_in"
    agent = subprocess.Popen([str(PEER / "venv" / "bin" / "python"), str(HERE / "tcpcl4_peer.py"),
                              "--bus", bus, "--listen", "127.0.0.1", str(port), "--segment-mru", "3000",
                              "--tx-segment", "100000", "--send", *[str(f) for f, _p, _i in ours.values()],
                              "--expect", "1000000", "--out", str(rx), "--timeout", "300"],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             env=dict(os.environ, PYTHONPATH=str(PEER / "src")))
    try:
        time.sleep(3)  # the agent's listener comes up (the run retries nothing: an absent peer is an error)
        out = tmp_path / "run"
        t0 = time.time()
        _o, err = finish(start_run(out, f"tcpcl4://127.0.0.1:{port}?node=9"))
        wall = time.time() - t0
        a_out, _a_err = agent.communicate(timeout=60)  # the gateway ended the session at the run's end
    finally:
        if agent.poll() is None:
            agent.kill()
    res = json.loads(a_out.strip().splitlines()[-1])
    gj = gateway_json(out)
    g = gj["gateway"]
    got = [f.read_bytes() for f in sorted(rx.glob("*.bin"))]
    down = downlinked(out)
    # how many downlinks there are depends on the hour's geometry (--epoch now), so at least one
    assert len(got) == len(down) == g["counters"]["sent"] == g["counters"]["acknowledged"] >= 1
    assert [sha256(b) for b in got] == [s["sha256"] for s in g["sent"]]  # byte-identical, in order
    assert sorted((decode_bundle(b).bundle_id, decode_bundle(b).payload) for b in got) == \
        sorted((decode_bundle(b).bundle_id, decode_bundle(b).payload) for b in down)
    now_ms = int((time.time() - 946_684_800) * 1000)
    assert all(decode_bundle(b).dest == (9, 1) and decode_bundle(b).creation_ms + decode_bundle(b).lifetime_ms
               > now_ms for b in got)
    # the agent's bundles: sent on the gateway's session (its own results), each delivered at its satellite
    assert res["sent"] == len(ours) and res["results"].count("success") == len(ours), res
    world = run_world(out)
    arrived = {e["bundle"]: e for e in gj["from_peer"]}
    up = {u["bundle"]: u for u in gj["uplinked"]}
    n_sat = 0
    for sat, (_f, payload, bid) in ours.items():
        e = arrived[bid]
        assert e["dest"] == f"ipn:{sat[4:]}.1"
        # at an --epoch now the geometry is the hour's: the ground routes over its own passes only
        # (ground_station/ground_agent.py); no pass left after the arrival -> dropped at once
        if uplink_contact_after(world, sat, e["t_ns"] / 1e9) is None:
            assert e["result"] == "dropped.no_route" and bid not in up, e
            continue
        assert e["result"] == "queued", e
        c = uplink_contact_after(world, sat, e["t_ns"] / 1e9)
        mine = [b for b in gj["delivered_at_satellites"].get(sat, {}).get("bundles", [])
                if b["bundle"] == bid]
        # the pass that is open at its arrival, or the next one; the ground node sends one bundle at a
        # time, so bundles leaving together queue behind each other (each size x 8 / the uplink rate,
        # ~2.6 ms at 1 Mbit/s; tests/gateway_runs.py UPLINK_QUEUE_S)
        assert 0 <= up[bid]["t_ns"] / 1e9 - max(e["t_ns"] / 1e9, c.start_s) < UPLINK_QUEUE_S
        assert [b["payload_sha256"] for b in mine] == [sha256(payload)]
        n_sat += 1
    assert n_sat >= 1
    print(f"gateway tcpcl4 -> dtn-demo-agent: {len(got)} downlinked bundles, "
          f"{g['counters']['bytes_sent']} B, "
          f"acknowledged (XFER_ACK), session parameters {res['params']}; agent -> gateway: {len(ours)} "
          f"bundles, {n_sat} delivered at their satellites; run wall {wall:.1f} s, gateway sending "
          f"{g.get('send_wall_s')} s", file=sys.stderr)
    assert "ground gateway tcpcl4://" in err and len(SATS) == len(ours)
