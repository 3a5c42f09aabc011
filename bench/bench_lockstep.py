"""Lockstep throughput of the ROS engine: steps/s with 2, 8 and 24 participant processes.

Each process hosts one toy Counter (tests/ros/toy_participants.py) that wakes every 10 s (= the
max step, so every step is 10 s of sim time) and sends one envelope per step to its ring neighbour; the clock records everything into an MCAP bag.
Prints, per process count: steps, wall time, steps/s, real-time factor at 10 s steps, peak RSS of
all processes together (sampled from /proc); then what the run key's MAC (msgs_json/auth.py) costs
per envelope, beside the wire encoding every envelope pays anyway. To compare with a checkout
without it, run that checkout's copy of this file (it imports the code beside it). Usage:
    .venv/bin/python bench/bench_lockstep.py [--procs 2 8 24] [--steps 300] [--no-bag]
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
import threading
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from bringup.engine.ros.launcher import launch
from bringup.engine.ros.run_spec import RunSpec


def _rss_tree_kib(root_pid: int) -> int:
    """Sum of VmRSS over root_pid and its descendants."""
    children: dict[int, list[int]] = {}
    rss: dict[int, int] = {}
    for d in os.listdir("/proc"):
        if not d.isdigit():
            continue
        try:
            with open(f"/proc/{d}/status") as fh:
                ppid, kib = 0, 0
                for line in fh:
                    if line.startswith("PPid:"):
                        ppid = int(line.split()[1])
                    elif line.startswith("VmRSS:"):
                        kib = int(line.split()[1])
            children.setdefault(ppid, []).append(int(d))
            rss[int(d)] = kib
        except OSError:
            continue
    total, todo = 0, [root_pid]
    while todo:
        p = todo.pop()
        total += rss.get(p, 0) if p != root_pid else 0
        todo.extend(children.get(p, []))
    return total


def bench(n_procs: int, steps: int, bag: bool) -> dict:
    out = Path(tempfile.mkdtemp(prefix=f"bench_lockstep_{n_procs}_"))
    max_step = 10 * 10**9
    spec = RunSpec(factory="tests.ros.toy_participants:make", roles=[f"c{i}" for i in range(n_procs)],
                   horizon_ns=steps * max_step, max_step_ns=max_step,
                   bag_dir=str(out / "bag") if bag else None, extra={"n_counters": n_procs, "blob_every": 0, "period_s": 10.0},
                   ack_timeout_s=60.0, startup_timeout_s=180.0)
    peak = [0]
    stop = threading.Event()

    def sample():
        while not stop.is_set():
            peak[0] = max(peak[0], _rss_tree_kib(os.getpid()))
            time.sleep(0.5)

    th = threading.Thread(target=sample, daemon=True)
    th.start()
    t0 = time.monotonic()
    res = launch(spec, out)
    total = time.monotonic() - t0
    stop.set()
    th.join()
    shutil.rmtree(out, ignore_errors=True)
    if not res.ok:
        raise SystemExit(f"{n_procs} processes: run failed: {res.message}")
    p = res.last
    return {"procs": n_procs, "steps": p.steps, "step_wall_s": p.wall_s, "steps_per_s": p.steps_per_s,
            "rtf_at_10s_steps": p.real_time_factor, "total_wall_s": total, "peak_rss_mib": peak[0] / 1024}


def mac_cost(n: int = 20000) -> dict | None:
    """Per-envelope cost [us] of the run key's MAC (msgs_json/auth.py) on a toy counter envelope and
    on a 300-byte bundle, beside the wire encode/decode every envelope pays anyway (min of 5 x n);
    None in a checkout without authenticated traffic (a baseline)."""
    import timeit

    try:
        from msgs_json.auth import RunAuth
    except ImportError:
        return None
    from msgs_json.envelope import Envelope
    from msgs_json.wire import decode_envelope_mac, encode_envelope

    auth = RunAuth(bytes(32))
    out = {}
    for kind, env in (("toy", Envelope(123_000_000_000, "c3", 41, "/toy/count/c3", '{"c": 41, "crc": 123456789}')),
                      ("bundle", Envelope(123_000_000_000, "sat_11", 41, "/sat_12/dtn/in", bytes(range(256)) + bytes(44)))):
        text = encode_envelope(env, auth.mac(env))

        def us(f):
            return min(timeit.repeat(f, number=n, repeat=5)) / n * 1e6

        out[kind] = {"mac": us(lambda env=env: auth.mac(env)),
                     "verify": us(lambda env=env, t=text: auth.verify(*decode_envelope_mac(t, env.topic)))
                     - us(lambda env=env, t=text: decode_envelope_mac(t, env.topic)),
                     "encode": us(lambda env=env: encode_envelope(env)),
                     "decode": us(lambda env=env, t=text: decode_envelope_mac(t, env.topic))}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--procs", type=int, nargs="+", default=[2, 8, 24])
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--no-bag", action="store_true")
    a = ap.parse_args()
    print(f"{'procs':>5} {'steps':>6} {'wall_s':>8} {'steps/s':>8} {'RTF@10s':>8} {'startup+all_s':>13} {'peakRSS_MiB':>11}")
    for n in a.procs:
        r = bench(n, a.steps, not a.no_bag)
        print(f"{r['procs']:>5} {r['steps']:>6} {r['step_wall_s']:>8.2f} {r['steps_per_s']:>8.1f} "
              f"{r['rtf_at_10s_steps']:>8.0f} {r['total_wall_s']:>13.1f} {r['peak_rss_mib']:>11.0f}", flush=True)
    cost = mac_cost()
    if cost is not None:
        for kind, c in cost.items():
            print(f"MAC per {kind} envelope: {c['mac']:.2f} us to make, {c['verify']:.2f} us to check "
                  f"(wire encode {c['encode']:.2f} us, decode {c['decode']:.2f} us)")


if __name__ == "__main__":
    main()
