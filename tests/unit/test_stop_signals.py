"""A stop signal whose exception a finalizer dropped is not lost (bringup/stop_signals.py).

Oracle: Python's own behaviour - an exception raised in ``__del__`` is printed as "Exception ignored"
and dropped. A finalizer that sends SIGTERM to this process makes the handler's exception land there;
without the recorded signal the block would end normally (the CI failure this test keeps away: a local
run stopped by SIGTERM during garbage collection ran on to its end and exited 0).
"""

from __future__ import annotations

import gc
import os
import signal
import sys

import pytest

from bringup.stop_signals import Interrupted, raise_pending, stop_on_signals


class _KillsOnDel:
    def __del__(self):
        os.kill(os.getpid(), signal.SIGTERM)
        for _ in range(1000):  # the handler runs between bytecodes, here inside the finalizer
            pass


def _drop_signal_in_finalizer() -> None:
    obj = _KillsOnDel()
    del obj
    gc.collect()


def test_dropped_signal_is_raised_by_raise_pending(monkeypatch):
    dropped = []
    monkeypatch.setattr(sys, "unraisablehook", dropped.append)
    with pytest.raises(Interrupted) as exc, stop_on_signals():
        _drop_signal_in_finalizer()
        # (the exception really was dropped: Python handed it to the unraisable hook)
        assert [type(u.exc_value) for u in dropped] == [Interrupted]
        raise_pending()
        pytest.fail("raise_pending did not raise the dropped SIGTERM")
    assert exc.value.signum == signal.SIGTERM


def test_dropped_signal_is_raised_at_the_end_of_the_block():
    with pytest.raises(Interrupted) as exc, stop_on_signals():
        _drop_signal_in_finalizer()
    assert exc.value.signum == signal.SIGTERM


def test_delivered_signal_leaves_nothing_pending():
    with pytest.raises(Interrupted), stop_on_signals():
        os.kill(os.getpid(), signal.SIGHUP)
        for _ in range(10**6):
            pass
    with stop_on_signals():
        raise_pending()  # (nothing: the earlier stop reached its block)


def test_caught_signal_is_not_raised_again():
    """A stop the code catches and handles (the ROS launcher returns 130) is not raised at the end."""
    with stop_on_signals():
        try:
            os.kill(os.getpid(), signal.SIGTERM)
            for _ in range(10**6):
                pass
        except Interrupted as exc:
            assert exc.signum == signal.SIGTERM
        raise_pending()


def test_the_earlier_handlers_come_back():
    before = signal.getsignal(signal.SIGTERM)
    with pytest.raises(Interrupted), stop_on_signals():
        _drop_signal_in_finalizer()
    assert signal.getsignal(signal.SIGTERM) is before
    raise_pending()  # (nothing pending outside the block)


def test_stop_inside_compiled_code_stops_the_run_rather_than_failing_it():
    """A signal handled while numba's dispatcher runs leaves "SystemError: ... returned a result
    with an exception set" with the interrupt as its cause (seen in a local run stopped by SIGTERM):
    the engine's error for a participant raises the interrupt itself."""
    from bringup.engine.contract import EngineError, failed

    stop = Interrupted(signal.SIGTERM)
    try:
        try:
            raise stop
        except Interrupted as inner:
            raise SystemError("CPUDispatcher(<function dp_states>) returned a result with an exception set") \
                from inner
    except SystemError as exc:
        with pytest.raises(Interrupted) as got:
            failed("sat_33", "step at 3600000000000", exc)
    assert got.value is stop
    plain = failed("sat_33", "step", ValueError("bad"))
    assert isinstance(plain, EngineError) and "sat_33 failed in step: ValueError: bad" in str(plain)
