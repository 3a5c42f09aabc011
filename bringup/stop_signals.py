"""Every way a user, a terminal or a supervisor stops a run, turned into one exception.

A run ends by SIGINT (Ctrl-C), SIGTERM (``timeout``, systemd, ``docker stop``, ``kill``), SIGHUP (the
terminal closed, an ssh session dropped) or SIGQUIT (Ctrl-\\). Python's defaults differ: SIGINT
raises KeyboardInterrupt, the three others end the process at once, leaving the run folder saying
"running" forever, the run's keys on disk and the bag without its report. :func:`stop_on_signals`
makes all four raise :class:`Interrupted` (a KeyboardInterrupt, so every ``except KeyboardInterrupt``
cleans up as it does for Ctrl-C) carrying the signal, in the main thread, for the ``with`` block; the
run folder then records ``interrupted`` with the signal's name (bringup/cli/run_folder.py) and the CLI
exits with 128 + the signal's number (130 for SIGINT, 143 for SIGTERM, 129 for SIGHUP, 131 for
SIGQUIT), as a shell reports a process the signal ended.

A signal that arrives while Python runs a finalizer (a ``__del__`` or a weakref callback during garbage
collection) has its exception printed as "Exception ignored in ..." and dropped: the run would go on to
its end and exit 0. The handler therefore also records the signal, and :func:`raise_pending` (called by
a loop at each step; the local engine's calls it) raises it again if it was dropped; the ``with``
block's end raises it too, so a dropped stop is never lost.

How we know it is right: tests/faults/test_run_signals.py sends each signal to a local run, a ROS
run's launcher and its processes, and checks run_status.json, the keys, the partial report and the
reuse of the folder.
"""

from __future__ import annotations

import signal
import threading
from contextlib import contextmanager

__all__ = ["STOP_SIGNALS", "Interrupted", "exit_code", "raise_pending", "signal_name", "stop_on_signals"]

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP, signal.SIGQUIT)


def signal_name(signum: int) -> str:
    try:
        return signal.Signals(signum).name
    except ValueError:
        return f"signal {signum}"


class Interrupted(KeyboardInterrupt):
    """The run was stopped by ``signum`` (a KeyboardInterrupt: cleaned up as Ctrl-C is)."""

    def __init__(self, signum: int = signal.SIGINT):
        super().__init__(f"interrupted by {signal_name(signum)}")
        self.signum = int(signum)


def exit_code(exc: BaseException) -> int:
    """128 + the signal's number (130 for a plain KeyboardInterrupt)."""
    return 128 + int(getattr(exc, "signum", signal.SIGINT))


#: signals received inside :func:`stop_on_signals` and not yet seen unwinding the block
_pending: list[int] = []


def raise_pending() -> None:
    """Raise :class:`Interrupted` for a stop signal that arrived and whose exception was dropped
    (raised inside a finalizer); nothing when none did. Call it where a loop would go on."""
    if _pending:
        raise Interrupted(_pending[0])


@contextmanager
def stop_on_signals(signals=STOP_SIGNALS):
    """Inside the block, each of ``signals`` raises :class:`Interrupted` in the main thread (the
    earlier handlers come back after it); outside the main thread, nothing changes. A second
    signal while the first is being handled raises again (a user pressing Ctrl-C twice)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum, _frame):
        _pending.append(int(signum))
        raise Interrupted(signum)

    old = {}
    _pending.clear()
    try:
        for s in signals:
            old[s] = signal.signal(s, handler)
        try:
            yield
        except KeyboardInterrupt:
            _pending.clear()  # (the stop reached the block: nothing was dropped)
            raise
        raise_pending()  # the block ended normally although a signal came: its exception was dropped
    finally:
        _pending.clear()
        for s, h in old.items():
            signal.signal(s, h)
