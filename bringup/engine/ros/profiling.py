"""Optional CPU profile of one node process of the ROS engine (a developer's tool, off by default).

With ``AGILE_DTN_PROFILE_DIR=DIR`` in the launcher's environment (every child inherits it) each
node process (clock and hosts) runs under :mod:`cProfile` from the start of ``constellation node``
to its end and writes ``DIR/<role>.prof`` just before it exits (:func:`bringup.engine.ros.host.exit_now`
skips the interpreter's normal exit, so the profile is written there). Read them with
``python -m pstats DIR/sat_00.prof`` (or snakeviz). Without the variable nothing is started and
:func:`dump` does nothing. Only the main thread is profiled (where the executor runs the callbacks
and the step); its times are that thread's CPU seconds, not wall. Checked by tests/unit/test_profiling_env.py (a profile is written where and when the
variable says, none without it).
"""

from __future__ import annotations

import cProfile
import os
import time
from pathlib import Path

__all__ = ["ENV_PROFILE_DIR", "dump", "start"]

ENV_PROFILE_DIR = "AGILE_DTN_PROFILE_DIR"

_active: tuple[cProfile.Profile, Path] | None = None


def start(role: str) -> bool:
    """Start profiling this process as ``role`` when the variable is set; True if it started."""
    global _active
    folder = os.environ.get(ENV_PROFILE_DIR)
    if not folder or _active is not None:
        return False
    prof = cProfile.Profile(time.thread_time)  # CPU time of this thread: a loaded machine's waits do not count
    _active = (prof, Path(folder) / f"{role}.prof")
    prof.enable()
    return True


def dump() -> Path | None:
    """Stop the profile started by :func:`start` and write it; its path (None: none was started)."""
    global _active
    if _active is None:
        return None
    prof, path = _active
    _active = None
    prof.disable()
    path.parent.mkdir(parents=True, exist_ok=True)
    prof.dump_stats(str(path))
    return path
