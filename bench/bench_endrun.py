"""Benchmark: the end of a local `constellation run` (after the engine's loop), and `report BAG` /
`bag-info BAG` on its bag.

Usage::

    nice .venv/bin/python bench/bench_endrun.py --out DIR [run options, e.g. --sats 240 --planes 3
        --hours 1 --planning alone --no-plots]
    nice .venv/bin/python bench/bench_endrun.py --bag DIR/bag      # report BAG and bag-info BAG only
        [--repeat N] [--baseline-src OLD_CHECKOUT]

``--baseline-src``: a checkout of another commit (``git archive COMMIT | tar -x -C DIR``), run
alternately with this one (its packages first on PYTHONPATH, the children in a scratch folder), so
that both see the same machine load; medians of ``--repeat`` runs each, and their ratio.

The run is a child process (``python -c``) that calls bringup.cli.main.main with the engine's loop
(bringup/cli/run.py ``run_local``) wrapped: when the loop returns, the child notes its wall clock,
its own CPU time and its live children's (the recorder, read from /proc); when main returns, the
same again with the reaped children's rusage. So:

* whole command: wall around the child, CPU = the child tree's rusage (user + system);
* end of run: from the loop's return to main's return - the recorder's bag close and report
  (bringup/recording/recorder_process.py), the stores' close, plots, report.md, report.json - wall,
  and CPU of the main process plus what its recorder spent after the loop.

``report BAG`` and ``bag-info BAG`` run as ``constellation report BAG --out FILE`` and ``constellation
bag-info BAG`` children, wall and rusage CPU. The 1-minute load average is printed with each figure
(the machine is shared: compare CPU times rather than wall times).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

_WRAPPER = r"""
import json, os, resource, sys, time

def _self_cpu():
    t = os.times()
    return t.user + t.system

def _live_children_cpu():
    tick = os.sysconf("SC_CLK_TCK")
    pid = os.getpid()
    total = 0.0
    try:
        kids = open(f"/proc/{pid}/task/{pid}/children").read().split()
    except OSError:
        kids = []
    for k in kids:
        try:
            f = open(f"/proc/{k}/stat").read().rsplit(")", 1)[1].split()
            total += (int(f[11]) + int(f[12])) / tick
        except (OSError, IndexError, ValueError):
            pass
    return total

def _reaped_cpu():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime

import bringup.cli.run as R
from bringup.cli.main import main
marks = {}
_orig = R.run_local

def _wrapped(*a, **k):
    res = _orig(*a, **k)
    marks["loop_end"] = [time.perf_counter(), _self_cpu(), _reaped_cpu() + _live_children_cpu()]
    return res

R.run_local = _wrapped
code = main(sys.argv[1:])
marks["end"] = [time.perf_counter(), _self_cpu(), _reaped_cpu() + _live_children_cpu()]
sys.stdout.flush()
print("BENCH-ENDRUN " + json.dumps(marks), file=sys.stderr, flush=True)
os._exit(code)
"""


def _load() -> str:
    return f"load {os.getloadavg()[0]:.2f}"


def _rusage_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _timed(cmd: list[str], src: Path | None) -> tuple[float, float, subprocess.CompletedProcess]:
    env = dict(os.environ)
    if src is not None:
        env["PYTHONPATH"] = os.pathsep.join([str(src), *filter(None, [env.get("PYTHONPATH")])])
    with tempfile.TemporaryDirectory() as scratch:  # not the checkout: '' on sys.path is the scratch folder
        c0, t0 = _rusage_cpu(), time.perf_counter()
        p = subprocess.run(cmd, capture_output=True, text=True, check=False, env=env, cwd=scratch)
        wall, cpu = time.perf_counter() - t0, _rusage_cpu() - c0
    if p.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed ({p.returncode}):\n{p.stderr[-3000:]}")
    return wall, cpu, p


def bench_run(out: Path, extra: list[str], src: Path | None) -> dict[str, tuple[float, float]]:
    cmd = [sys.executable, "-c", _WRAPPER, "run", "--scenario", "paper", "--engine", "local", "--no-progress",
           "--out", str(out.resolve()), *extra]
    wall, cpu, p = _timed(cmd, src)
    line = next(x for x in p.stderr.splitlines() if x.startswith("BENCH-ENDRUN "))
    marks = json.loads(line.split(" ", 1)[1])
    (t1, s1, c1), (t2, s2, c2) = marks["loop_end"], marks["end"]
    done = next((x for x in p.stderr.splitlines() if "run: done in" in x), "")
    print(f"  {done.strip()}")
    print(f"  whole command: wall {wall:.1f} s, CPU {cpu:.1f} s ({_load()})")
    print(f"  end of run:    wall {t2 - t1:.2f} s, CPU {s2 - s1 + c2 - c1:.2f} s "
          f"(main {s2 - s1:.2f} s + recorder {c2 - c1:.2f} s) ({_load()})")
    return {"whole command": (wall, cpu), "end of run": (t2 - t1, s2 - s1 + c2 - c1)}


def bench_bag(bag: Path, src: Path | None) -> dict[str, tuple[float, float]]:
    exe = [sys.executable, "-m", "bringup.cli"]
    with tempfile.TemporaryDirectory() as tmp:
        rw, rc, _ = _timed([*exe, "report", str(bag.resolve()), "--out", str(Path(tmp) / "r.json")], src)
    print(f"  report BAG:    wall {rw:.2f} s, CPU {rc:.2f} s ({_load()})")
    iw, ic, _ = _timed([*exe, "bag-info", str(bag.resolve())], src)
    print(f"  bag-info BAG:  wall {iw:.2f} s, CPU {ic:.2f} s ({_load()})")
    return {"report BAG": (rw, rc), "bag-info BAG": (iw, ic)}


def _median(xs: list[float]) -> float:
    return statistics.median(xs)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, help="run folder to create (the run is made there; with --repeat or "
                    "--baseline-src, OUT-<label>-<k>)")
    ap.add_argument("--bag", type=Path, help="only report BAG and bag-info BAG on this bag")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--baseline-src", type=Path, default=None, help="another checkout, run alternately")
    args, extra = ap.parse_known_args()
    if args.bag is None and args.out is None:
        ap.error("--out or --bag")
    trees = [("this", None)] + ([("baseline", args.baseline_src.resolve())] if args.baseline_src else [])
    got: dict[str, dict[str, list[tuple[float, float]]]] = {label: {} for label, _ in trees}
    for k in range(args.repeat):
        for label, src in (trees if k % 2 == 0 else trees[::-1]):
            print(f"{label} #{k + 1}:")
            if args.bag is not None:
                figs = bench_bag(args.bag, src)
            else:
                out = args.out if len(trees) == 1 and args.repeat == 1 else Path(f"{args.out}-{label}-{k + 1}")
                figs = bench_run(out, extra, src)
                figs.update(bench_bag(out / "bag", src))
            for name, v in figs.items():
                got[label].setdefault(name, []).append(v)
    if len(trees) == 1 and args.repeat == 1:
        return
    print(f"medians of {args.repeat} ({_load()}):")
    for name in got["this"]:
        this = [_median([w for w, _ in got["this"][name]]), _median([c for _, c in got["this"][name]])]
        line = f"  {name:14} this: wall {this[0]:.2f} s, CPU {this[1]:.2f} s"
        if "baseline" in got:
            base = [_median([w for w, _ in got["baseline"][name]]), _median([c for _, c in got["baseline"][name]])]
            line += (f" | baseline: wall {base[0]:.2f} s, CPU {base[1]:.2f} s"
                     f" | CPU ratio {this[1] / base[1]:.2f}")
        print(line)


if __name__ == "__main__":
    main()
