"""Launcher of the ROS engine: the clock process plus one process per participant group.

``launch(spec, out_dir)`` writes the run spec to ``out_dir/run_spec.json`` and starts, each as
``python -m bringup.cli node --run-spec ... --role R``: the clock (lockstep coordinator and MCAP
recorder into ``spec.bag_dir``) and one process per role (N satellites, router, ground station;
what a role hosts comes from the spec's participant factory). Every child gets
``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` (no packet leaves loopback), a run-unique
``ROS_DOMAIN_ID`` (1..101, held by an fcntl lock file for the whole run so parallel runs on one
host never share one; the lock files live in a per-user folder of mode 0700,
bringup/private_files.py ``private_state_dir``, so no other user can pre-create and hold them) and ``FASTRTPS_DEFAULT_PROFILES_FILE`` = bringup/engine/ros/dds/fastdds_profile.xml.
Progress (sim time, real-time factor, steps/s, bundles in flight in the router) goes to a
callback. Ctrl-C, SIGTERM, SIGHUP (the terminal closed) or SIGQUIT (bringup/stop_signals.py): the
clock is asked to stop first (it tells the hosts and closes the bag, which stays readable), then the
hosts; the result's code is 128 + the signal's number (130 for Ctrl-C) and its message names the
signal; the keys file is removed whatever the signal. A child that fails is named in
the result's message (a signal by its name: "process 'sat_11' killed by SIGKILL") with what the
stop left in the bag, and the result is non-zero. The run's keys (bringup/engine/keys.py) go to
``out_dir/run.keys`` (mode 0600) unless the spec names a keys file, and are removed at the end; the
run spec records the keys file and the ROS_DOMAIN_ID, and every child gets the file's SHA-256 in
its environment (``AGILE_DTN_RUN_KEYS_SHA256``) and refuses a file that differs (a file replaced
after the launcher wrote it; bringup/engine/keys.py). Every child holds a lifeline to the launcher
(``AGILE_DTN_LAUNCHER_PID``; bringup/engine/ros/lifeline.py): if the launcher dies, even by
SIGKILL, its processes stop within seconds (the clock closing the bag). A child still running 5 s
after SIGTERM gets SIGUSR1 (node processes then write their Python stacks into their log) and
SIGKILL, and its log says so.
End of a run: after the clock exits 0 the hosts get 10 s to leave (they take ~0.1 s), then
SIGTERM. A host that had to be killed then is not a failure of the run (it acked the final step,
so everything it sent is in the bag and its per-step state is committed); it is listed in the
result's ``lingered``. A host can hang in FastDDS participant destruction during its teardown
(blocked in C, so SIGTERM goes unhandled); node processes skip that destruction
(bringup/engine/ros/host.py exit_now), and this rule keeps any other hang at exit from failing a
complete run.
Each child's stderr goes to ``out_dir/logs/<role>.log`` (appended across restarts) and its pid to
``out_dir/logs/<role>.pid``.

Ready before steps: with the spec's ``prepare`` hook the launcher first runs it once
(``constellation node --prepare``, log ``logs/prepare.log``; e.g. the satellites' numba kernels
compiled into numba's cache, so 24 processes load them instead of all compiling them at once on a
cold cache), then starts the processes; each runs the hook for its role before it says hello. The
clock waits for every hello before step 0 and names the processes it still waits for; those
reports reach ``progress`` as ``LaunchProgress.status`` / ``not_ready`` (bringup/engine/ros/clock_node.py).

Managed nodes: every participant node starts ``unconfigured``; the run's lifecycle manager, started
with the clock (bringup/engine/ros/lifecycle_manager.py; in the clock process so that it runs
wherever the clock does: here, in a container, in a network namespace), calls every node's
lifecycle services, configure -> activate before step 0 and deactivate -> cleanup -> shutdown after
the last step. A node that fails a transition ends the run: the clock reports it (a
``lifecycle_failed`` record), and the result's one-line message names the node, its process, the
transition and the cause that process logged (tests/ros/test_lifecycle_run.py).

Crash and restart: when the spec has ``max_restarts > 0`` a host process that dies
(any exit but 0, e.g. SIGKILL) while the clock runs is started again with the same command, up to
``max_restarts`` times per role; it resumes from its checkpoint (bringup/engine/ros/host.py) and the clock
waits for it (``restart_wait_s``). Restarts are counted per role in the result.
The clock too: with ``restart_wait_s > 0`` and a ``state_dir`` it checkpoints every step
(bringup/engine/ros/clock_node.py), and when it crashes (killed by a signal we did not send, or an
unexpected exit code; not its own decisions 0, 2, 3, 130) it is started again, up to
``max_restarts`` times, with a new progress reader; the hosts wait for it (their idle timeout).
When the clock crashes once more than ``max_restarts`` allows, the launcher exports its journal
(``state_dir/clock.sqlite``: every step committed before the crash) into ``bag_dir`` itself, the
same export a clock does at its end, and the result's message says where that partial bag is.
Checkpoints of an earlier run in ``state_dir`` (``clock.sqlite``, ``<role>.state.sqlite``) are
removed when a launch starts, so a new run never resumes an old one.

Forked hosts: with ``fork`` (the command line's ``main``; `constellation run` passes it) the launcher
loads the hosts' code and runs the prepare hook in its own process, then forks every host from itself
(bringup/engine/ros/fork_start.py; tests/ros/test_fork_start.py): the same command, environment, log
and pid file, without each paying the imports and kernels again; the clock and wrapped hosts are not.

Multi-host: ``wrap(role, argv, env) -> (argv, env)`` rewrites each child's command and environment,
e.g. ``ip netns exec NS ...`` with per-host ``ROS_STATIC_PEERS`` (tests/multihost).

Oracle: tests/ros/test_launcher.py (a toy run completes and its bag equals the local engine's
envelopes; a killed host is named; a host that will not exit after a clean run is killed, named
in ``lingered`` with its stacks in its log, and the run stands; SIGINT leaves a readable bag; two
leases never share an id; a killed child is named with its signal; tests/ros/test_launcher_dies.py:
no child outlives a SIGKILLed launcher, Ctrl-C is 130;
progress carries the router's bundles in flight, equal step by step to the local engine's figure,
tests/ros/test_progress_in_flight.py); tests/faults/test_restart_clock.py (a clock killed more
often than allowed leaves a partial bag that equals the local engine's run up to its last step).
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import os
import pickle
import random
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import msgspec

from bringup.engine.keys import ENV_KEYS_DIGEST, KEYS_FILE_NAME, RunKeys
from bringup.engine.ros.fork_start import fork_node, preload
from bringup.engine.ros.lifeline import ENV_LAUNCHER_PID, ENV_RESTARTED
from bringup.engine.ros.run_spec import CLOCK_ROLE, RunSpec
from bringup.engine.ros.shm_cleanup import remove_unheld
from bringup.errors import UserError
from bringup.private_files import open_private, private_state_dir, read_private_bytes
from bringup.recording.journal import BagJournal
from bringup.stop_signals import signal_name, stop_on_signals

__all__ = [
    "FASTDDS_PROFILE",
    "DomainLease",
    "LaunchProgress",
    "LaunchResult",
    "child_env",
    "launch",
    "lease_domain_id",
]

REPO = Path(__file__).resolve().parents[3]
FASTDDS_PROFILE = Path(__file__).resolve().parent / "dds" / "fastdds_profile.xml"
LEASE_DIR_NAME = "agile_dtn_ros_domains"
ENV_LEASE_DIR = "AGILE_DTN_LEASE_DIR"


def lease_dir() -> Path:
    """The folder of the domain leases' lock files: ``$AGILE_DTN_LEASE_DIR``, else per user
    (``$XDG_RUNTIME_DIR/agile_dtn_ros_domains`` or ``/tmp/agile_dtn_ros_domains-<uid>``), mode 0700,
    owned by the user (another user could hold every id of a shared folder)."""
    return private_state_dir(LEASE_DIR_NAME, ENV_LEASE_DIR)


class DomainLease:
    """A ROS_DOMAIN_ID held by an exclusive fcntl lock until :meth:`release` (or process exit)."""

    def __init__(self, domain_id: int, fd: int):
        self.domain_id = domain_id
        self._fd: int | None = fd

    def release(self) -> None:
        if self._fd is not None:
            fcntl.flock(self._fd, fcntl.LOCK_UN)
            os.close(self._fd)
            self._fd = None

    def __enter__(self) -> DomainLease:
        return self

    def __exit__(self, *exc) -> None:
        self.release()


def lease_domain_id(lo: int = 1, hi: int = 101) -> DomainLease:
    """Lock a free domain id in ``[lo, hi]`` (random start, so parallel runs spread)."""
    folder = lease_dir()
    ids = list(range(lo, hi + 1))
    start = random.randrange(len(ids))
    for d in ids[start:] + ids[:start]:
        fd = open_private(folder / f"domain_{d}.lock", os.O_CREAT | os.O_RDWR, "domain lease", 0o600)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            continue
        return DomainLease(d, fd)
    raise UserError(f"no free ROS_DOMAIN_ID in {lo}..{hi} (all locked under {folder})")


def child_env(domain_id: int) -> dict[str, str]:
    """Environment of every process of a run: loopback discovery, the run's domain, the profile."""
    env = dict(os.environ)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env["ROS_DOMAIN_ID"] = str(domain_id)
    env["FASTRTPS_DEFAULT_PROFILES_FILE"] = str(FASTDDS_PROFILE)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(REPO), env.get("PYTHONPATH", "")) if p)
    env["PYTHONUNBUFFERED"] = "1"
    # every node process ends with this one (bringup/engine/ros/lifeline.py)
    env[ENV_LAUNCHER_PID] = str(os.getpid())
    return env


@dataclass(frozen=True)
class LaunchProgress:
    t_ns: int
    horizon_ns: int
    steps: int
    wall_s: float
    # bundle copies in flight in the DTN router after step t_ns (None: the run has no router)
    in_flight: int | None = None
    # before step 0: what the run is doing ("" once it steps) and the roles not ready yet
    status: str = ""
    not_ready: tuple[str, ...] = ()

    @property
    def real_time_factor(self) -> float:
        return self.t_ns / 1e9 / self.wall_s if self.wall_s > 0 else 0.0

    @property
    def steps_per_s(self) -> float:
        return self.steps / self.wall_s if self.wall_s > 0 else 0.0


@dataclass
class LaunchResult:
    returncode: int
    message: str
    domain_id: int
    out_dir: Path
    last: LaunchProgress | None
    failed_roles: list[str]
    restarts: dict[str, int] = None  # type: ignore[assignment]
    # hosts that did not exit after a run the clock completed and were killed (the run stands)
    lingered: list[str] = None  # type: ignore[assignment]

    def __post_init__(self) -> None:
        if self.restarts is None:
            self.restarts = {}
        if self.lingered is None:
            self.lingered = []

    @property
    def ok(self) -> bool:
        return self.returncode == 0


class _Child:
    def __init__(self, role: str, proc: subprocess.Popen, log: Path):
        self.role, self.proc, self.log = role, proc, log

    def last_error(self) -> str:
        try:
            lines = [ln for ln in self.log.read_text(errors="replace").splitlines() if ln.strip()]
        except OSError:
            return ""
        errs = [ln for ln in lines if "error" in ln.lower() or "Error" in ln]
        return (errs or lines or [""])[-1].strip()


def _terminate(children: list[_Child], timeout_s: float) -> list[str]:
    """SIGTERM every live child; one still running ``timeout_s`` later is killed (SIGKILL), after
    a SIGUSR1 that makes a node process (bringup/cli/node.py via ros_host / clock_node:
    faulthandler) write its Python stacks into its log. Returns the roles that had to be killed;
    each log says so."""
    for c in children:
        if c.proc.poll() is None:
            c.proc.send_signal(signal.SIGTERM)
    deadline = time.monotonic() + timeout_s
    killed: list[str] = []
    for c in children:
        try:
            c.proc.wait(timeout=max(0.0, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            with open(c.log, "a") as fh:
                fh.write(f"launcher: {c.role} still running {timeout_s:g} s after SIGTERM; its stacks, then SIGKILL\n")
            c.proc.send_signal(signal.SIGUSR1)
            try:
                c.proc.wait(timeout=1.0)
            except subprocess.TimeoutExpired:
                pass
            c.proc.kill()
            c.proc.wait()
            killed.append(c.role)
    return killed


def _signame(sig: int) -> str:
    try:
        return signal.Signals(sig).name
    except ValueError:
        return f"signal {sig}"


def _died(c: _Child) -> str:
    """One line for a process that ended on its own, naming the signal that killed it."""
    code = c.proc.returncode
    if code is not None and code < 0:
        return f"process '{c.role}' killed by {_signame(-code)}"
    return f"process '{c.role}' failed (exit code {code}): {c.last_error() or 'no message'}"


def _bag_after_stop(clock: _Child, spec: RunSpec) -> str:
    """What the stop left in the bag: the clock closes it when it stops by itself (exit 0, 3, 130)."""
    if not spec.bag_dir:
        return "no bag recorded"
    code = clock.proc.returncode
    if code in (0, 3, 130):
        return f"the clock stopped the run and closed the bag {spec.bag_dir}: it holds the run up to the stop"
    if code is not None and code < 0:
        return (f"the clock was killed by {_signame(-code)} and did not close the bag {spec.bag_dir}: "
                "it reads up to its last closed chunk (at most 2 min of sim time lost)")
    return (f"the clock exited with code {code}; the bag {spec.bag_dir} may not be closed "
            "(it reads up to its last closed chunk)")


# Wall seconds hosts get to exit after the clock ended the run (they normally take ~0.1 s).
_HOST_EXIT_GRACE_S = 10.0

# Clock exit codes that are its own decision (ok, user error, a host failed, interrupted): never restarted.
_CLOCK_DECIDED = (0, 2, 3, 130)


def _lifecycle_message(rec: dict, hosts: list[_Child], clock_error: str) -> tuple[str, list[str]]:
    """The run's one-line error for a node that failed a lifecycle transition (the clock's
    ``lifecycle_failed`` record): node, process, transition, and the cause its process logged."""
    proc = str(rec.get("process") or "")
    where = f" (process {proc})" if proc else ""
    msg = (f"node {rec.get('node')}{where} failed lifecycle transition '{rec.get('transition')}' "
           f"in state '{rec.get('state')}'; the run stopped")
    host = next((h for h in hosts if h.role == proc), None)
    cause = host.last_error() if host is not None else ""
    if cause:
        msg += f": {cause}"
    elif clock_error:
        msg += f" ({clock_error})"
    return msg, ([proc] if proc else []) + [CLOCK_ROLE]


def _partial_bag(spec: RunSpec) -> str:
    """The clock crashed for good: export what its journal committed (every step before the one it
    died in; bringup/recording/journal.py BagJournal, the same export a restarted clock ends with) into
    ``spec.bag_dir``. Returns the clause for the run's one-line error."""

    path = Path(spec.state_dir) / "clock.sqlite"  # type: ignore[arg-type]
    if not path.exists():
        return "no bag: the clock recorded nothing"
    try:
        j = BagJournal(path, epoch_ns=spec.epoch_ns())
        try:
            row = j.load()
            state = pickle.loads(row[1]) if row is not None else {}
            n = j.export(spec.bag_dir, custom={"engine": "ros", "roles": ",".join(spec.roles),  # type: ignore[arg-type]
                                               "partial": "clock crashed; exported from its journal by the launcher"})
        finally:
            j.close()
    except Exception as exc:  # noqa: BLE001 - the run has failed already; say why there is no bag
        return f"no bag: exporting the clock's journal {path} failed: {type(exc).__name__}: {exc}"
    # the checkpoint of step k holds every step before it (k's own messages were rolled back)
    upto = f"steps before t = {state['t_ns'] / 1e9:g} s, " if "t_ns" in state else ""
    return f"partial bag ({upto}{n} messages) in {spec.bag_dir}"


def _clear_checkpoints(state_dir: Path, roles: list[str]) -> None:
    names = ["clock.sqlite", *(f"{r}.state.sqlite" for r in roles)]
    for name in names:
        for suffix in ("", "-wal", "-shm"):
            (state_dir / (name + suffix)).unlink(missing_ok=True)


def _prepare(spec: RunSpec, spec_path: Path, out_dir: Path, env: dict[str, str], python: str,
             progress: Callable[[LaunchProgress], None] | None) -> str:
    """Run the spec's prepare hook once (``constellation node --prepare``, in the run's environment)
    before any process starts: e.g. the satellites' numba kernels compiled into the cache, which the
    processes then load instead of each compiling them (bringup/scenario/participants.py prepare).
    Returns "" or the run's one-line error."""
    if progress is not None:
        progress(LaunchProgress(0, 0, 0, 0.0, status=f"preparing the run ({spec.prepare})"))
    log = out_dir / "logs" / "prepare.log"
    t0 = time.monotonic()
    with open(log, "ab") as fh:
        proc = subprocess.run([python, "-m", "bringup.cli", "node", "--run-spec", str(spec_path), "--prepare"],
                              env=env, cwd=str(REPO), stdout=subprocess.DEVNULL, stderr=fh, stdin=subprocess.DEVNULL,
                              check=False)
    if proc.returncode != 0:
        return (f"preparing the run ({spec.prepare}) failed (exit code {proc.returncode}): "
                f"{_Child('prepare', proc, log).last_error() or 'no message'}")
    if progress is not None:  # what the first run of a checkout pays once (numba kernels compiled into the cache)
        progress(LaunchProgress(0, 0, 0, 0.0, status=f"prepared in {time.monotonic() - t0:.1f} s (logs/prepare.log)"))
    return ""


Wrap = Callable[[str, list[str], dict[str, str]], tuple[list[str], dict[str, str]]]


def _preload(spec: RunSpec, out_dir: Path, progress: Callable[[LaunchProgress], None] | None) -> str:
    """``launch(fork=main)``: load in this process what the forked hosts share
    (bringup/engine/ros/fork_start.py preload: the host code, the factory, the prepare hook for the
    whole run). Returns "" or the run's one-line error."""
    what = spec.prepare or spec.factory
    if progress is not None:
        progress(LaunchProgress(0, 0, 0, 0.0, status=f"preparing the run ({what})"))
    t0 = time.monotonic()
    try:
        preload(spec)
    except Exception as exc:  # noqa: BLE001 - the run's one-line error names the hook and the cause
        return f"preparing the run ({what}) failed: {type(exc).__name__}: {exc}"
    took = time.monotonic() - t0
    with open(out_dir / "logs" / "prepare.log", "a") as fh:
        fh.write(f"node prepare: ready ({what} took {took:.2f} s in the launcher's process; hosts forked from it)\n")
    if progress is not None:
        progress(LaunchProgress(0, 0, 0, 0.0, status=f"prepared in {took:.1f} s (logs/prepare.log)"))
    return ""


def launch(spec: RunSpec, out_dir: Path, *, progress: Callable[[LaunchProgress], None] | None = None,
           domain_id: int | None = None, python: str = sys.executable, wrap: Wrap | None = None,
           keys: RunKeys | None = None, fork: Callable[[list[str]], int] | None = None) -> LaunchResult:
    """Run the whole ROS-engine run described by ``spec``; returns when every child has exited.

    ``fork``: the command line's ``main`` (bringup/cli/main.py): the host processes are forked from
    this process, each running ``main(["node", ...])``, once it has loaded their code and the
    prepare hook's kernels (bringup/engine/ros/fork_start.py), instead of each started as a new
    interpreter; not with ``wrap``. The clock is always started as its own command.

    ``keys``: the run's keys when the spec names no ``keys_file`` (default: a new run key and the
    deployment's BPSec key, bringup/engine/keys.py); they are written to ``out_dir/run.keys`` (mode
    0600) for the run and removed when it ends."""
    spec.check()
    out_dir = Path(out_dir).absolute()  # (the children run in the repository's folder)
    (out_dir / "logs").mkdir(parents=True, exist_ok=True)
    spec_path = out_dir / "run_spec.json"
    if spec.state_dir:
        _clear_checkpoints(Path(spec.state_dir), [CLOCK_ROLE, *spec.roles])
    # FastDDS shared-memory files that no live process holds are leftovers of killed processes; a port
    # file a process was killed while creating stays empty, and the next participant to pick its port
    # number waits on it forever ("hosts not ready"): remove them, whole groups only (shm_cleanup.py)
    remove_unheld()
    lease = lease_domain_id() if domain_id is None else None
    dom = lease.domain_id if lease else int(domain_id)  # type: ignore[arg-type]
    own_keys = None
    if spec.keys_file is None:
        run_keys = keys or RunKeys.generate()
        own_keys = run_keys.write(out_dir / KEYS_FILE_NAME)
        digest = run_keys.digest()
    else:  # (a keys file of the caller's: the children check they read what the launcher saw)
        digest = hashlib.sha256(read_private_bytes(spec.keys_file, "run keys", 4097)).hexdigest()
    spec = msgspec.structs.replace(spec, domain_id=dom,
                                   keys_file=str(own_keys.resolve()) if own_keys else spec.keys_file)
    spec.to_file(spec_path)
    env = child_env(dom)
    env[ENV_KEYS_DIGEST] = digest
    last: list[LaunchProgress | None] = [None]
    lifecycle_failed: list[dict] = []  # the clock's record of a node that failed a transition
    children: list[_Child] = []

    restarts: dict[str, int] = {}
    lingered: list[str] = []
    forking = fork is not None and wrap is None

    def start(role: str, restarted: int = 0, **kw) -> _Child:
        log = out_dir / "logs" / f"{role}.log"
        fh = open(log, "ab")
        argv = [python, "-m", "bringup.cli", "node", "--run-spec", str(spec_path), "--role", role]
        cenv = dict(env)
        if restarted:  # (a restarted clock does not take its own dead predecessor for another run)
            cenv[ENV_RESTARTED] = str(restarted)
        if wrap is not None:
            argv, cenv = wrap(role, argv, cenv)
        if forking and role != CLOCK_ROLE:
            fh.close()
            proc = fork_node(argv[3:], cenv, log, str(REPO), fork)  # type: ignore[arg-type]
        else:
            proc = subprocess.Popen(argv, env=cenv, cwd=str(REPO), stderr=fh, stdin=subprocess.DEVNULL, **kw)
            fh.close()
        (tmp := out_dir / "logs" / f".{role}.pid.tmp").write_text(f"{proc.pid}\n")  # (renamed whole: never empty)
        os.replace(tmp, out_dir / "logs" / f"{role}.pid")
        return _Child(role, proc, log)

    def read_progress(stream) -> None:
        for line in stream:
            try:
                rec = json.loads(line)
            except ValueError:
                continue
            lf = rec.get("lifecycle_failed")
            if isinstance(lf, dict):
                lifecycle_failed.append(lf)
                continue
            w = rec.get("waiting")
            if isinstance(w, dict) and progress is not None:
                nr = tuple(str(r) for r in w.get("not_ready", ()))
                names = ", ".join(nr[:6]) + (f" and {len(nr) - 6} more" if len(nr) > 6 else "")
                progress(LaunchProgress(0, int(w.get("horizon_ns", 0)), 0, float(w.get("wall_s", 0.0)),
                                        status=f"waiting for {len(nr)} of {w.get('roles')} processes to be "
                                               f"ready ({float(w.get('wall_s', 0.0)):.0f} s): {names}",
                                        not_ready=nr))
                continue
            body = rec.get("progress") or rec.get("done")
            if not isinstance(body, dict):
                continue
            fl = body.get("in_flight")
            p = LaunchProgress(int(body["t_ns"]), int(body["horizon_ns"]), int(body["steps"]), float(body["wall_s"]),
                               None if fl is None else int(fl))
            last[0] = p
            if progress is not None:
                progress(p)

    stops = stop_on_signals()
    stops.__enter__()
    try:
        if forking:
            failed_prep = _preload(spec, out_dir, progress)
            if failed_prep:
                return LaunchResult(1, failed_prep, dom, out_dir, None, ["prepare"])
        elif spec.prepare is not None:
            failed_prep = _prepare(spec, spec_path, out_dir, env, python, progress)
            if failed_prep:
                return LaunchResult(1, failed_prep, dom, out_dir, None, ["prepare"])
        clock = start(CLOCK_ROLE, stdout=subprocess.PIPE, text=True)
        reader = threading.Thread(target=read_progress, args=(clock.proc.stdout,), daemon=True)
        reader.start()
        clock_restartable = spec.max_restarts > 0 and spec.restart_wait_s > 0 and bool(spec.state_dir)
        hosts = [start(r, stdout=subprocess.DEVNULL) for r in spec.roles]
        children = [clock, *hosts]
        failed: list[str] = []
        message = ""
        rc = 0
        try:
            while True:
                crc = clock.proc.poll()
                dead = [h for h in hosts if h.proc.poll() not in (None, 0)]
                if dead and crc is None and spec.max_restarts > 0:
                    for h in [h for h in dead if restarts.get(h.role, 0) < spec.max_restarts]:
                        restarts[h.role] = restarts.get(h.role, 0) + 1
                        with open(h.log, "a") as fh:
                            fh.write(f"launcher: {h.role} exited with code {h.proc.returncode}; "
                                     f"restart {restarts[h.role]} of {spec.max_restarts}\n")
                        remove_unheld()  # what the dead process left unheld (an empty port if it died starting)
                        new = start(h.role, restarts[h.role], stdout=subprocess.DEVNULL)
                        hosts[hosts.index(h)] = new
                        children[children.index(h)] = new
                    dead = [h for h in hosts if h.proc.poll() not in (None, 0)]
                if dead and crc is None:
                    failed = [h.role for h in dead]
                    message = "; ".join(_died(h) for h in dead)
                    rc = 1
                    _terminate([clock], 10.0)
                    _terminate(hosts, 5.0)
                    message += "; " + _bag_after_stop(clock, spec)
                    break
                if (crc is not None and crc not in _CLOCK_DECIDED and clock_restartable
                        and restarts.get(CLOCK_ROLE, 0) < spec.max_restarts):
                    restarts[CLOCK_ROLE] = restarts.get(CLOCK_ROLE, 0) + 1
                    with open(clock.log, "a") as fh:
                        fh.write(f"launcher: {CLOCK_ROLE} exited with code {crc}; "
                                 f"restart {restarts[CLOCK_ROLE]} of {spec.max_restarts}\n")
                    reader.join(timeout=2.0)
                    remove_unheld()
                    new = start(CLOCK_ROLE, restarts[CLOCK_ROLE], stdout=subprocess.PIPE, text=True)
                    children[children.index(clock)] = new
                    clock = new
                    reader = threading.Thread(target=read_progress, args=(clock.proc.stdout,), daemon=True)
                    reader.start()
                    continue
                if crc is not None:
                    crashed = crc not in _CLOCK_DECIDED and clock_restartable
                    if crc != 0:
                        rc = crc
                        failed = [CLOCK_ROLE] + [h.role for h in hosts if h.proc.poll() not in (None, 0)]
                        message = clock.last_error() or f"clock exited with code {crc}"
                        if crc < 0:  # killed: the recorder with it
                            message = (f"clock killed by {_signame(-crc)}" + (
                                "" if crashed or not spec.bag_dir else
                                f": the recorder died with it and did not close the bag {spec.bag_dir}; "
                                "it reads up to its last closed chunk (at most 2 min of sim time lost)"))
                        if lifecycle_failed:  # the node's process named, its cause from its log
                            message, failed = _lifecycle_message(lifecycle_failed[0], hosts, message)
                        if crashed:
                            how = f"killed by {_signame(-crc)}" if crc < 0 else f"exited with code {crc}"
                            message = (f"clock {how} and was restarted {restarts.get(CLOCK_ROLE, 0)} of "
                                       f"{spec.max_restarts} times")
                    # hosts leave on the clock's stop message; give them a moment, then insist
                    deadline = time.monotonic() + _HOST_EXIT_GRACE_S
                    while time.monotonic() < deadline and any(h.proc.poll() is None for h in hosts):
                        time.sleep(0.05)
                    stuck = _terminate(hosts, 5.0)
                    # After a clean end (clock exit 0) every host has acked the final step, so its
                    # envelopes are in the bag and its per-step state is committed: a host killed
                    # here only failed to leave (seen: stuck in rclpy destroy_node, SIGTERM
                    # unhandled). Its log says so and the result carries it, but the run stands.
                    bad = [h for h in hosts if h.role not in stuck
                           and h.proc.returncode not in (0, -signal.SIGTERM, 130)]
                    if crc == 0:
                        lingered = [f"process '{h.role}' did not exit within {_HOST_EXIT_GRACE_S:g} s of the "
                                    f"end of the run (nor 5 s after SIGTERM) and was killed; see its log {h.log}"
                                    for h in hosts if h.role in stuck]
                    if crc == 0 and bad:
                        rc = 1
                        failed = [h.role for h in bad]
                        message = "; ".join(_died(h) for h in bad)
                    if crashed and spec.bag_dir:
                        message += "; " + _partial_bag(spec)
                    break
                time.sleep(0.05)
        except KeyboardInterrupt as exc:
            signum = getattr(exc, "signum", signal.SIGINT)
            _terminate([clock], 15.0)
            _terminate(hosts, 5.0)
            rc, message, failed = (128 + signum, f"interrupted by {signal_name(signum)}: every process stopped; "
                                   + _bag_after_stop(clock, spec), [])
        reader.join(timeout=2.0)
        return LaunchResult(rc, message, dom, out_dir, last[0], failed, restarts, lingered)
    finally:
        _terminate(children, 5.0)
        stops.__exit__(None, None, None)
        if lease is not None:
            lease.release()
        if own_keys is not None:
            own_keys.unlink(missing_ok=True)
