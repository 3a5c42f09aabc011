"""Local engine and bag writer overhead (issue 5 target: local engine >= 1000x real time on the paper run).

Drives 26 toy participants (24 satellites that each emit one observation-sized JSON envelope every
10 s of sim time and read everything on a shared topic, router, ground) over 6 h with a 1 s max
step, streaming every envelope into an MCAP bag like `constellation run --engine local` will.
Prints engine-only and engine+bag wall times and per-step/per-envelope costs.

    .venv/bin/python bench/bench_local_engine.py
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from bringup.engine.local import run_local
from bringup.recording.bag import BagWriter
from msgs_json.envelope import Emit, StepResult

S = 1_000_000_000
BODY = '{"v":1,"sat":"sat_11","gp":12,"t_ns":0,"assumed_value":112.5,"recorded_value":118.0,"schedule_version":3}'


class Toy:
    def __init__(self, name, period_ns):
        self.name, self.period_ns, self.next = name, period_ns, period_ns
        self.topic = f"/{name}/observations"

    def subscriptions(self):
        return ["/shared"]

    def start(self, t0_ns):
        return StepResult([], self.next)

    def step(self, t_ns, inbox):
        if self.period_ns and t_ns >= self.next:
            self.next += self.period_ns
            return StepResult([Emit(self.topic, BODY, t_ns), Emit("/shared", BODY, t_ns)], self.next)
        return StepResult(None, self.next if self.period_ns else None)

    def finish(self, t_ns):
        return []


def build():
    sats = [Toy(f"sat_{p}{s}", 10 * S) for p in (1, 2, 3) for s in range(1, 9)]
    return sats + [Toy("router", 0), Toy("ground", 0)]


def main() -> None:
    horizon = 6 * 3600 * S
    r = run_local(build(), horizon_ns=horizon, max_step_ns=S)
    n = sum(r.counts_by_topic.values())
    print(f"engine only: {r.steps} steps, {n} envelopes, {r.wall_s:.2f} s wall, "
          f"RTF {r.real_time_factor:.0f}x, {r.wall_s / r.steps * 1e6:.1f} us/step")
    with tempfile.TemporaryDirectory() as d, BagWriter(Path(d) / "bag") as bag:
        t = time.perf_counter()
        r = run_local(build(), horizon_ns=horizon, max_step_ns=S, sink=bag.write_envelope,
                      sink_many=bag.write_envelopes, on_step=bag.write_clock)
        bag.close()
        w = time.perf_counter() - t
        size = sum(p.stat().st_size for p in (Path(d) / "bag").iterdir())
    print(f"engine + bag (/clock every step): {w:.2f} s wall, RTF {horizon / S / w:.0f}x, "
          f"bag {size / 1e6:.1f} MB")


if __name__ == "__main__":
    main()
