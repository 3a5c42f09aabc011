"""Ending a process at once, with what it printed flushed.

``os._exit`` skips the interpreter's shutdown (object finalizers, module teardown, DDS participants'
goodbye): the command line uses it after a finished command (bringup/cli/main.py), a ROS host after
its run (bringup/engine/ros/host.py: a DDS listener can spin forever in the teardown) and a forked
host always (bringup/engine/ros/fork_start.py: the launcher's state is not the child's to tear
down). What it would lose is Python's buffered stdout and stderr; :func:`exit_now` flushes them first.

How we know it is right: tests/ros/test_fork_start.py reads a forked host's last stderr line and its
exit code; tests/unit/test_cli_exit.py does the same for the command line.
"""

from __future__ import annotations

import os
import sys
from typing import NoReturn

__all__ = ["exit_now"]


def exit_now(code: int) -> NoReturn:
    """Flush stdout and stderr (a closed or broken stream is skipped), then ``os._exit(code)``."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError, AttributeError):
            pass
    os._exit(code)
