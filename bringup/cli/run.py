"""`constellation run`: one whole run of a scenario, recorded and reported (docs/design.md section 6).

``--engine ros`` (default): the clock, the router / ground station and one OS process per satellite
(or per ``--sats-per-process K`` satellites) over DDS (bringup/engine/ros/launcher.py), recording
every topic into ``OUT/bag``. ``--engine local``: the same
node logic in this process (bringup/engine/local.py), recording the same topics. Either way the run
ends with ``OUT/report.json`` (rebuilt from the bag, bringup/analysis/report.py), ``OUT/report.md`` and
``OUT/plots/*.png``, ``OUT/scenario.toml`` (the resolved scenario; report.json's ``provenance``:
bringup/scenario/provenance.py), and a non-zero exit with a one-line message if anything failed.
However the run ends (complete, failed, interrupted), the bag it leaves is sealed under the user's
key (bringup/recording/bag_seal.py, ``OUT/bag/seal.json``) before its report is made from it.

Checked by tests/unit/test_cli_exit.py (a local run's outputs complete, one-line errors) and
tests/system/test_engines_equal.py (both engines, same traces and report).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sqlite3
import sys
import time
from contextlib import nullcontext
from pathlib import Path
from types import SimpleNamespace

from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

from bringup.analysis.report import ReportBuilder, RunMeta, report_from_bag
from bringup.analysis.report_md import report_md
from bringup.cli import gateway_run as cli_gateway
from bringup.cli.common import (
    add_key_args,
    add_scenario_args,
    keys_from_args,
    overrides_of,
    scenario_from_args,
)
from bringup.cli.main import main as cli_main
from bringup.cli.run_folder import RunFolder, json_text, write_text_atomic
from bringup.engine.local import LocalEngine
from bringup.engine.ros.factory import FACTORY, PREPARE
from bringup.engine.ros.ground_gateway import GATEWAY_DIR
from bringup.engine.ros.launcher import launch, lease_domain_id
from bringup.engine.ros.run_spec import MAX_DOMAIN_ID, RunSpec
from bringup.engine.store_batches import StoreBatches
from bringup.errors import UserError
from bringup.recording.bag_seal import check_bag, seal_bag
from bringup.recording.recorder_process import Recorder
from bringup.scenario.participants import (
    AUTO_SAT_PROCESSES,
    all_participants,
    create_stores,
    process_groups,
    roles_for,
    sats_per_process_auto,
)
from bringup.scenario.provenance import provenance
from bringup.scenario.work import check_work
from bringup.scenario.work import describe as describe_work
from bringup.scenario.world import World
from bringup.stop_signals import STOP_SIGNALS, Interrupted, raise_pending, stop_on_signals
from dtn_router.router import ROUTER_NAME
from ground_station.gateway import FLUSH_S
from ground_station.operator_requests import OPERATOR_DIR
from msgs_json.envelope import Envelope

# every file a run writes is closed before run() returns (bag by its writer or recorder process,
# stores, report.json, report.md, plots): the console script may skip the interpreter's teardown
# (bringup/cli/main.py entry)
FAST_EXIT = True

_NS = 1_000_000_000
MAX_ISL_DELAY_S = 86_400.0  # one day of extra one-way delay: beyond any TTL, still a number
MAX_RESTARTS = 1000
# wall seconds a ROS process has to finish a step (with K satellites per process: K times this)
ACK_TIMEOUT_S = 10.0


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_scenario_args(p, knowledge=True)
    p.add_argument("--mode", choices=("distributed", "centralized", "nonagile"), default="distributed",
                   help="distributed: every satellite plans onboard from what reached it over the DTN; "
                        "centralized: the ground plans from downlinks and uplinks plans at passes; nonagile: "
                        "satellites look straight down (default: distributed)")
    p.add_argument("--engine", choices=("ros", "local"), default="ros",
                   help="ros: real rclpy nodes, one OS process per satellite (or --sats-per-process), DDS on "
                        "loopback; local: the same logic in one process, identical results (default: ros)")
    p.add_argument("--out", type=Path, default=None, help="run folder (default runs/<scenario>-<mode>)")
    p.add_argument("--ground-gateway", default=None, metavar="URL",
                   help="centralized mode: the ground's bundle agent exchanges bundles with a DTN "
                        "node: tcpcl4|tcpcl3|udp://HOST:PORT?node=N[&listen=HOST:PORT]"
                        "[&foreign=accept|refuse]; "
                        "the downlinks go to ipn:N.1, the node's bundles up to their satellite "
                        "(docs/guide/dtn-interop.md)")
    p.add_argument("--real-time-factor", type=float, default=None,
                   help="pace the clock at this many sim seconds per wall second (default: as fast as possible)")
    p.add_argument("--no-progress", action="store_true", help="no progress display")
    p.add_argument("--no-plots", action="store_true", help="skip the plots")
    p.add_argument("--plot-formats", type=_plot_formats, default=("png",), metavar="png[,svg][,pdf]",
                   help="write each plot as PNG and also in these vector formats (default: png)")
    p.add_argument("--isl-delay-s", type=float, default=0.0, help="extra one-way ISL delay [s] added by the router")
    p.add_argument("--cut", action="append", default=[], metavar="A-B@T1-T2",
                   help="cut the ISL between satellites A and B from T1 to T2 [s] (repeatable)")
    p.add_argument("--viz-period-s", type=float, default=None, metavar="S",
                   help="sim seconds between visualisation frames: the bag's fixes, markers and /tf, and the ros "
                        "engine's live topics (default: the scenario's [viz] period_s, 60)")
    p.add_argument("--sats-per-process", default="auto", metavar="K|auto",
                   help="ros engine: satellites hosted by one OS process (one executor, one node each); "
                        f"auto: 1 up to {AUTO_SAT_PROCESSES} satellites (and with --restart), else as few "
                        f"as keep {AUTO_SAT_PROCESSES} satellite processes (default auto)")
    add_key_args(p)
    p.add_argument("--domain-id", type=int, default=None, metavar="N",
                   help="ros engine: run on ROS_DOMAIN_ID N (0..232), e.g. to attach RViz or Foxglove; the run does "
                        "not lease it, so no other run may use it (default: a free id 1..101, leased)")
    p.add_argument("--namespace", default="", metavar="NS",
                   help="ros engine: push every node into NS (as launch's PushRosNamespace), e.g. /fleet")
    p.add_argument("--ros-args", nargs=argparse.REMAINDER, default=[], metavar="ARG",
                   help="ros engine: the rest of the command line is given to every node process as ROS "
                        "arguments, e.g. --ros-args -r sat_12:__ns:=/moved/sat_12 (must come last)")
    p.add_argument("--force", action="store_true",
                   help="run a scenario past the work estimate's limits (ISL links in view, DP cells; "
                        "bringup/scenario/work.py): for a machine known to be fast enough")
    p.add_argument("--live-commands", action="store_true",
                   help="ros engine: take operator commands while the run goes on (`constellation task --out OUT "
                        "...`, `constellation command --out OUT SAT mode safe`; docs/guide/operations.md)")
    p.add_argument("--restart", type=int, default=0, metavar="N",
                   help="ros engine: restart a crashed process (satellite, router, ground or the clock) up to "
                        "N times; every process checkpoints each step and resumes from it (default 0: a crash "
                        "ends the run)")


def parse_cut(text: str) -> tuple[str, str, float, float]:
    try:
        link, span = text.split("@")
        a, b = link.split("-")
        t1, t2 = (float(x) for x in span.split("-"))
    except ValueError:
        raise UserError(f"--cut {text!r}: expected A-B@T1-T2, e.g. sat_11-sat_21@600-1200") from None
    if not t2 > t1:
        raise UserError(f"--cut {text!r}: T2 must be after T1")
    return a, b, t1, t2


def sats_per_process(args: argparse.Namespace, n_sats: int) -> int:
    """``--sats-per-process`` as a number (auto: participants.sats_per_process_auto, or 1 with
    ``--restart``); one-line UserError when it is not a number >= 1, or above 1 with ``--restart``
    (a host checkpoints its step in one participant's store)."""
    text = str(getattr(args, "sats_per_process", "auto"))
    if text == "auto":
        k = 1 if getattr(args, "restart", 0) else sats_per_process_auto(n_sats)
    else:
        try:
            k = int(text)
        except ValueError:
            raise UserError(f"--sats-per-process {text!r}: expected a number >= 1 or 'auto'") from None
        if k < 1:
            raise UserError(f"--sats-per-process {text!r}: expected a number >= 1 or 'auto'")
    if k > 1 and getattr(args, "restart", 0):
        raise UserError(f"--restart with {k} satellites per process: a process checkpoints its step in one "
                        "satellite's bundle store, so restarts need --sats-per-process 1")
    return k


def run(args: argparse.Namespace) -> int:
    if args.real_time_factor is not None and not args.real_time_factor > 0:
        raise UserError(f"--real-time-factor {args.real_time_factor}: must be > 0")
    if not 0 <= args.isl_delay_s <= MAX_ISL_DELAY_S:
        raise UserError(f"--isl-delay-s {args.isl_delay_s}: must be in 0..{MAX_ISL_DELAY_S:g} s")
    if not 0 <= args.restart <= MAX_RESTARTS:
        raise UserError(f"--restart {args.restart}: must be in 0..{MAX_RESTARTS}")
    sc = scenario_from_args(args)
    gateway_spec = cli_gateway.gateway_spec(args)
    if args.domain_id is not None and not 0 <= args.domain_id <= MAX_DOMAIN_ID:
        raise UserError(f"--domain-id {args.domain_id}: expected 0..{MAX_DOMAIN_ID}")
    if args.engine != "ros" and (args.domain_id is not None or args.namespace or args.ros_args):
        raise UserError("--domain-id, --namespace and --ros-args are for --engine ros")
    if args.viz_period_s is not None:
        if not 0 < args.viz_period_s <= 86400:
            raise UserError(f"--viz-period-s {args.viz_period_s:g}: expected 0 < S <= 86400")
        sc = sc.with_overrides(viz_period_s=args.viz_period_s)
    cuts = [parse_cut(c) for c in args.cut]
    # CPU: refused here, before the folder or the world (a run that could not step in useful time)
    args.work_estimate = check_work(sc, force=getattr(args, "force", False))  # (said once the folder is ours)
    per_process = sats_per_process(args, len(sc.sat_names)) if args.engine == "ros" else 1
    for a, b, _, _ in cuts:
        for n in (a, b):
            if n not in sc.sat_names:
                raise UserError(f"--cut: {n!r} is not a satellite of the scenario ({sc.sat_names[0]}..)")
    # made absolute here, against the folder the user ran the command in (the ROS engine's
    # processes run in the repository's folder)
    keys = keys_from_args(args)
    # SIGTERM, SIGHUP, SIGQUIT as Ctrl-C: the folder says "interrupted" with the signal, a partial
    # report of what the bag holds, the keys removed (bringup/stop_signals.py)
    # the gateway's peer is reached before anything else is made: an unreachable one is one line, exit 2
    args._gateway = cli_gateway.start_gateway(gateway_spec, args.engine)
    args._gateway_url = gateway_spec.url if gateway_spec is not None else None
    with cli_gateway.closing(args._gateway), stop_on_signals(), \
            RunFolder(args.out or Path("runs") / f"{sc.name}-{args.mode}") as folder:
        out = folder.path
        bag_dir = out / "bag"
        try:
            try:
                return _run(sc, cuts, out, bag_dir, args, folder, per_process, keys)
            except sqlite3.Error as exc:  # a satellite's bundle store (sat_node/dtn/store.py)
                raise UserError(f"a satellite's SQLite store in {out / 'store'} failed: {exc}"
                                + _space_note(out)) from None
        except BaseException as exc:
            _leave_partial_report(folder, bag_dir, exc)
            raise


def _space_note(out: Path) -> str:
    """' (no space left on device: N KiB free)' when the run folder's file system is (nearly) full."""
    try:
        free = shutil.disk_usage(out).free
    except OSError:
        return ""
    return f" (no space left on device: {free // 1024} KiB free)" if free < 2**20 else ""


def _run(sc, cuts, out: Path, bag_dir: Path, args, folder: RunFolder, per_process: int, keys) -> int:
    def say(*a) -> None:
        print(*a, file=sys.stderr)
    say(f"run: {sc.name}, {sc.n_sats} satellites, {sc.scenario.horizon_s / 3600:g} h, "
        f"mode {args.mode}, engine {args.engine}"
        + (f" ({per_process} satellites per process)" if per_process > 1 else "") + f" -> {out}")
    say(f"run: BPSec key {keys.bpsec_from}")
    if getattr(args, "live_commands", False) and args.engine != "ros":
        raise UserError("--live-commands needs --engine ros (a local run has no live process to command; "
                        "script the commands with [[commands]] instead)")
    if getattr(args, "work_estimate", None):
        say(f"run: estimate: {describe_work(args.work_estimate)}" + (" (--force)" if args.force else ""))
    t0 = time.perf_counter()
    stores_ready = None
    if args.engine == "local":  # the ros engine's satellites make their own, in their processes
        stores_ready = _fresh_store_dir(out / "store", sc.sat_names if args.mode == "distributed" else [])
    world = World.cached(sc, out / "cache", progress=lambda stage: say(f"run: building the world: {stage}"))
    world_path = out / "cache" / f"world-{world.key}.pkl"
    if not world_path.exists():
        world.save(world_path)
    say(f"run: world ready in {time.perf_counter() - t0:.1f} s ({len(world.isl_plan)} ISL contacts, "
        f"{len(world.ground_plan)} ground contacts, {world.n_gp} ground points)")
    meta = RunMeta.for_world(world, args.mode, args.engine)
    if meta.regions_never_in_view:
        print(f"run: warning: no satellite has region(s) {', '.join(meta.regions_never_in_view)} in its field of "
              "regard during the horizon: their ground points can only count 0", file=sys.stderr)
    # what the run is made from (report.json and the bag's /run/meta: provenance), and the resolved
    # scenario beside the report, loadable on its own (`constellation run --scenario OUT/scenario.toml`)
    meta.provenance = provenance(sc, getattr(args, "_argv", None))
    write_text_atomic(out / "scenario.toml", meta.provenance["scenario_toml"])
    router_kw = {"extra_delay_s": args.isl_delay_s, "cuts": cuts} if (args.isl_delay_s or cuts) else None
    rep = None
    if args.engine == "local":
        stores_ready()  # (before the recorder forks: no other thread runs then)
        runtime, rep = _run_local(world, args, meta, bag_dir, out, router_kw, keys, show=not args.no_progress)
    else:
        runtime = _run_ros(world, world_path, args, meta, bag_dir, out, router_kw, keys, say,
                           show=not args.no_progress, per_process=per_process)
        if getattr(args, "_gateway_url", None):  # what the ground's and satellites' processes wrote
            runtime["_gateway"] = cli_gateway.write_gateway_report_ros(out, say)
    seal_bag(bag_dir)  # (the bag is closed: every process that wrote it has ended)
    code = _finish(out, bag_dir, runtime, world, args, say, rep=rep)
    folder.done()
    return code


def _leave_partial_report(folder: RunFolder, bag_dir: Path, exc: BaseException) -> None:
    """The run failed: if its bag holds anything, leave a report of it marked ``partial`` (never
    the report of another run: RunFolder removed those), and say so."""
    if not bag_dir.exists():
        return
    notes: list[str] = []
    try:
        seal_bag(bag_dir)  # what the run left, as it left it
        rep = report_from_bag(bag_dir, warn=notes.append)
    except (UserError, OSError, ValueError):
        return
    rep["partial"] = True
    rep["run_error"] = " ".join(str(exc).split())[:500] or type(exc).__name__
    try:
        write_text_atomic(folder.path / "report.json", json_text(rep, indent=2, sort_keys=True) + "\n")
    except OSError:
        return
    folder.mark_partial_report()
    how = f"was {exc}" if isinstance(exc, Interrupted) else "failed"
    print(f"run: the run {how}; {folder.path / 'report.json'} is a partial report of what the bag holds "
          f"(t = {rep['horizon_reached_s']:g} s of {rep['horizon_s']:g} s)", file=sys.stderr)


def _plot_formats(text: str) -> tuple[str, ...]:
    """``--plot-formats``: a comma-separated subset of png, svg, pdf (PNG is always written)."""
    fmts = tuple(dict.fromkeys(f.strip().lower() for f in text.split(",") if f.strip()))
    bad = [f for f in fmts if f not in ("png", "svg", "pdf")]
    if bad or not fmts:
        raise argparse.ArgumentTypeError(f"{text!r}: expected png, svg and/or pdf, comma-separated")
    return fmts


#: wall seconds between two progress lines when the output is not a terminal (a log, CI, nohup)
PROGRESS_LOG_PERIOD_S = 10.0


def _progress_display(show: bool, horizon_ns: int, *, terminal: bool | None = None, period_s: float | None = None):
    """A rich progress bar (sim time, real-time factor, envelopes) on a terminal; on anything else
    (a pipe, a log file, CI) one line on stderr every PROGRESS_LOG_PERIOD_S wall seconds and at every
    tenth of the horizon; or a no-op with ``show`` False. Returns (rich Progress or None, update)."""
    if not show:
        return None, (lambda **kw: None)

    def hms(t_ns: int) -> str:
        s = int(t_ns // _NS)
        return f"{s // 3600}:{s // 60 % 60:02d}:{s % 60:02d}"

    if terminal is None:
        terminal = sys.stdout.isatty()
    if not terminal:
        period = PROGRESS_LOG_PERIOD_S if period_s is None else period_s
        state = {"wall": time.monotonic(), "tenth": 0}

        def log_line(*, t_ns: int, rtf: float | None, extra: str = ""):
            tenth = int(10 * t_ns // max(horizon_ns, 1))
            now = time.monotonic()
            if now - state["wall"] < period and tenth <= state["tenth"]:
                return
            state["wall"], state["tenth"] = now, max(tenth, state["tenth"])
            rate = f", {rtf:,.0f}x real time" if rtf else ""
            print(f"run: sim {hms(t_ns)} of {hms(horizon_ns)} ({100.0 * t_ns / max(horizon_ns, 1):.1f} %){rate}"
                  f"{', ' + extra if extra else ''}", file=sys.stderr, flush=True)

        return None, log_line

    prog = Progress(TextColumn("[bold]sim {task.fields[sim]}"), BarColumn(), TextColumn("{task.percentage:>5.1f}%"),
                    TextColumn("RTF {task.fields[rtf]}"), TextColumn("{task.fields[extra]}"), TimeElapsedColumn(),
                    transient=False, refresh_per_second=4)
    task = prog.add_task("run", total=horizon_ns, sim="0:00:00", rtf="-", extra="")

    def update(*, t_ns: int, rtf: float | None, extra: str = ""):
        prog.update(task, completed=t_ns, sim=hms(t_ns), rtf=f"{rtf:,.0f}x" if rtf else "-", extra=extra)

    return prog, update


def _run_local(world, args, meta, bag_dir: Path, out: Path, router_kw, keys, *, show: bool) -> tuple[dict, dict]:
    """The run on the local engine; returns its runtime figures and its report (built by the
    recorder process from the envelopes it wrote: the same body as `constellation report BAG`,
    tests/system/test_engines_equal.py)."""
    sc = world.scenario
    store_dir = out / "store"  # (made by run(): _fresh_store_dir)
    # the recorder (bag, visualisation, report decoding) forks first, before the stores open
    with Recorder(bag_dir, world, report=ReportBuilder) as rec:
        parts = all_participants(world, args.mode, store_dir=store_dir, router_kw=router_kw,
                                 bpsec_key=keys.bpsec, command_key=keys.command or None,
                                 gateway=getattr(args, "_gateway", None))
        prog, update = _progress_display(show, sc.horizon_ns)
        rec.write_envelope(Envelope(0, "run", 0, "/run/meta", json.dumps({"meta": meta.__dict__})))

        def progress(p) -> None:
            extra = f"{p.envelopes:,} msgs"
            if p.in_flight is not None:  # the ISL medium's copies still travelling (StepResult.in_flight)
                extra += f", {p.in_flight} bundles in flight"
            update(t_ns=p.t_ns, rtf=p.real_time_factor, extra=extra)

        # one store commit per satellite every few steps, not every step (bringup/engine/store_batches.py)
        batches = StoreBatches(s for s in (getattr(getattr(p, "agent", None), "store", None) for p in parts)
                               if s is not None)

        # the ISL medium's copies in flight after the previous step, plotted from the bag (metrics_feed.py)
        router = next((q for q in parts if q.name == ROUTER_NAME), None)

        def on_step(t_ns: int) -> None:
            raise_pending()  # (a stop signal whose exception a finalizer dropped: bringup/stop_signals.py)
            rec.step(t_ns, in_flight=None if router is None else len(router.pending))
            batches.step()

        if prog is not None:
            prog.start()
        batches.start()
        try:
            # every participant configured and activated before its start, deactivated after its
            # finish; cleaned up (stores closed) and shut down below (bringup/engine/lifecycle.py)
            engine = LocalEngine(parts, horizon_ns=sc.horizon_ns,
                                 max_step_ns=round(sc.scenario.lockstep_max_step_s * _NS),
                                 sink=rec.write_envelope, sink_many=rec.write_envelopes, on_step=on_step,
                                 progress=progress, progress_interval_s=0.25)
            res = engine.run(release=False)
        except BaseException:
            batches.abandon()
            raise
        finally:
            if prog is not None:
                prog.stop()
        batches.finish()  # after the participants' finish, before the stores close
        runtime = {"wall_s": res.wall_s, "real_time_factor": res.real_time_factor, "steps": res.steps,
                   "envelopes": sum(res.counts_by_topic.values()),
                   "rejected_messages": sum(getattr(p, "rejected", 0) for p in parts),
                   "cgr_queries": sum(getattr(getattr(p, "agent", None), "cgr_queries", 0) for p in parts)}
        # one process, no network: nothing reaches the nodes from outside the run (the ROS clock
        # writes what its processes rejected here)
        rec.write_envelope(Envelope(sc.horizon_ns, "run", 1, "/run/meta", json.dumps(
            {"meta": meta.__dict__, "runtime": runtime, "security": {"rejected_by_process": {}}})))
        # while the recorder finishes the bag and the report, the satellites' stores close: SQLite
        # checkpoints each WAL into its file and syncs it, mostly waiting on the disk, so the 24
        # closes run side by side (~1 s one after the other on the paper run)
        gateway = cli_gateway.write_gateway_report(out, parts, lambda *a: print(*a, file=sys.stderr))
        # (the life cycle's cleanup closes them, 8 at a time; then every participant is shut down)
        rep = rec.finish(meta, json.loads(json.dumps(runtime)), meanwhile=lambda: engine.release(workers=8))
        if gateway is not None:  # the ground gateway's counters, each policy decision per reason
            rep["gateway"] = gateway
    return runtime, rep


def spec_overrides(args: argparse.Namespace) -> dict:
    """What the ROS engine's processes apply to the scenario file to get the run's scenario
    (RunSpec.load_scenario): the named options, ``--viz-period-s`` and the ``--set`` texts."""
    return {**overrides_of(args), "viz_period_s": args.viz_period_s, "set": list(args.set)}


def _fresh_store_dir(store_dir: Path, sats: list[str]):
    """An empty ``store_dir``, its satellites' new stores started (participants.create_stores: the
    returned ``wait()``)."""
    if store_dir.exists():
        shutil.rmtree(store_dir)
    store_dir.mkdir()
    return create_stores(store_dir, sats)


def _run_ros(world, world_path: Path, args, meta, bag_dir: Path, out: Path, router_kw, keys, say, *,
             show: bool, per_process: int = 1) -> dict:
    sc = world.scenario
    live = bool(getattr(args, "live_commands", False))
    groups = process_groups(roles_for(world, args.mode, live_commands=live), world.sat_names, per_process)
    extra_live = {}
    if live:  # the folder live operator requests go into (ground_station/operator_requests.py)
        op_dir = out / OPERATOR_DIR
        if op_dir.exists():
            shutil.rmtree(op_dir)
        op_dir.mkdir(mode=0o700)
        extra_live = {"operator_dir": str(op_dir.resolve())}
        say(f"run: live commands: constellation task --out {out} --lat .. --lon .. --priority P --by ISO")
    store_dir = out / "store"
    if store_dir.exists():
        shutil.rmtree(store_dir)
    store_dir.mkdir()
    # --ground-gateway: the ground's process runs the gateway, every process writes its part of
    # gateway.json into gateway_dir at its finish (bringup/engine/ros/ground_gateway.py); the final
    # step may wait for the peer's last acknowledgments (up to FLUSH_S) and the session's end
    extra_gateway, ack_extra_s = {}, 0.0
    if getattr(args, "_gateway_url", None):
        gw_dir = out / GATEWAY_DIR
        if gw_dir.exists():
            shutil.rmtree(gw_dir)
        extra_gateway = {"ground_gateway": args._gateway_url, "gateway_dir": str(gw_dir.resolve())}
        ack_extra_s = FLUSH_S + 20.0
    # the satellites' numba kernels compiled once before the processes start (prepare), and no bound
    # on the start: a slow one (cold caches, a loaded machine) is waited for and named, never fatal
    spec = RunSpec(factory=FACTORY, prepare=PREPARE, startup_timeout_s=None,
                   roles=list(groups), groups={g: m for g, m in groups.items() if m != [g]},
                   # a process steps its K satellites one after the other: K times the one-satellite deadline
                   ack_timeout_s=ACK_TIMEOUT_S * per_process + ack_extra_s,
                   scenario=str(Path(sc.source_path).resolve()),
                   overrides=spec_overrides(args), mode=args.mode,
                   namespace=args.namespace, ros_args=[a for a in args.ros_args if a != "--"],
                   real_time_factor=args.real_time_factor, bag_dir=str(bag_dir.resolve()),
                   max_restarts=args.restart, restart_wait_s=120.0 if args.restart else 0.0,
                   state_dir=str((out / "state").resolve()) if args.restart else None,
                   extra={"world": str(world_path.resolve()), "world_key": world.key,
                          "store_dir": str(store_dir.resolve()), "meta": meta.__dict__,
                          "router": router_kw, **extra_live, **extra_gateway})
    prog, update = _progress_display(show, sc.horizon_ns)

    last_status = [""]

    def progress(p) -> None:
        if p.status:  # before step 0: preparing, or waiting for processes to be ready
            update(t_ns=0, rtf=None, extra=p.status)
            if p.status != last_status[0] and (not show or prog is None or p.status.startswith("prepared in")):
                if prog is not None:  # the prepare time stays on screen above the bar
                    prog.console.print(f"run: {p.status}", highlight=False)
                else:
                    print(f"run: {p.status}", file=sys.stderr)
            last_status[0] = p.status
            return
        extra = f"{p.steps:,} steps, {p.steps_per_s:,.0f} steps/s"
        if p.in_flight is not None:  # the ISL medium's copies still travelling, from the hosts' acks
            extra += f", {p.in_flight} bundles in flight"
        update(t_ns=p.t_ns, rtf=p.real_time_factor, extra=extra)

    # --domain-id N: that id, not leased (the user chose it, e.g. to attach RViz); else a leased free one
    given = nullcontext(SimpleNamespace(domain_id=args.domain_id)) if args.domain_id is not None else None
    with given or lease_domain_id() as lease:
        # (also in OUT/run_spec.json): what a user needs to look at the live run with ROS tools
        say(f"run: ROS_DOMAIN_ID={lease.domain_id} (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST)")
        if prog is not None:
            prog.start()
        t0 = time.perf_counter()
        try:
            # the hosts forked from this process, their code and kernels loaded once (fork_start.py)
            res = launch(spec, out, progress=progress, domain_id=lease.domain_id, keys=keys, fork=cli_main)
        finally:
            if prog is not None:
                prog.stop()
    wall = time.perf_counter() - t0
    restarts = getattr(res, "restarts", {}) or {}
    if res.returncode - 128 in STOP_SIGNALS:  # stopped by a signal: the exit code says which, as everywhere
        say(f"run: {res.message} (logs in {out / 'logs'})")
        raise Interrupted(res.returncode - 128)
    if not res.ok:
        raise UserError(f"ROS run failed: {res.message} (logs in {out / 'logs'})")
    last = res.last
    return {"wall_s": wall, "real_time_factor": (sc.scenario.horizon_s / wall) if wall > 0 else None,
            "steps": last.steps if last else None, "domain_id": res.domain_id,
            "process_restarts": sum(restarts.values())}


def _finish(out: Path, bag_dir: Path, runtime: dict, world, args, say, *, rep: dict | None = None) -> int:
    """Plots, report.md, then report.json (last: its presence means the others are there), each
    written whole (a temporary name renamed)."""
    if rep is None:  # (the local engine's recorder built it from what it wrote, as report BAG does)
        rep = report_from_bag(bag_dir, warn=lambda line: say(f"run: warning: {line}"))
    else:
        rep["integrity"] = check_bag(bag_dir).as_dict()
    gateway = runtime.pop("_gateway", None)
    if gateway is not None:  # (ROS engine: the ground gateway's counters, each policy decision per reason)
        rep["gateway"] = gateway
    rep["runtime"].update({k: v for k, v in runtime.items() if k not in rep["runtime"]})
    rep["runtime"].update({"wall_s": runtime.get("wall_s"), "real_time_factor": runtime.get("real_time_factor")})
    plots = []
    if not args.no_plots:
        # here, not at the top: matplotlib costs ~0.27 s to import (python -X importtime), paid
        # only when plots are made (not with --no-plots, as the tests and sweeps run)
        from bringup.analysis.run_figures import run_plots

        stage = out / f".staging-{os.getpid()}"
        shutil.rmtree(stage, ignore_errors=True)
        made = run_plots(stage, bag_dir, world, rep, formats=args.plot_formats)
        (stage / "plots").rename(out / "plots")
        shutil.rmtree(stage, ignore_errors=True)
        plots = [out / "plots" / p.name for p in made]
    write_text_atomic(out / "report.md", report_md(rep, plots, base=out))
    write_text_atomic(out / "report.json", json_text(rep, indent=2, sort_keys=True) + "\n")
    rej = rep.get("security", {}).get("rejected") or {}
    if rej:
        say(f"run: {sum(rej.values())} messages from outside the run rejected and not acted on "
            f"({', '.join(f'{k} {n}' for k, n in rej.items())}; report.json security)")
    v = rep["value"]
    d = rep["dtn"]
    say(f"run: done in {runtime.get('wall_s', 0):.1f} s "
        f"(RTF {runtime.get('real_time_factor') or 0:,.0f}x): value {v['cumulative']:.0f}, "
        f"{rep['observations']['count']} observations, "
        f"{(rep['coverage']['gp_observed_fraction'] or 0) * 100:.1f} % of GPs, "
        f"bundles {d.get('bundles_delivered', 0)}/{d.get('bundles_created', 0)} delivered -> {out / 'report.json'}")
    return 0
