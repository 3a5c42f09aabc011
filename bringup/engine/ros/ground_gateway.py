"""The ground gateway on the ROS engine (``constellation run --engine ros --ground-gateway URL``).

The run spec carries the gateway's URL (``extra["ground_gateway"]``) and a folder
(``extra["gateway_dir"]``); the participant factory (bringup/engine/ros/factory.py) asks
:func:`gateway_for` what its process needs:

* the ground's process starts the gateway (ground_station/gateway.py) while it is built, before it
  says it is ready: the convergence-layer sessions run in the gateway's own asyncio loop on a thread
  of its own, so the host's executor and the lockstep never wait on the network; the ground's steps
  only hand bundles over and take what arrived (ground_station/ground_segment.py), so the peer's
  bundles enter the run at the ground step after they arrived and go up to their satellite at its
  next pass, as on the local engine;
* the satellites' processes get the gateway's spec alone (their downlinks are addressed to the
  peer's node, and they take the bundles the ground uplinks).

Every process writes what the run's gateway.json needs when it has run its participants' ``finish``
(:func:`report_at_finish`; the processes end with ``os._exit``, bringup/engine/ros/host.py
exit_now, so nothing after the last step could): the ground its agent's and gateway's report
(``ground.json``, after the gateway's last acknowledgments and its session's end), each satellite
that got bundles from the ground what became of them (``<sat>.json``). The run's command merges
them (bringup/cli/gateway_run.py write_gateway_report_ros) into the same gateway.json as a local run's.

How we know it is right: tests/system/test_ground_gateway.py (a ROS-engine run whose downlinks reach
``bundles listen`` byte-identical and whose peer bundles reach the named satellites, the same
checks as the local engine's run) and tests/interop/test_ground_gateway_ion.py (the ROS engine
into ION over TCPCLv3).
"""

from __future__ import annotations

import json
from pathlib import Path

from bringup.errors import UserError
from bringup.scenario.participants import GROUND_ROLE

__all__ = ["GATEWAY_DIR", "GROUND_FILE", "gateway_for", "report_at_finish"]

GATEWAY_DIR = "gateway"  # in the run folder: what each process wrote for gateway.json
GROUND_FILE = "ground.json"


def gateway_for(extra: dict, roles: list[str]) -> dict:
    """``make_participant`` keywords for a process hosting ``roles``: ``gateway`` (started, for the
    ground's process) and ``gateway_spec``; {} without a gateway."""
    url = extra.get("ground_gateway")
    if not url:
        return {}
    # imported here: the processes of runs without a gateway never load the convergence layers
    from ground_station.gateway import Gateway, parse_gateway
    from sat_node.dtn.cl import ClError

    try:
        spec = parse_gateway(url)
    except ValueError as exc:
        raise UserError(f"run spec: extra.ground_gateway: {exc}") from None
    if GROUND_ROLE not in roles:
        return {"gateway_spec": spec}
    try:
        return {"gateway": Gateway(spec).start()}
    except ClError as exc:
        raise UserError(f"ground gateway {spec.cl}://{spec.host}:{spec.port}: {exc}") from None


def report_at_finish(parts: list, extra: dict) -> None:
    """Make each participant of a gateway run write its part of gateway.json after its ``finish``
    (into ``extra["gateway_dir"]``); the ground also closes its gateway then."""
    if not extra.get("ground_gateway"):
        return
    folder = Path(extra["gateway_dir"])
    for p in parts:
        if getattr(p, "gateway", None) is not None and callable(getattr(p, "gateway_report", None)):
            p.finish = _after(p.finish, lambda p=p: _ground_done(p, folder))
        elif callable(getattr(p, "ground_deliveries", None)):
            p.finish = _after(p.finish, lambda p=p: _write(folder / f"{p.name}.json", p.ground_deliveries()))


def _after(finish, then):
    def wrapped(t_ns: int):
        emits = finish(t_ns)
        then()
        return emits
    return wrapped


def _ground_done(ground, folder: Path) -> None:
    ground.gateway.close()  # (after finish: the last acknowledgments are in)
    _write(folder / GROUND_FILE, ground.gateway_report())


def _write(path: Path, data: dict | None) -> None:
    if data is None:
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(data, indent=2, sort_keys=True) + "\n")
    tmp.replace(path)
