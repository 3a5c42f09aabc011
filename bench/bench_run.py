"""Benchmark: a whole `constellation run` on each engine - wall time, real-time factor, peak memory, CPU.

Usage::

    .venv/bin/python bench/bench_run.py [--sats 24 --hours 6 --mode distributed --engines local,ros]
        [--repeat N] [--baseline-src DIR]

Each engine runs as a child process (`python -m bringup.cli run ...`); the process tree's total
resident memory is sampled every 0.25 s from /proc (peak of the RSS sum and of the PSS sum), and the machine's MemAvailable drop during the run (what the run took, whatever else ran), CPU time is the children's
rusage after they exit (user + system, every process of the tree), wall time is measured around the
child. The local engine is the baseline printed beside the ROS engine in the same run, and the two
runs' headline figures are compared (they must be equal: same observations and deliveries).
Where the CPU goes: ``cpu_s_by_kind`` sums each process's CPU (/proc/PID/stat, sampled) by kind -
the ROS engine's clock, satellites, router, contacts (named by the run's ``logs/<role>.pid``
files: forked hosts keep the launcher's command line), the launcher (the `constellation run`
process), the launcher's ``--prepare`` process - and, for the ROS engine, ``phases`` splits wall
and CPU into the start (until the clock's log says every process is ready: step 0 follows), the
steps (until it says the nodes are shut down after the last step) and the end (until the command
exits).
Targets (issue 5): ros >= 60x real time (6 h in <= 6 min), local >= 1000x, total memory <= 4 GiB.
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


def _tree(pid: int) -> list[int]:
    out, todo = [], [pid]
    while todo:
        p = todo.pop()
        out.append(p)
        try:
            with open(f"/proc/{p}/task/{p}/children") as fh:
                todo += [int(x) for x in fh.read().split()]
        except OSError:
            pass
    return out


def _mem_mib(pids: list[int]) -> tuple[float, float]:
    """(sum of RSS, sum of PSS) [MiB] over the processes. RSS counts shared library pages once per
    process; PSS (proportional set size) splits them between the processes that share them, so
    the PSS sum is the memory the tree really takes."""
    rss = pss = 0
    for p in pids:
        try:
            with open(f"/proc/{p}/smaps_rollup") as fh:
                for line in fh:
                    if line.startswith("Rss:"):
                        rss += int(line.split()[1])
                    elif line.startswith("Pss:"):
                        pss += int(line.split()[1])
        except OSError:
            pass
    return rss / 1024, pss / 1024


_TICK = os.sysconf("SC_CLK_TCK")


def _roles_by_pid(logs: Path) -> dict[int, str]:
    """pid -> role from the ROS launcher's ``logs/<role>.pid`` files (forked hosts keep the
    launcher's command line, so the command line cannot tell)."""
    out = {}
    for f in logs.glob("*.pid"):
        try:
            out[int(f.read_text().strip() or 0)] = f.stem
        except (OSError, ValueError):
            pass
    return out


def _cpu_by_pid(pids: list[int], seen: dict[int, tuple[str, float]], logs: Path) -> None:
    """Record each process's CPU seconds so far (user + system, /proc/PID/stat) under its kind: the
    ROS engine's node processes by their role (sat_* -> "satellites"), the rest "prepare" (the
    launcher's `node --prepare`), "launcher" (the `constellation run` process itself) or "other". A
    process that exits between two samples loses at most one sampling period of CPU here; the
    tree's total (rusage) is exact."""
    roles = None
    for p in pids:
        try:
            with open(f"/proc/{p}/stat") as fh:
                f = fh.read().rsplit(")", 1)[1].split()
            cpu = (int(f[11]) + int(f[12])) / _TICK
        except (OSError, IndexError, ValueError):
            continue
        kind = seen.get(p, ("", 0.0))[0]
        if kind in ("", "other"):  # (a forked host is "other" until its pid file is written)
            if roles is None:
                roles = _roles_by_pid(logs)
            role = roles.get(p)
            if role is not None:
                kind = "satellites" if role.startswith("sat_") else role
            elif p == pids[0]:
                kind = "launcher"
            else:
                try:
                    with open(f"/proc/{p}/cmdline", "rb") as fh:
                        argv = fh.read().decode(errors="replace").split("\0")
                except OSError:
                    continue
                kind = "prepare" if "--prepare" in argv else "other"
        seen[p] = (kind, cpu)


def _by_kind(seen: dict[int, tuple[str, float]]) -> dict[str, float]:
    kinds: dict[str, float] = {}
    for kind, c in seen.values():
        kinds[kind] = round(kinds.get(kind, 0.0) + c, 1)
    return dict(sorted(kinds.items()))


def _phases(log: Path, t0: float, marks: dict[str, tuple[float, dict]], seen) -> None:
    """When (wall seconds since the start) the clock's log first said every process was ready (the
    start-up's end: step 0 follows) and that the nodes were shut down (after the last step), with
    the CPU seconds per process kind so far at that moment."""
    if "shut_down" in marks:
        return
    try:
        text = log.read_text(errors="replace")
    except OSError:
        return
    now = time.perf_counter() - t0
    if "ready" not in marks and "every process ready" in text:
        marks["ready"] = (now, _by_kind(seen))
    if "shut_down" not in marks and "nodes shut down in" in text:
        marks["shut_down"] = (now, _by_kind(seen))


def _mem_available_mib() -> float:
    with open("/proc/meminfo") as fh:
        for line in fh:
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) / 1024
    return float("nan")


def run_one(engine: str, args, out: Path, src: str | None = None) -> dict:
    cmd = [sys.executable, "-m", "bringup.cli", "run", "--engine", engine, "--mode", args.mode, "--sats",
           str(args.sats), "--hours", str(args.hours), "--out", str(out), "--no-plots", "--no-progress"]
    env = None
    if src is not None:  # another checkout of the project (e.g. a git worktree of an older commit)
        env = dict(os.environ, PYTHONPATH=os.pathsep.join([src, os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep))
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    # (run from inside the checkout: `python -m` puts the working folder first on sys.path)
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=env, cwd=src)
    peak_rss = peak_pss = 0.0
    avail0 = min_avail = _mem_available_mib()
    seen: dict[int, tuple[str, float]] = {}
    marks: dict[str, tuple[float, dict]] = {}
    while proc.poll() is None:
        tree = _tree(proc.pid)
        _cpu_by_pid(tree, seen, out / "logs")
        _phases(out / "logs" / "clock.log", t0, marks, seen)
        rss, pss = _mem_mib(tree)
        peak_rss, peak_pss = max(peak_rss, rss), max(peak_pss, pss)
        min_avail = min(min_avail, _mem_available_mib())
        time.sleep(0.25)
    wall = time.perf_counter() - t0
    err = proc.stderr.read()
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise SystemExit(f"{engine} run failed: {err[-2000:]}")
    rep = json.loads((out / "report.json").read_text())
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    kinds = _by_kind(seen)
    rt = rep.get("runtime", {})
    # ROS engine: wall and CPU per kind of the start (command start -> every process ready, step 0
    # next), the steps (-> every node shut down after the last step) and the end (-> command exit)
    phases = {}
    if "ready" in marks and "shut_down" in marks:
        (t1, c1), (t2, c2) = marks["ready"], marks["shut_down"]
        phases = {"start": {"wall_s": round(t1, 1), "cpu_s": c1},
                  "steps": {"wall_s": round(t2 - t1, 1),
                            "cpu_s": {k: round(v - c1.get(k, 0.0), 1) for k, v in c2.items()}},
                  "end": {"wall_s": round(wall - t2, 1),
                          "cpu_s": {k: round(v - c2.get(k, 0.0), 1) for k, v in kinds.items()}}}
    return {"engine": engine, "wall_s": round(wall, 2), "real_time_factor": round(args.hours * 3600 / wall, 1),
            "peak_rss_sum_mib": round(peak_rss, 1), "peak_pss_mib": round(peak_pss, 1),
            "peak_mem_taken_mib": round(avail0 - min_avail, 1), "cpu_s": round(cpu, 1), "cpu_cores_avg": round(cpu / wall, 2),
            "value": rep["value"]["cumulative"], "observations": rep["observations"]["count"],
            "bundles_created": rep["dtn"].get("bundles_created"),
            "bundles_delivered": rep["dtn"].get("bundles_delivered"),
            "steps": rt.get("steps"), "cpu_s_by_kind": kinds, "phases": phases}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sats", type=int, default=24)
    ap.add_argument("--hours", type=float, default=6.0)
    ap.add_argument("--mode", default="distributed")
    ap.add_argument("--engines", default="local,ros")
    ap.add_argument("--repeat", type=int, default=1, help="runs per engine (wall time: min and median printed)")
    ap.add_argument("--baseline-src", default=None, metavar="DIR",
                    help="also run each engine from this checkout (e.g. `git worktree add DIR REV`), "
                         "alternating with this one, and print the wall-time ratio of the medians")
    args = ap.parse_args()
    rows = []
    walls: dict[str, list[float]] = {}
    srcs = [None] + ([args.baseline_src] if args.baseline_src else [])
    with tempfile.TemporaryDirectory() as d:
        for eng in args.engines.split(","):
            for k in range(args.repeat):
                for src in srcs:
                    tag = eng if src is None else f"{eng}@baseline"
                    row = run_one(eng, args, Path(d) / f"{tag}-{k}", src)
                    row["engine"] = tag
                    walls.setdefault(tag, []).append(row["wall_s"])
                    if src is None and k == args.repeat - 1:
                        rows.append(row)
                    print(json.dumps(row), flush=True)
    for tag, w in walls.items():
        if len(w) > 1:
            print(f"{tag}: wall min {min(w):.2f} s, median {statistics.median(w):.2f} s over {len(w)} runs "
                  f"(RTF {args.hours * 3600 / statistics.median(w):.0f}x at the median)")
    for eng in args.engines.split(","):
        if f"{eng}@baseline" in walls:
            a, b = statistics.median(walls[eng]), statistics.median(walls[f"{eng}@baseline"])
            print(f"{eng}: this checkout / baseline wall time (medians): {a / b:.3f}")
    if len(rows) == 2:
        a, b = rows
        same = all(a[k] == b[k] for k in ("value", "observations", "bundles_created", "bundles_delivered"))
        print(f"engines agree on value/observations/bundles: {same}")
        print(f"{b['engine']} / {a['engine']} wall time: {b['wall_s'] / a['wall_s']:.1f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
