"""orbit_clock/fork_split.py: parts computed in forked processes come back in order, equal to the
calls made in one process; a child's exception and a child's death are named."""

from __future__ import annotations

import os

import numpy as np
import pytest

from orbit_clock.fork_split import SplitError, available_workers, run_parts


class _NoPickle:
    """Held by the function, not sent: a child must inherit it (as the SGP4 records are)."""

    def __reduce__(self):
        raise TypeError("does not pickle")

    def __init__(self, scale: float):
        self.scale = scale


def test_parts_in_order_equal_one_process():
    held = _NoPickle(1.0 / 3.0)

    def fn(part):
        a = np.arange(part[0], part[1], dtype=float)
        return np.sin(a * held.scale), os.getpid()

    parts = [(0, 1000), (1000, 2500), (2500, 2600)]
    got = run_parts(fn, parts, workers=3)
    want = [fn(p) for p in parts]
    assert all(np.array_equal(g[0], w[0]) for g, w in zip(got, want, strict=True))
    pids = [g[1] for g in got]
    assert pids[0] == os.getpid() and len(set(pids)) == 3  # the first here, each other in a child


def test_one_worker_runs_every_part_here():
    got = run_parts(lambda p: (p, os.getpid()), [1, 2, 3], workers=1)
    assert got == [(1, os.getpid()), (2, os.getpid()), (3, os.getpid())]


def test_a_childs_exception_is_named():
    def fn(part):
        if part == 1:
            raise ValueError("bad part one")
        return part

    with pytest.raises(SplitError, match=r"part 1 of 2 failed in its process: ValueError: bad part one"):
        run_parts(fn, [0, 1], workers=2)


def test_a_child_that_dies_is_named():
    def fn(part):
        if part == 1:
            os._exit(3)
        return part

    with pytest.raises(SplitError, match=r"part 1 of 2: its process ended without a result \(exit code 3\)"):
        run_parts(fn, [0, 1], workers=2)


def test_an_exception_here_ends_the_children():
    def fn(part):
        if part == 0:
            raise KeyError("here")
        import time

        time.sleep(30)
        return part

    import multiprocessing as mp

    with pytest.raises(KeyError):
        run_parts(fn, [0, 1], workers=2)
    assert not [p for p in mp.active_children() if p.name.startswith("split-")]


def test_available_workers_is_the_affinity():
    assert available_workers() == len(os.sched_getaffinity(0))
