"""Some of a local run's participants, made and stepped in a forked child process (issue 5: local
engine >= 1000x real time on two cores).

The local engine (bringup/local_engine.py) steps every participant once per lockstep step, each on
the envelopes of the step before; no participant sees another's state. So a group of them can run
in a second process, at the same time as the parent steps its own: per step the parent sends the
group's inboxes in one pipe message (marshal of plain tuples) and, after stepping its own
participants, reads back each one's emits and next wakeup. The engine stamps, sorts and delivers
those exactly as it does the parent's, so a run with a worker gives the same envelopes, in the same
order, as the one-process run (tests/unit/test_worker_group.py on toy participants;
tests/system/test_engines_equal.py and test_local_workers.py on the paper scenario).

The child makes its participants itself (``make()`` runs in it: their SQLite stores open there and
are batched there, bringup/store_batches.py) and answers with their names and subscriptions. A
failure in the child comes back as the participant's name, the call and the exception, and the
engine raises it as its own EngineError; the parent gone (EOF) or ``close(abandon=True)`` rolls back
the open store batch and closes everything. SIGINT is ignored in the child: the parent decides.
"""

from __future__ import annotations

import gc
import marshal
import multiprocessing as mp
import os
import pickle
import signal
from collections.abc import Callable, Iterable

from bringup.errors import UserError
from msgs_json.envelope import Envelope

__all__ = ["RemoteFailure", "WorkerGroup"]


class RemoteFailure(UserError):
    """A participant in a worker process failed (``name``, ``call``: start/step/finish, ``text``)."""

    def __init__(self, name: str, call: str, text: str):
        super().__init__(f"{name} failed in {call}: {text}")
        self.name, self.call, self.text = name, call, text


class WorkerGroup:
    """Parent side. ``names``/``subscriptions`` of the child's participants, in ``make()`` order;
    ``start``/``step``/``finish`` for all of them at once; ``rejected`` (name -> count) after finish."""

    def __init__(self, make: Callable[[], list], *, close_in_child: Iterable = (), label: str = "worker"):
        ctx = mp.get_context("fork")
        self.label = label
        self._conn, child_conn = ctx.Pipe(duplex=True)
        old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        try:
            self._proc = ctx.Process(target=_child_main, name=label, daemon=True,
                                     args=(child_conn, [self._conn, *close_in_child], make))
            self._proc.start()
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, old)
        child_conn.close()
        self._closed = False
        self._sent = False
        reply = self._recv("start-up")
        self.names: list[str] = reply["names"]
        self.subscriptions: list[list[str]] = reply["subscriptions"]
        self.rejected: dict[str, int] = {}

    @property
    def pipe(self):
        """This process's end of the pipe to the worker (see Recorder.pipe)."""
        return self._conn

    # -- the engine's calls ----------------------------------------------------------------------
    def start(self, t_ns: int) -> list[tuple[list, int | None]]:
        self._send(b"S" + marshal.dumps(int(t_ns)))
        return self._recv("start")

    def send_step(self, t_ns: int, inboxes: list[list[Envelope]]) -> None:
        """Hand the group step ``t_ns`` (one inbox per participant, in ``names`` order); the child
        steps while the parent steps its own. :meth:`recv_step` collects the results."""
        self._send(b"T" + marshal.dumps((t_ns, [[tuple(e) for e in box] for box in inboxes])))
        self._sent = True

    def recv_step(self) -> list[tuple[list, int | None]]:
        """Per participant: (emits as (topic, data, t_ns) tuples, next wakeup)."""
        self._sent = False
        return self._recv("step")

    def finish(self, t_ns: int) -> list[list]:
        self._send(b"F" + marshal.dumps(int(t_ns)))
        reply = self._recv("finish")
        self.rejected = reply["rejected"]
        return reply["emits"]

    def close(self, *, abandon: bool = False) -> None:
        """Close the child's participants (their stores: the open batch committed, or rolled back
        with ``abandon``) and wait for it to exit. Idempotent."""
        if self._closed:
            return
        self._closed = True
        try:
            if self._sent:  # a step in flight: let it end first
                self._recv_raw()
            self._conn.send_bytes(b"A" if abandon else b"C")
            self._recv_raw()
        except (OSError, EOFError, RemoteFailure):
            pass
        self._proc.join(timeout=60)
        if self._proc.is_alive():
            self._proc.kill()
            self._proc.join()
        self._conn.close()

    # -- plumbing --------------------------------------------------------------------------------
    def _send(self, msg: bytes) -> None:
        if self._closed:
            raise UserError(f"{self.label}: already closed")
        try:
            self._conn.send_bytes(msg)
        except OSError as exc:
            raise UserError(f"{self.label}: stopped ({type(exc).__name__}: {exc}; exit code "
                            f"{self._proc.exitcode})") from None

    def _recv_raw(self):
        return pickle.loads(self._conn.recv_bytes())

    def _recv(self, what: str):
        try:
            reply = self._recv_raw()
        except (EOFError, OSError):
            self._proc.join(timeout=5)
            raise UserError(f"{self.label}: stopped without a reply to {what} (exit code "
                            f"{self._proc.exitcode})") from None
        if reply[0] == "error":
            _, name, call, text = reply
            raise RemoteFailure(name, call, text)
        return reply[1]


def _child_main(conn, inherited, make) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    for c in inherited:  # the parent's pipe ends (ours, the recorder's): EOF must reach their readers
        try:
            c.close()
        except OSError:
            pass
    from bringup.store_batches import StoreBatches
    from msgs_json.envelope import Emit, StepResult

    def reply(obj) -> None:
        conn.send_bytes(pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL))

    parts: list = []
    batches = None
    abandon = True
    try:
        try:
            parts = make()
        except BaseException as exc:  # noqa: BLE001 - reported to the parent
            reply(("error", "worker", "start-up", f"{type(exc).__name__}: {exc}"))
            return
        batches = StoreBatches(s for s in (getattr(getattr(p, "agent", None), "store", None) for p in parts)
                               if s is not None)
        reply(("ok", {"names": [p.name for p in parts],
                      "subscriptions": [list(dict.fromkeys(p.subscriptions())) for p in parts]}))
        gc.collect()
        gc.freeze()
        gc.set_threshold(50_000, 50, 1000)
        batches.start()
        make_env = Envelope._make
        steps = [p.step for p in parts]
        while True:
            try:
                msg = conn.recv_bytes()
            except EOFError:  # the parent is gone
                break
            kind, body = msg[:1], memoryview(msg)[1:]
            if kind in (b"A", b"C"):
                abandon = kind == b"A"
                break
            i, t, call = 0, None, "step"
            try:
                if kind == b"T":
                    t, boxes = marshal.loads(body)
                    batches.step()  # (a lockstep step begins: as the parent's on_step)
                    out = []
                    for i, box in enumerate(boxes):
                        out.append(_pack(steps[i](t, [make_env(x) for x in box]), StepResult, Emit))
                    reply(("ok", out))
                elif kind == b"S":
                    call = "start"
                    t = marshal.loads(body)
                    out = []
                    for i, p in enumerate(parts):
                        out.append(_pack(p.start(t), StepResult, Emit))
                    reply(("ok", out))
                elif kind == b"F":
                    call = "finish"
                    t = marshal.loads(body)
                    emits = []
                    for i, p in enumerate(parts):
                        emits.append(_pack_emits(p.finish(t), Emit))
                    batches.finish()
                    abandon = False
                    reply(("ok", {"emits": emits, "rejected": {p.name: int(getattr(p, "rejected", 0) or 0)
                                                               for p in parts}}))
                else:
                    raise ValueError(f"unknown request {bytes(kind)!r}")
            except BaseException as exc:  # noqa: BLE001 - reported to the parent, which raises it
                name = parts[i].name if i < len(parts) else "worker"
                reply(("error", name, f"{call}({t})", f"{type(exc).__name__}: {exc}"))
    finally:
        try:
            if batches is not None:
                if abandon:
                    batches.abandon()
                else:
                    batches.finish()
        except Exception:  # noqa: BLE001 - closing below still releases the files
            pass
        for p in parts:
            close = getattr(p, "close", None)
            if callable(close):
                try:
                    close()
                except Exception:  # noqa: BLE001
                    pass
        try:
            reply(("ok", None))
            conn.close()
        except OSError:
            pass
        os._exit(0)


def _pack_emits(emits, Emit) -> list[tuple]:
    out = []
    for e in emits:
        if type(e) is not Emit and not isinstance(e, Emit):
            raise TypeError(f"emitted {type(e).__name__}, expected Emit")
        out.append((e.topic, e.data, e.t_ns))
    return out


def _pack(r, StepResult, Emit) -> tuple[list, int | None]:
    if not isinstance(r, StepResult):
        raise TypeError(f"returned {type(r).__name__}, expected StepResult")
    return (_pack_emits(r.emits, Emit) if r.emits else []), r.next_wakeup_ns
