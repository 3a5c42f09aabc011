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
collection) has its exception handed to ``sys.unraisablehook`` ("Exception ignored in ...") and dropped:
the run would go on to its end and exit 0. Inside the block a hook notes each :class:`Interrupted`
dropped that way (and passes it on to the hook before it); :func:`raise_pending` (called by a loop at
each step; the local engine's calls it) raises it again, and so does the ``with`` block's end, so a
dropped stop is never lost. A stop that reached the code (caught and handled there, as the ROS
launcher does) is not noted.

How we know it is right: tests/faults/test_run_signals.py sends each signal to a local run, a ROS
run's launcher and its processes, and checks run_status.json, the keys, the partial report and the
reuse of the folder.
"""

from __future__ import annotations

import signal
import sys
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


#: signals whose Interrupted was dropped (by a finalizer) inside :func:`stop_on_signals`
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
        raise Interrupted(signum)

    before_hook = sys.unraisablehook

    def dropped(unraisable) -> None:
        if isinstance(unraisable.exc_value, Interrupted):
            _pending.append(unraisable.exc_value.signum)
        before_hook(unraisable)

    old = {}
    _pending.clear()
    sys.unraisablehook = dropped
    try:
        for s in signals:
            old[s] = signal.signal(s, handler)
        try:
            yield
        except KeyboardInterrupt:
            _pending.clear()  # (a stop is on its way out: the dropped one would say the same)
            raise
        raise_pending()  # the block ended normally although a stop's exception was dropped
    finally:
        _pending.clear()
        sys.unraisablehook = before_hook
        for s, h in old.items():
            signal.signal(s, h)
