"""Independent pieces of a computation run side by side in forked processes.

The orbit searches of a run's world (the ISL contact plan's edge bisection and mean ranges,
orbit_clock/isl.py) evaluate SGP4 at millions of scattered (satellite, time) points, each on its
own: the points can be cut into parts that run on separate cores and whose results, put back in
order, are the numbers one process computes. :func:`run_parts` calls ``fn(part)`` for every part:
the first in this process, each other one in a child forked for it, so that ``fn`` may use what
does not pickle (the SGP4 records) - the child inherits this process's memory, copy on write. A
child sends its result back pickled through a pipe and leaves with ``os._exit`` (no finalizer of
this process's objects runs in it).

Failure: an exception in a child is raised here as :class:`SplitError` naming it; a child that
dies (killed, out of memory) is a :class:`SplitError` naming its exit; an exception in this
process ends the children first.

Where ``fork`` is not available, or ``workers`` is 1, every part runs here, in order.

How we know it is right: tests/unit/test_fork_split.py - results in order and equal to the
calls made in one process, a child's exception and a child's death named; the searches that
use it compare their split results with one process bit for bit (tests/unit/test_isl_split.py).
"""

from __future__ import annotations

import multiprocessing as mp
import os
import pickle
from collections.abc import Callable, Sequence

__all__ = ["SplitError", "available_workers", "run_parts"]


class SplitError(RuntimeError):
    """A part computed in a child process failed; the message names the part and why."""


def available_workers() -> int:
    """The cores this process may run on (its CPU affinity), at least 1."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # (no affinity on this platform)
        return max(1, os.cpu_count() or 1)


def _child(fn, part, conn) -> None:
    try:
        msg = ("ok", fn(part))
    except BaseException as exc:  # noqa: BLE001 - sent to the parent, which raises it
        msg = ("error", f"{type(exc).__name__}: {exc}")
    try:
        conn.send_bytes(pickle.dumps(msg, protocol=pickle.HIGHEST_PROTOCOL))
        conn.close()
    finally:
        os._exit(0)


def run_parts(fn: Callable, parts: Sequence, *, workers: int = 2) -> list:
    """``[fn(p) for p in parts]``, with up to ``workers`` parts at a time: the first part here,
    the others in forked children (see the module docstring). ``len(parts)`` should not exceed
    ``workers``: every part past the first gets a child of its own."""
    parts = list(parts)
    if workers <= 1 or len(parts) <= 1 or "fork" not in mp.get_all_start_methods():
        return [fn(p) for p in parts]
    ctx = mp.get_context("fork")
    children = []
    try:
        for k, p in enumerate(parts[1:], start=1):
            recv, send = ctx.Pipe(duplex=False)
            proc = ctx.Process(target=_child, args=(fn, p, send), name=f"split-{k}", daemon=True)
            proc.start()
            send.close()
            children.append((k, proc, recv))
        out = [fn(parts[0])]
        for k, proc, recv in children:
            try:
                status, value = pickle.loads(recv.recv_bytes())
            except EOFError:
                proc.join()
                raise SplitError(f"part {k} of {len(parts)}: its process ended without a result "
                                 f"(exit code {proc.exitcode})") from None
            proc.join()
            if status != "ok":
                raise SplitError(f"part {k} of {len(parts)} failed in its process: {value}")
            out.append(value)
        return out
    finally:
        for _k, proc, recv in children:
            if proc.is_alive():
                proc.kill()
            proc.join()
            recv.close()
