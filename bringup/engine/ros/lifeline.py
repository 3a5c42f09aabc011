"""Children of a launcher die with it: the lifeline every node process of a local ROS run holds.

The launcher (bringup/engine/ros/launcher.py) starts each process with its own pid in
``AGILE_DTN_LAUNCHER_PID``. At start the process (bringup/cli/node.py) calls :func:`hold`:

* ``prctl(PR_SET_PDEATHSIG, SIGTERM)``: the kernel sends it SIGTERM when the thread that started it
  ends - also when the launcher is killed with SIGKILL and can clean nothing up;
* a watchdog thread on a pidfd of the launcher (``pidfd_open``, Linux >= 5.3; immune to pid
  reuse), for the cases PDEATHSIG misses: a wrapper between the two (``ip netns exec`` execs, so
  there is none there; ``sudo`` would be one), or a process that was started by a thread that is
  still alive while the launcher is gone. When the launcher ends, it sends the process SIGTERM;
* SIGTERM is the ordinary stop: the clock tells the hosts to stop and closes the bag (readable),
  hosts leave (exit 130). A process still alive ``grace_s`` after its launcher ended leaves with
  ``os._exit`` (the watchdog thread runs while the main thread is in rclpy's C code, which releases
  the GIL while it waits).

If the launcher is already gone when :func:`hold` runs (it died while this process started), the
process stops at once. Without ``AGILE_DTN_LAUNCHER_PID`` (a container, whose lifetime its engine
owns; ``constellation node`` run by hand) there is nothing to hold.

Oracle: tests/ros/test_launcher_dies.py (SIGKILL the launcher of a scenario run: no process of the
run is alive a few seconds later; the clock's log says why it stopped).
"""

from __future__ import annotations

import ctypes
import os
import select
import signal
import sys
import threading

__all__ = ["ENV_LAUNCHER_PID", "ENV_RESTARTED", "hold"]

ENV_LAUNCHER_PID = "AGILE_DTN_LAUNCHER_PID"
# set (to the restart count) in the environment of a process the launcher started again after a crash
ENV_RESTARTED = "AGILE_DTN_RESTARTED"
_PR_SET_PDEATHSIG = 1


def _pdeathsig(sig: int) -> bool:
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(_PR_SET_PDEATHSIG, int(sig), 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


def _stop(why: str, grace_s: float) -> None:
    print(f"{why}: stopping this process (SIGTERM; it leaves by itself within {grace_s:g} s at most)",
          file=sys.stderr, flush=True)
    os.kill(os.getpid(), signal.SIGTERM)


def hold(role: str, env: dict[str, str] | None = None, *, grace_s: float = 30.0) -> bool:
    """Tie this process to its launcher (module docstring); False when there is none to hold."""
    env = os.environ if env is None else env
    raw = env.get(ENV_LAUNCHER_PID)
    if not raw:
        return False
    pid = int(raw)
    _pdeathsig(signal.SIGTERM)
    try:
        fd = os.pidfd_open(pid)
    except ProcessLookupError:
        _stop(f"{role}: its launcher (pid {pid}) is gone", grace_s)
        return True
    except (OSError, AttributeError):  # no pidfd (old kernel): PDEATHSIG alone
        return True

    def watch() -> None:
        select.select([fd], [], [])  # readable once the launcher has ended
        _stop(f"{role}: its launcher (pid {pid}) ended", grace_s)
        threading.Event().wait(grace_s)
        print(f"{role}: still running {grace_s:g} s after its launcher ended; leaving now", file=sys.stderr,
              flush=True)
        os._exit(1)

    threading.Thread(target=watch, name="lifeline", daemon=True).start()
    return True
