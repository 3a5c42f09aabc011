"""Helpers for the tests that run the constellation with a ground gateway (ground_station/gateway.py):
the run as a subprocess of the CLI (centralized, local or ROS engine, six satellites, one hour, ``--epoch
now``, polar regions beside the paper's so that observations precede the passes), bundles for the
satellites made by pyD3TN (an independent BPv7 implementation), and what a run should have done,
recomputed from its folder (its scenario.toml, with the epoch it ran at, and the world built anew)."""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
import time
from datetime import UTC, datetime
from pathlib import Path

from pyd3tn.bundle7 import serialize_bundle7

REPO = Path(__file__).resolve().parents[1]
POLAR = ('regions.list=[{name="Dhaka",lat_deg=23.8103,lon_deg=90.4125,size_km=80.0},'
         '{name="Sydney",lat_deg=-33.8688,lon_deg=151.2093,size_km=80.0},'
         '{name="Dallas",lat_deg=32.7767,lon_deg=-96.797,size_km=80.0},'
         '{name="London",lat_deg=51.5074,lon_deg=-0.1278,size_km=80.0},'
         '{name="Rio de Janeiro",lat_deg=-22.9068,lon_deg=-43.1729,size_km=80.0},'
         '{name="Tromso",lat_deg=69.65,lon_deg=18.96,size_km=150.0},'
         '{name="Ross",lat_deg=-72.0,lon_deg=170.0,size_km=150.0},'
         '{name="Greenland",lat_deg=72.0,lon_deg=-40.0,size_km=150.0},'
         '{name="Peninsula",lat_deg=-65.0,lon_deg=-62.0,size_km=150.0}]')
# how much later than its pass (or its arrival in an open pass) a peer's bundle may leave the ground:
# the ground's one agent sends one bundle at a time, so the peer's bundles that leave together (six, one
# per satellite, at most ~450 B each once the ground signed them) queue: 6 x 450 x 8 bit / 1 Mbit/s
# = 22 ms at most (measured: 2.57 ms behind one 321-B bundle, a ROS run into ION)
UPLINK_QUEUE_S = 0.025
SATS = ("sat_11", "sat_12", "sat_21", "sat_22", "sat_31", "sat_32")  # the 6-satellite Walker pattern


def env() -> dict:
    return dict(os.environ, PYTHONPATH=str(REPO))


def cli(*argv: str, **kw) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "bringup.cli", *argv], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env(), cwd=REPO, **kw)


def start_run(out: Path, url: str, engine: str = "local", *extra: str) -> subprocess.Popen:
    return cli("run", "--mode", "centralized", "--engine", engine, "--sats", "6", "--hours", "1",
               "--epoch", "now", "--no-plots", "--no-progress", "--set", POLAR, "--out", str(out),
               "--ground-gateway", url, *extra)


def peer_bundles(folder: Path, src_node: int, lifetime_s: int = 7200) -> dict[str, tuple[Path, bytes, str]]:
    """One bundle per satellite from ``ipn:<src_node>.1`` to ``ipn:<sat>.1``, created now (pyD3TN):
    {satellite: (file, payload, bundle id)}."""
    folder.mkdir(parents=True, exist_ok=True)
    now = datetime.now(UTC)
    out = {}
    for i, sat in enumerate(SATS):
        payload = f"for {sat} from the ground network ".encode() * (3 + i)
        raw = serialize_bundle7(f"ipn:{src_node}.1", f"ipn:{sat[4:]}.1", payload, lifetime=lifetime_s,
                                creation_timestamp=now, sequence_number=i)
        f = folder / f"to_{sat}.bpv7"
        f.write_bytes(raw)
        dtn_ms = int(round((now - datetime(2000, 1, 1, tzinfo=UTC)).total_seconds() * 1000))
        out[sat] = (f, payload, f"ipn{src_node}.1-{dtn_ms}-{i}")
    return out


def finish(p: subprocess.Popen, timeout: float = 600) -> tuple[str, str]:
    out, err = p.communicate(timeout=timeout)
    assert p.returncode == 0, f"exit {p.returncode}\n{err[-3000:]}"
    return out, err


def gateway_json(out: Path) -> dict:
    return json.loads((out / "gateway.json").read_text())


def sha256(b: bytes) -> str:
    return hashlib.sha256(b).hexdigest()


def downlinked(out: Path) -> list[bytes]:
    """Every bundle the satellites downlinked in the run, from its bag (the GroundDownlink messages)."""
    from bringup.recording.bag_reader import BagReader
    from msgs_json import codec

    with BagReader(out / "bag") as bag:
        return [b for e in bag.envelopes(["/ground/downlink"]) for b in codec.decode(e.topic, e.data).bundles]


def run_world(out: Path):
    """The run's world, built again from its folder's scenario.toml (the epoch it ran at)."""
    from bringup.scenario.config import load_scenario
    from bringup.scenario.world import World

    return World.build(load_scenario(out / "scenario.toml"))


def uplink_contact_after(world, sat: str, t_s: float):
    """By hand: the first station-to-``sat`` contact still open at or after ``t_s`` (None: none)."""
    best = None
    for c in world.ground_plan.contacts:
        if c.dst == sat and c.src.startswith("gs_") and c.end_s > t_s:
            if best is None or max(t_s, c.start_s) < max(t_s, best.start_s):
                best = c
    return best


def wait_for(cond, timeout: float, step: float = 0.1) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(step)
    return cond()
