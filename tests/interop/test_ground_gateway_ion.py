"""The ground gateway (ground_station/gateway.py) into an ION-DTN node (built from its source by
scripts/build_ion.sh) over TCPCLv3 and UDP: a 6-satellite, 1-h centralized run at ``--epoch now``
(local engine; and over TCPCLv3 the ROS engine, whose ground process runs the gateway) forwards every downlinked bundle to ION node 2, and bundles that ION's bpsendfile
sends to the satellites reach the named satellite at its next pass.

The ION node is configured by its own rc files (tests/interop/ion_node.py): a plan for the ground's
node 100 on the layer under test and an exit for the satellites' node numbers (11-99) through
``ipn:100.0``. The oracles are ION's: bprecvfile writes the payload of every bundle ION accepted and
delivered at ``ipn:2.1`` (an expired or malformed bundle is never delivered); those payloads must be
exactly the downlinked bundles' payloads, read from the run's bag. Marker ``interop``.
"""

from __future__ import annotations

import socket
import sys
import time
from collections import Counter

import pytest
from ion_node import IonNode, free_port

from sat_node.dtn.bpv7 import decode_bundle
from tests.gateway_runs import (
    SATS,
    UPLINK_QUEUE_S,
    downlinked,
    finish,
    gateway_json,
    run_world,
    sha256,
    start_run,
    uplink_contact_after,
    wait_for,
)

pytestmark = pytest.mark.interop


def _listening(cl: str, port: int) -> bool:
    """The gateway's listen address is open (TCP: it accepts; UDP: the port is taken)."""
    if cl == "udp":
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            return True
        finally:
            s.close()
        return False
    with socket.socket() as s:
        return s.connect_ex(("127.0.0.1", port)) == 0


@pytest.mark.parametrize("cl,engine", [("tcpcl3", "local"), ("udp", "local"), ("tcpcl3", "ros")])
def test_downlinks_into_ion_and_ion_bundles_to_the_satellites(cl, engine, tmp_path):
    duct = "tcp" if cl == "tcpcl3" else "udp"
    gport = free_port(socket.SOCK_STREAM if cl == "tcpcl3" else socket.SOCK_DGRAM)
    ion = IonNode(tmp_path / "ion", 2, {100: f"{duct}/127.0.0.1:{gport}"}, exits="a exit 11 99 ipn:100.0\n")
    try:
        ion.start()
        print(f"ION: {ion.version()}", file=sys.stderr)
        ion_port = ion.tcp_port if cl == "tcpcl3" else ion.udp_port
        out = tmp_path / "run"
        t0 = time.time()
        # paced (1 h in 24 s): ION's outduct takes seconds to open its session to the ground (measured
        # ~4 s), and an unloaded machine runs the hour in 5-20 s - its bundles would come after the end
        run = start_run(out, f"{cl}://127.0.0.1:{ion_port}?node=2&listen=127.0.0.1:{gport}", engine,
                        "--real-time-factor", "150")
        # (the ROS engine's ground process opens it once its kernels are loaded: tens of seconds)
        assert wait_for(lambda: _listening(cl, gport), 60 if engine == "local" else 300, 0.05)  # the gateway is up; the run is starting
        payloads = {}
        for i, sat in enumerate(SATS):  # ION -> the constellation: one bundle per satellite, 2 h to live
            f = tmp_path / f"to_{sat}.bin"
            f.write_bytes(f"from ION to {sat} ".encode() * (5 + i))
            ion.send_file("ipn:2.1", f"ipn:{sat[4:]}.1", f, ttl_s=7200)
            payloads[sat] = f.read_bytes()
        _o, err = finish(run)
        wall = time.time() - t0
        gj = gateway_json(out)
        g = gj["gateway"]["counters"]
        n = g.get("sent", 0)
        down = downlinked(out)
        # every downlink went to the gateway's peer; how many there are depends on the hour's geometry
        # (--epoch now: 7 at 03:30 UTC, ~170 at 22:00), so the test asks for at least one
        assert n == len(down) >= 1, (n, len(down), gj["agent"])
        t_rx = time.time()
        got = ion.receive_files("ipn:2.1", n, timeout=120)
        rx_s = time.time() - t_rx
    finally:
        ion.stop()
    now_ms = int((time.time() - 946_684_800) * 1000)
    # ION delivered every downlinked bundle, payloads byte-identical, none expired
    assert Counter(got) == Counter(decode_bundle(b).payload for b in down)
    assert all(decode_bundle(b).creation_ms + decode_bundle(b).lifetime_ms > now_ms for b in down)
    assert all(decode_bundle(b).dest == (2, 1) for b in down)
    # ION's bundles: each reached the gateway; each whose satellite has a pass left after its arrival
    # went up at that pass (the run's ground plan, searched by hand) and was delivered there
    world = run_world(out)
    assert sorted(e["dest"] for e in gj["from_peer"]) == sorted(f"ipn:{s[4:]}.1" for s in SATS), gj["from_peer"]
    # at an --epoch now the geometry is the hour's: the ground routes over its own passes only
    # (ground_station/ground_agent.py), so a bundle for a satellite with no pass left in the run after
    # its arrival is dropped at once (no_route), every other one is queued for that pass
    for e in gj["from_peer"]:
        c = uplink_contact_after(world, f"sat_{e['dest'][4:-2]}", e["t_ns"] / 1e9)
        assert e["result"] == ("dropped.no_route" if c is None else "queued"), (e, c)
    arrived = [e for e in gj["from_peer"] if e["result"] == "queued"]
    up = {u["bundle"]: u for u in gj["uplinked"]}
    at_sats = gj["delivered_at_satellites"]
    n_sat = 0
    for e in arrived:
        sat = f"sat_{e['dest'][4:-2]}"
        c = uplink_contact_after(world, sat, e["t_ns"] / 1e9)
        mine = [b for b in at_sats.get(sat, {}).get("bundles", []) if b["bundle"] == e["bundle"]]
        assert up[e["bundle"]]["sat"] == sat
        # the pass that is open at its arrival, or the next one; the ground node sends one bundle at a
        # time, so bundles leaving together queue behind each other (each size x 8 / the uplink rate,
        # ~2.6 ms at 1 Mbit/s; tests/gateway_runs.py UPLINK_QUEUE_S)
        assert 0 <= up[e["bundle"]]["t_ns"] / 1e9 - max(e["t_ns"] / 1e9, c.start_s) < UPLINK_QUEUE_S
        assert [b["payload_sha256"] for b in mine] == [sha256(payloads[sat])]  # ION's payload, there
        n_sat += 1
    assert n_sat >= 1 and gj["held_at_end"] == len(arrived) - n_sat
    acked = "acknowledged" if cl == "tcpcl3" else "unacknowledged (UDP)"
    print(f"gateway {cl} -> ION ({engine} engine): {n} downlinked bundles, {g.get('bytes_sent', 0)} B, {acked}, all delivered "
          f"by ION byte-identical (bprecvfile {rx_s:.1f} s); ION -> gateway: {len(arrived)} bundles, {n_sat} "
          f"delivered at their satellites; run wall {wall:.1f} s, gateway sending "
          f"{gj['gateway'].get('send_wall_s')} s", file=sys.stderr)
    assert "ground gateway" in err
