"""``constellation run --ground-gateway URL``: the ground gateway's part of a run (ground_station/gateway.py):
the URL checked and the peer reached before anything else is made (one line, exit 2, otherwise), the
gateway closed when the run ends, and what it did written to the run folder (gateway.json) and to
report.json (``gateway``). Checked by tests/unit/test_gateway.py (the refusals) and
tests/system/test_ground_gateway.py (a whole run).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from bringup.cli.run_folder import json_text, write_text_atomic
from bringup.errors import UserError
from ground_station.gateway import Gateway, parse_gateway
from ground_station.ground_segment import GroundLogic
from sat_node.dtn.cl import ClError
from sat_node.satellite import SatelliteLogic

__all__ = ["closing", "gateway_spec", "start_gateway", "write_gateway_report"]


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
    if args.engine != "local":
        raise UserError("--ground-gateway runs on --engine local (the ROS engine's ground process has no "
                        "gateway yet)")
    return spec


def start_gateway(spec):
    if spec is None:
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
    """gateway.json: the ground agent's and the gateway's counters and what reached each satellite;
    returns its summary for report.json (``gateway``: the counters, without the per-bundle lists)."""
    ground = next((p for p in parts if isinstance(p, GroundLogic)), None)
    if ground is None or ground.gateway is None:
        return None
    rep = ground.gateway_report()
    rep["delivered_at_satellites"] = {
        p.name: {"counters": dict(sorted(p.from_ground.items())),
                 "bundles": [{"bundle": b, "payload_bytes": n, "payload_sha256": h, "t_ns": t}
                             for b, n, h, t in p.delivered_from_ground]}
        for p in parts if isinstance(p, SatelliteLogic) and (p.from_ground or p.delivered_from_ground)}
    write_text_atomic(out / "gateway.json", json_text(rep, indent=2, sort_keys=True) + "\n")
    g = rep["gateway"]["counters"]
    n_sat = sum(len(v["bundles"]) for v in rep["delivered_at_satellites"].values())
    say(f"run: ground gateway {ground.gateway.spec.url}: {g.get('sent', 0)} bundles sent to the peer "
        f"({g.get('bytes_sent', 0)} B, "
        f"{'acknowledged' if rep['gateway']['acknowledged'] else 'unacknowledged: UDP'}), "
        f"{g.get('received', 0)} received from it, {n_sat} delivered at satellites, "
        f"{rep['held_at_end']} held at the end -> {out / 'gateway.json'}")
    return {"url": rep["gateway"]["url"], "acknowledged": rep["gateway"]["acknowledged"], "counters": g,
            "ground_agent": rep["agent"], "rx_policy": rep["rx_policy"], "held_at_end": rep["held_at_end"],
            "delivered_at_satellites": n_sat}


