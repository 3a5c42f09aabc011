"""``constellation run --ground-gateway URL``: the ground gateway's part of a run (ground_station/gateway.py):
the URL checked and the peer reached before anything else is made (one line, exit 2, otherwise), the
gateway closed when the run ends, and what it did written to the run folder (gateway.json) and to
report.json (``gateway``). On the local engine the gateway runs in this process; on the ROS engine in
the ground's process (bringup/engine/ros/ground_gateway.py), which with the satellites' processes
writes what gateway.json needs at the run's end. Checked by tests/unit/test_gateway.py (the refusals) and
tests/system/test_ground_gateway.py (a whole run).
"""

from __future__ import annotations

import argparse
import asyncio
import json
import socket
from pathlib import Path

from bringup.cli.run_folder import json_text, write_text_atomic
from bringup.engine.ros.ground_gateway import GATEWAY_DIR, GROUND_FILE
from bringup.errors import UserError
from ground_station.gateway import CONNECT_S, Gateway, parse_gateway
from ground_station.ground_segment import GroundLogic
from sat_node.dtn.cl import ClError, udp
from sat_node.satellite import SatelliteLogic

__all__ = ["closing", "gateway_spec", "start_gateway", "write_gateway_report", "write_gateway_report_ros",
           "write_report"]


def gateway_spec(args: argparse.Namespace):
    """``--ground-gateway`` parsed (None without it); one-line UserError when the URL or the run
    cannot have one."""
    url = getattr(args, "ground_gateway", None)
    if url is None:
        return None
    try:
        spec = parse_gateway(url)
    except ValueError as exc:
        raise UserError(f"--ground-gateway: {exc}") from None
    if args.mode != "centralized":
        raise UserError(f"--ground-gateway needs --mode centralized (the ground segment's bundle agent), "
                        f"not {args.mode}")
    if args.engine == "ros" and getattr(args, "restart", 0):
        raise UserError("--ground-gateway with --restart: a restarted ground process would lose the "
                        "gateway's session and what it had not yet handed over; run without --restart")
    return spec


def start_gateway(spec, engine: str = "local"):
    """The started gateway (local engine), None on the ROS engine, whose ground process starts its
    own (bringup/engine/ros/ground_gateway.py): there the peer is only reached here - a TCP connection
    opened and closed, no TCPCL session (a node such as ION ties sessions to the node ID and ends its
    own when one from that node ends), the UDP address checked - so an unreachable one still stops
    the run before anything is made."""
    if spec is None:
        return None
    if engine == "ros":
        if spec.cl == "udp":  # (no listen address: the check takes no datagram)
            try:
                asyncio.run(udp.send(spec.host, spec.port, []))
            except ClError as exc:
                raise UserError(f"--ground-gateway {spec.cl}://{spec.host}:{spec.port}: {exc}") from None
            return None
        try:
            socket.create_connection((spec.host, spec.port), timeout=CONNECT_S).close()
        except OSError as exc:
            raise UserError(f"--ground-gateway {spec.cl}://{spec.host}:{spec.port}: cannot connect "
                            f"({exc.strerror or exc})") from None
        return None
    try:
        return Gateway(spec).start()
    except ClError as exc:
        raise UserError(f"--ground-gateway {spec.cl}://{spec.host}:{spec.port}: {exc}") from None


class closing:
    def __init__(self, gw):
        self.gw = gw

    def __enter__(self):
        return self.gw

    def __exit__(self, *exc):
        if self.gw is not None:
            self.gw.close()
        return False


def write_gateway_report(out: Path, parts: list, say) -> dict | None:
    """gateway.json of a local run (its participants in this process): see :func:`write_report`."""
    ground = next((p for p in parts if isinstance(p, GroundLogic)), None)
    if ground is None or ground.gateway is None:
        return None
    sats = {p.name: d for p in parts if isinstance(p, SatelliteLogic) and (d := p.ground_deliveries())}
    return write_report(out, ground.gateway_report(), sats, say)


def write_gateway_report_ros(out: Path, say) -> dict | None:
    """gateway.json of a ROS run, from what its ground and satellite processes wrote at their finish
    (bringup/engine/ros/ground_gateway.py): see :func:`write_report`."""
    folder = out / GATEWAY_DIR
    ground_file = folder / GROUND_FILE
    if not ground_file.exists():
        raise UserError(f"--ground-gateway: the ground process wrote no {ground_file} (its log in {out / 'logs'})")
    sats = {f.stem: json.loads(f.read_text()) for f in sorted(folder.glob("*.json")) if f != ground_file}
    return write_report(out, json.loads(ground_file.read_text()), sats, say)


def write_report(out: Path, rep: dict, sats: dict, say) -> dict:
    """gateway.json: the ground agent's and the gateway's counters (``rep``: GroundLogic.gateway_report)
    and what reached each satellite (``sats``: SatelliteLogic.ground_deliveries by name); returns its
    summary for report.json (``gateway``: the counters, without the per-bundle lists)."""
    rep["delivered_at_satellites"] = dict(sorted(sats.items()))
    write_text_atomic(out / "gateway.json", json_text(rep, indent=2, sort_keys=True) + "\n")
    g = rep["gateway"]["counters"]
    n_sat = sum(len(v["bundles"]) for v in rep["delivered_at_satellites"].values())
    say(f"run: ground gateway {rep['gateway']['url']}: {g.get('sent', 0)} bundles sent to the peer "
        f"({g.get('bytes_sent', 0)} B, "
        f"{'acknowledged' if rep['gateway']['acknowledged'] else 'unacknowledged: UDP'}), "
        f"{g.get('received', 0)} received from it, {n_sat} delivered at satellites, "
        f"{rep['held_at_end']} held at the end -> {out / 'gateway.json'}")
    return {"url": rep["gateway"]["url"], "acknowledged": rep["gateway"]["acknowledged"], "counters": g,
            "ground_agent": rep["agent"], "rx_policy": rep["rx_policy"], "held_at_end": rep["held_at_end"],
            "delivered_at_satellites": n_sat}
