"""The local engine's recorder, in a second process beside the run.

``constellation run --engine local`` runs every node's logic in one process (bringup/engine/local.py).
Recording the run - the MCAP bag (bringup/recording/bag.py), the visualisation frames
(bringup/recording/viz_feed.py) and decoding what report.json is made of (bringup/analysis/report.py ReportBuilder) -
does not change what any node does, so it runs beside the nodes in a forked child, on the machine's
other core.

How it works: the parent buffers the calls it would make on a bag - a step's envelopes (as plain
tuples), then ``write_clock(t)``, the visualisation of instant ``t`` and the plotted series
(bringup/recording/metrics_feed.py, with the bundles in flight the parent hands over) - and sends them through a
pipe in batches of a few thousand envelopes (marshal: tuples of ints, str and bytes, about twice as
fast as pickle for them). The child makes exactly those calls, in that order, on
a BagWriter of its own, so the file is the one the parent would have written itself
(tests/unit/test_record_process.py compares the bytes). Envelopes on the report's topics are also
decoded as they arrive; at ``finish`` the child builds the report and sends it back.

Failure handling:
* the child fails (disk full, bad path, ...): it sends the error (an OSError as "no space left on
  device writing <file>") and exits; the parent raises ``RecorderError`` naming it at its next batch
  or at ``finish``;
* the child is killed (SIGKILL, the OOM killer): the parent's next batch or ``finish`` raises
  ``RecorderError`` naming the signal; the bag holds every chunk closed before (bag.py, "Crash
  safety"; tests/faults/test_recorder_kill.py);
* Ctrl-C, SIGTERM, SIGHUP, SIGQUIT (a terminal or a supervisor signals the whole process group):
  the child ignores them (bringup/stop_signals.py), the parent's ``close`` (also on an exception) tells it to close
  the bag, so the bag is complete and readable up to the last step handed over;
* the parent dies: the child reads end-of-file, closes the bag and exits.

The child is forked before the satellites open their SQLite stores and never touches the parent's
objects other than the world (read only); it leaves with ``os._exit`` (no finalizers of the parent's
objects run in it).
"""

from __future__ import annotations

import gc
import marshal
import multiprocessing as mp
import os
import pickle
import signal
from pathlib import Path

from bringup.errors import UserError, os_error_line
from bringup.recording.bag import BagWriter
from bringup.recording.metrics_feed import MetricsFeed
from bringup.recording.viz_feed import VizFeed
from bringup.stop_signals import STOP_SIGNALS
from msgs_json.envelope import Envelope

__all__ = ["Recorder", "RecorderError"]

_BATCH = 4096  # envelopes per pipe message (a paper run: ~450k envelopes, ~110 messages)


class RecorderError(UserError):
    """The recorder process failed; the message names what failed."""


class Recorder:
    """Parent side: ``write_envelope``/``write_envelopes``/``step`` buffer, ``finish`` returns the
    report, ``close`` ends the child (idempotent). Use as a context manager."""

    def __init__(self, bag_dir: str | Path, world=None, *, viz: bool = True, report=None):
        """``report``: None (no report), or a class whose instances ``add(env)`` each envelope on
        one of its ``TOPIC_SUFFIXES`` and ``build(meta, runtime)`` the report at ``finish``
        (bringup/analysis/report.py ReportBuilder: the recorder does not know what a report holds)."""
        self.bag_dir = Path(bag_dir)
        if self.bag_dir.exists():
            raise UserError(f"bag {self.bag_dir}: already exists, not overwriting")
        ctx = mp.get_context("fork")
        self._conn, child_conn = ctx.Pipe(duplex=True)
        self._proc = ctx.Process(target=_child_main, name="recorder", daemon=False,
                                 args=(child_conn, self._conn, str(self.bag_dir), world if viz else None, report))
        # SIGINT blocked across the fork: the child ignores it from its first instruction on (a
        # Ctrl-C at that very moment reaches the parent once it is unblocked here)
        old = signal.pthread_sigmask(signal.SIG_BLOCK, set(STOP_SIGNALS))
        try:
            self._proc.start()
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, old)
        child_conn.close()
        self._ops: list = []  # lists of envelope tuples and clock ints, in call order
        self._n = 0
        self._closed = False
        self.report: dict | None = None
        self.counts: dict[str, int] = {}

    # -- what the local engine calls -----------------------------------------------------------------
    def write_envelope(self, env: Envelope) -> None:
        self.write_envelopes([env])

    def write_envelopes(self, envs) -> None:
        ops = [(e.t_ns, e.source, e.seq, e.topic, e.data) for e in envs]
        self._ops.append(ops)
        self._n += len(ops)
        if self._n >= _BATCH:
            self._flush()

    def step(self, t_ns: int, in_flight: int | None = None) -> None:
        """The /clock record and the visualisation of instant ``t_ns`` (VizFeed and MetricsFeed decide
        if due); ``in_flight``: the ISL medium's bundle copies after the previous step, if any."""
        self._ops.append(int(t_ns) if in_flight is None else (int(t_ns), int(in_flight)))

    # -- end -----------------------------------------------------------------------------------------
    def finish(self, meta=None, runtime: dict | None = None, *, meanwhile=None) -> dict | None:
        """Close the bag; with ``meta``, the report of everything written (else None).
        ``meanwhile()``, if given, runs here while the child finishes."""
        if self._closed:
            raise RecorderError(f"recorder for {self.bag_dir}: already closed")
        self._flush()
        self._send(b"F" + pickle.dumps((meta, runtime)))
        self._closed = True
        if meanwhile is not None:
            try:
                meanwhile()
            except BaseException:
                self._join_quietly()
                raise
        try:
            reply = self._conn.recv()
        except (EOFError, OSError):  # the child is gone (killed: ConnectionResetError)
            reply = None
        self._join()
        if not reply or reply[0] != "ok":
            raise RecorderError(self._failure(reply))
        self.report, self.counts = reply[1], reply[2]
        return self.report

    def close(self) -> None:
        """End the child, bag closed (what was handed over is in it); no report."""
        if self._closed:
            return
        self._closed = True
        try:
            self._flush()
            self._conn.send_bytes(b"F" + pickle.dumps((None, None)))
            self._conn.recv()
        except (OSError, EOFError, RecorderError):
            pass
        self._join()

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- plumbing ------------------------------------------------------------------------------------
    def _flush(self) -> None:
        if not self._ops:
            return
        ops, self._ops, self._n = self._ops, [], 0
        try:
            spoke = self._conn.poll()  # the child only speaks first when it failed
        except OSError:
            spoke = True
        if spoke:
            raise RecorderError(self._failure(self._recv_quiet()))
        self._send(b"O" + marshal.dumps(ops))

    def _send(self, msg: bytes) -> None:
        try:
            self._conn.send_bytes(msg)
        except OSError as exc:
            raise RecorderError(self._failure(self._recv_quiet(), exc)) from None

    def _recv_quiet(self):
        try:
            return self._conn.recv() if self._conn.poll(5.0) else None
        except (OSError, EOFError):
            return None

    def _failure(self, reply, exc: Exception | None = None) -> str:
        if reply and reply[0] == "error":
            return f"recorder for {self.bag_dir} failed: {reply[1]}"
        self._proc.join(timeout=5.0)
        code = self._proc.exitcode
        if code is not None and code < 0:
            try:
                how = f"was killed by {signal.Signals(-code).name}"
            except ValueError:
                how = f"was killed by signal {-code}"
        else:
            how = f"stopped without a reply (exit code {code})"
        return (f"recorder process for {self.bag_dir} {how}: the bag holds what it wrote up to its last closed "
                "chunk (constellation bag-info / report read it)")

    def _join_quietly(self) -> None:
        try:
            self._conn.recv() if self._conn.poll(60) else None
        except (OSError, EOFError):
            pass
        self._join()

    def _join(self) -> None:
        self._proc.join(timeout=60)
        if self._proc.is_alive():
            self._proc.kill()
            self._proc.join()
        self._conn.close()


def _child_main(conn, parent_conn, bag_dir: str, world, report) -> None:
    """The recorder process: replay the parent's bag calls, decode the report's envelopes."""
    for sig in STOP_SIGNALS:  # the parent decides when the bag closes
        signal.signal(sig, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, set(STOP_SIGNALS))
    parent_conn.close()
    gc.freeze()  # the inherited heap is never garbage; only what this process makes is scanned
    gc.set_threshold(50_000, 50, 1000)
    builder = report() if report is not None else None
    suffixes = tuple(report.TOPIC_SUFFIXES) if report is not None else ()
    wanted: dict[str, tuple[bool, bool]] = {}
    reply = None
    try:
        viz = metrics = None
        if world is not None:
            viz = VizFeed(world)
            metrics = MetricsFeed(world.scenario.value.revisit_zero_s)
        last = None  # (t_ns, in_flight) of the last step
        with BagWriter(bag_dir, epoch_ns=world.scenario.epoch_ns if world is not None else 0) as bag:
            while True:
                try:
                    msg = conn.recv_bytes()
                except EOFError:  # the parent is gone: close the bag with what it handed over
                    break
                if msg[:1] == b"F":
                    meta, runtime = pickle.loads(msg[1:])
                    if metrics is not None and last is not None:  # the series' last points
                        metrics.write(bag, last[0], in_flight=last[1], final=True)
                    bag.close()
                    rep = builder.build(meta, runtime) if (builder is not None and meta is not None) else None
                    reply = ("ok", rep, dict(bag.counts))
                    break
                for op in marshal.loads(memoryview(msg)[1:]):
                    if type(op) is int or type(op) is tuple:  # a step: t_ns, or (t_ns, in_flight)
                        last = (op, None) if type(op) is int else op
                        bag.write_clock(last[0])
                        if viz is not None:
                            viz.write(bag, last[0])
                            metrics.write(bag, last[0], in_flight=last[1])
                        continue
                    envs = [Envelope(*x) for x in op]
                    bag.write_envelopes(envs)
                    if builder is not None or metrics is not None:
                        for env in envs:
                            w = wanted.get(env.topic)
                            if w is None:  # (to the report, to the value series)
                                w = wanted[env.topic] = (builder is not None and env.topic.endswith(suffixes),
                                                         metrics is not None and env.topic.endswith("/observations"))
                            if w[0]:
                                builder.add(env)
                            if w[1]:
                                metrics.observe(env)
    except OSError as exc:  # a full disk, a vanished folder: named with the file
        line = os_error_line(exc)
        reply = ("error", line if exc.filename else f"{line} writing {Path(bag_dir) / (Path(bag_dir).name + '.mcap')}")
    except BaseException as exc:  # noqa: BLE001 - reported to the parent, which raises it
        reply = ("error", f"{type(exc).__name__}: {exc}")
    try:
        if reply is not None:
            conn.send(reply)
        conn.close()
    except OSError:
        pass
    os._exit(0 if reply is None or reply[0] == "ok" else 1)
