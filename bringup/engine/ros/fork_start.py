"""Host processes of a ROS run forked from the launcher, their code and numba kernels loaded once.

Started as ``python -m bringup.cli node --role R`` (bringup/engine/ros/launcher.py), every host
process of a run pays on its own what every other one pays too: the interpreter's start, the
imports (rclpy, numpy, numba, the project's packages) and the satellites' numba kernels loaded from
the cache (sat_node/kernels.py). With one process per satellite that is 24 times the same work,
done at once on the machine's cores before step 0 can start. With ``launch(..., fork=True)`` the
launcher does that work once in its own process (:func:`preload`: the host module and the run's
participant factory imported, the spec's prepare hook run in-process instead of in a
``--prepare`` process) and starts each host with ``os.fork()`` (:func:`fork_node`): the child
starts with everything loaded (pages shared copy-on-write; :func:`gc.freeze` keeps the collector
from touching, and so copying, the inherited objects) and runs the very command a started process
runs, ``constellation node --run-spec SPEC --role R`` (bringup/cli/main.py ``main``, which the
command that launches hands in: the engine does not import the command line), in its own
environment (the run's ``ROS_DOMAIN_ID``, the DDS profile, the lifeline's launcher pid), with
stdin and stdout on /dev/null, stderr appended to ``logs/<role>.log`` and the working folder the
repository's, as a started process has. Nothing of DDS exists before the fork: the launcher never
initialises rclpy, each child makes its own participant.

:class:`ForkedProcess` is the launcher's handle of such a child with the part of
:class:`subprocess.Popen` the launcher uses (``pid``, ``returncode``, ``poll``, ``wait`` with
:class:`subprocess.TimeoutExpired`, ``send_signal``, ``kill``): the child is the launcher's own,
so ``waitpid`` gives its exit status, a signal as ``-signum`` as Popen gives it. The lifeline
(bringup/engine/ros/lifeline.py: PDEATHSIG and the launcher's pidfd) holds the same way.

Limits: Linux (``os.fork``); the launcher's own thread must not hold a lock the child needs: the
child gets new ``sys.stdin/stdout/stderr`` objects on its own descriptors, and the launcher's
stop-signal handlers are reset to the default before anything else runs. Commands that ``wrap``
their children (``ip netns exec``, multi-host) are started as before.

How we know it is right: tests/ros/test_fork_start.py (a forked toy host's exit code, a signal's
``-signum``, ``wait`` timing out, stderr in the role's log and the environment the node sees) and
tests/system/test_engines_equal.py (`constellation run --engine ros` forks its hosts; its report
equals the local engine's).
"""

from __future__ import annotations

import gc
import io
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

from bringup.stop_signals import STOP_SIGNALS
from bringup.process_end import exit_now

__all__ = ["ForkedProcess", "fork_node", "preload"]


class ForkedProcess:
    """The launcher's handle of a forked node process: what the launcher uses of ``Popen``."""

    stdout = None

    def __init__(self, pid: int, args: list[str]):
        self.pid = pid
        self.args = args
        self.returncode: int | None = None

    def poll(self) -> int | None:
        if self.returncode is None:
            try:
                pid, status = os.waitpid(self.pid, os.WNOHANG)
            except ChildProcessError:  # (reaped elsewhere: nothing left to learn)
                self.returncode = 0
                return self.returncode
            if pid == self.pid:
                self.returncode = os.waitstatus_to_exitcode(status)
        return self.returncode

    def wait(self, timeout: float | None = None) -> int:
        deadline = None if timeout is None else time.monotonic() + timeout
        pause = 0.001
        while self.poll() is None:
            if deadline is not None and time.monotonic() >= deadline:
                raise subprocess.TimeoutExpired(self.args, timeout)
            time.sleep(pause)
            pause = min(0.05, pause * 2)
        return self.returncode  # type: ignore[return-value]

    def send_signal(self, sig: int) -> None:
        if self.poll() is None:
            try:
                os.kill(self.pid, sig)
            except ProcessLookupError:
                pass

    def terminate(self) -> None:
        self.send_signal(signal.SIGTERM)

    def kill(self) -> None:
        self.send_signal(signal.SIGKILL)


def preload(spec, role_hint: str | None = None) -> None:
    """Load in this (the launcher's) process what every forked host would load itself: the host
    module (rclpy), the run's participant factory and its prepare hook for the whole run
    (``spec.prepare(spec, None)``: the numba kernels compiled or loaded). Then the collector's
    generations are frozen, so the children do not copy the inherited pages by collecting them."""
    import bringup.engine.ros.host  # noqa: F401 - loaded once for every child
    from bringup.engine.ros.run_spec import load_factory

    _type_supports()

    load_factory(spec.factory)
    if spec.prepare is not None:
        load_factory(spec.prepare)(spec, role_hint)
    gc.collect()
    gc.freeze()


def _type_supports() -> None:
    """The C type supports of the messages and services every host's nodes use (each loaded by
    rclpy at its first publisher, subscription or service: a library load and the rosidl parser's
    import per process otherwise)."""
    from diagnostic_msgs.msg import DiagnosticArray
    from lifecycle_msgs.msg import TransitionEvent
    from lifecycle_msgs.srv import ChangeState, GetAvailableStates, GetAvailableTransitions, GetState
    from rcl_interfaces.msg import ParameterEvent
    from rcl_interfaces.srv import (
        DescribeParameters,
        GetParameters,
        GetParameterTypes,
        ListParameters,
        SetParameters,
        SetParametersAtomically,
    )
    from rclpy.type_support import check_for_type_support
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import NavSatFix
    from std_msgs.msg import String

    for t in (String, Clock, DiagnosticArray, NavSatFix, TransitionEvent, ParameterEvent, ChangeState, GetState,
              GetAvailableStates, GetAvailableTransitions, DescribeParameters, GetParameters, GetParameterTypes,
              ListParameters, SetParameters, SetParametersAtomically):
        check_for_type_support(t)


def fork_node(argv: list[str], env: dict[str, str], log: Path, cwd: str,
              main: Callable[[list[str]], int]) -> ForkedProcess:
    """Fork a node process running ``main(argv)`` (the command line's: bringup/cli/main.py ``main``,
    handed in by the command that launches) in environment ``env``, stderr appended to ``log``,
    working folder ``cwd``; the child's exit code is what ``main`` returns."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    pid = os.fork()
    if pid:
        return ForkedProcess(pid, list(argv))
    code = 1
    try:  # the child: never returns into the launcher's code
        for sig in STOP_SIGNALS:
            signal.signal(sig, signal.SIG_DFL)
        fd = os.open(log, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
        os.dup2(fd, 2)
        os.close(fd)
        nul = os.open(os.devnull, os.O_RDWR)
        os.dup2(nul, 0)
        os.dup2(nul, 1)
        os.close(nul)
        # new stream objects: the launcher's may have been locked by one of its threads at the fork
        sys.stdin = io.TextIOWrapper(io.FileIO(0, "r", closefd=False))
        sys.stdout = io.TextIOWrapper(io.FileIO(1, "w", closefd=False), line_buffering=True)
        sys.stderr = io.TextIOWrapper(io.FileIO(2, "w", closefd=False), errors="backslashreplace",
                                      line_buffering=True, write_through=True)
        os.chdir(cwd)
        os.environ.clear()
        os.environ.update(env)
        sys.argv = ["constellation", *argv]
        code = main(list(argv))
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else 1
    except BaseException:  # noqa: BLE001 - the child's last word goes to its log
        import traceback

        traceback.print_exc()
        code = 1
    finally:
        exit_now(code)
