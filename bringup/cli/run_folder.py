"""A run's output folder: one run at a time, outputs written whole, the run's state on disk.

``constellation run --out DIR`` writes a bag, a report and plots into DIR (``compare`` and
``sweep --out`` their tables, each run of ``compare`` a run folder of its own). :class:`RunFolder` makes that safe:

* **only the run's user controls it**: DIR must be owned by the effective user and writable by no
  one else (bringup/private_files.py ``check_private_dir``: a shared /tmp, a group folder or
  another user's folder is refused in one line, exit 2), and every file the run keeps there (the
  lock, the state, the keys) is opened without following a symlink and checked to be a regular
  file of the user's own (``open_private``): another local user cannot make the run write through
  a planted symlink or read their keys;
* **where the user meant**: DIR is made absolute against the caller's working folder before
  anything starts (the ROS engine's processes run elsewhere and get absolute paths only);
  a DIR that is a file, or cannot be made or written, is one line naming it;
* **one run at a time**: the run holds an exclusive ``flock`` on ``DIR/.run.lock`` (Linux
  flock(2): released by the kernel when the process ends, however it ends, so a killed run leaves
  no stale lock); a second run into the same DIR fails at once, naming the first (its pid, start
  time and command), and touches nothing;
* **no stale outputs**: once the lock is held, the outputs of an earlier run (:data:`OUTPUTS`: the
  bag, report, plots, logs, stores, state) are removed, so nothing left in DIR can be taken for this
  run's; the world cache (``cache/``) and files the run does not write stay;
* **the run's state** in ``DIR/run_status.json``: ``running`` (with the pid) from the start, then
  ``complete``, ``failed`` (with the one-line error) or ``interrupted`` (with the signal:
  SIGINT, SIGTERM, SIGHUP or SIGQUIT, bringup/stop_signals.py), and whether the report
  beside it is ``partial``;
* **whole files**: :func:`write_text_atomic` writes a temporary file in the same folder, flushes it
  to disk and renames it over the target (rename(2) is atomic within a file system), so a reader
  sees the old file or the new one, never a part.

How we know it is right: tests/faults/test_run_folder.py (two runs into one --out: the second
refused in one line, the first's report its own; stale outputs removed; a failed run's status and
partial report; an --out that is a file or unwritable; a relative --out from another folder) and
tests/faults/test_hostile_inputs.py; tests/faults/test_trust_files.py (a symlinked lock, a foreign
owned or world-writable --out) and tests/faults/test_run_signals.py (each stop signal).
"""

from __future__ import annotations

import errno
import fcntl
import json
import math
import os
import shutil
import sys
import time
from pathlib import Path

from bringup.errors import UserError, os_error_line
from bringup.private_files import check_private_dir, open_private, write_private_atomic
from bringup.stop_signals import signal_name

__all__ = ["LOCK_NAME", "OUTPUTS", "STATUS_NAME", "RunFolder", "json_text", "write_text_atomic"]

LOCK_NAME = ".run.lock"
STATUS_NAME = "run_status.json"
# what a run writes into its folder (bringup/cli/run.py, bringup/engine/ros/launcher.py)
OUTPUTS = ("bag", "report.json", "report.md", "plots", "logs", "store", "state", "run_spec.json", "run.keys",
           "scenario.toml", STATUS_NAME)


def _finite(obj):
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    return obj


def json_text(obj, **kw) -> str:
    """JSON text of ``obj`` with every non-finite float written as null (JSON has no NaN or
    Infinity: ``json.dumps`` would write tokens other readers reject)."""
    return json.dumps(_finite(obj), allow_nan=False, **kw)


def write_text_atomic(path: str | Path, text: str) -> Path:
    """Write ``text`` to ``path`` whole or not at all (temporary file in the same folder, fsync,
    rename); an OSError names ``path``."""
    # (the temporary file is new, never a symlink someone planted: bringup/private_files.py)
    return write_private_atomic(path, text.encode("utf-8"), "output file", 0o644)


def _now_utc() -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())


class RunFolder:
    """The output folder of one run (module docstring). Use as a context manager::

        with RunFolder(out, "constellation run ...") as folder:   # locked, stale outputs gone
            ...                                                    # the run
            folder.done(partial=False)                             # status complete
        # leaving with an exception: status failed (or interrupted), the exception goes on
    """

    def __init__(self, out: str | Path, command: str | None = None, *, what: str = "--out",
                 outputs: tuple[str, ...] = OUTPUTS):
        """``outputs``: the names in the folder this kind of run writes (removed at the start)."""
        self.path = Path(os.path.abspath(Path(out).expanduser()))
        self.command = command if command is not None else " ".join(sys.argv)
        self.what = what
        self.outputs = tuple(outputs) + ((STATUS_NAME,) if STATUS_NAME not in outputs else ())
        self._fd: int | None = None
        self._status: dict = {}
        self.partial = False

    # -- open -----------------------------------------------------------------------------------------
    def __enter__(self) -> RunFolder:
        p = self.path
        if p.exists() and not p.is_dir():
            raise UserError(f"{self.what} {p}: is a file, not a folder")
        try:
            for q in [*reversed(p.parents), p]:  # (each folder made here: writable by its owner only)
                if not q.exists():
                    q.mkdir(mode=0o755, exist_ok=True)
        except OSError as exc:
            raise UserError(f"{self.what} {p}: cannot make the folder: {os_error_line(exc, 'making')}") from None
        check_private_dir(p, self.what)
        if not os.access(p, os.W_OK | os.X_OK):
            raise UserError(f"{self.what} {p}: not writable (permission denied)")
        try:
            fd = open_private(p / LOCK_NAME, os.O_RDWR | os.O_CREAT, f"{self.what} lock file", 0o600)
        except OSError as exc:
            raise UserError(f"{self.what} {p}: cannot make its lock file: {os_error_line(exc)}") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            holder = _read_holder(fd)
            os.close(fd)
            if exc.errno in (errno.EWOULDBLOCK, errno.EAGAIN):
                raise UserError(f"{self.what} {p}: another run is writing into this folder ({holder}); "
                                "wait for it to end or choose another --out") from None
            raise UserError(f"{self.what} {p}: cannot lock {LOCK_NAME}: {os_error_line(exc, 'locking')}") from None
        self._fd = fd
        try:
            os.ftruncate(fd, 0)
            os.pwrite(fd, json.dumps({"pid": os.getpid(), "started_utc": _now_utc(),
                                      "command": self.command}).encode() + b"\n", 0)
            self._clear_stale()
            self._status = {"status": "running", "pid": os.getpid(), "started_utc": _now_utc(),
                            "command": self.command}
            self._write_status()
        except BaseException:
            self._release()
            raise
        return self

    def _clear_stale(self) -> None:
        for name in self.outputs:
            q = self.path / name
            try:
                if q.is_dir() and not q.is_symlink():
                    shutil.rmtree(q)
                elif q.exists() or q.is_symlink():
                    q.unlink()
            except OSError as exc:
                raise UserError(f"{self.what} {self.path}: cannot remove the earlier run's {name}: "
                                f"{os_error_line(exc, 'removing')}") from None

    # -- close ----------------------------------------------------------------------------------------
    def done(self, *, partial: bool = False) -> None:
        """The run ended and wrote its outputs."""
        self.partial = partial
        self._status.update(status="complete", partial=partial, ended_utc=_now_utc())
        self._write_status()

    def __exit__(self, exc_type, exc, tb) -> None:
        try:
            if exc_type is not None and self._status.get("status") == "running":
                interrupted = issubclass(exc_type, KeyboardInterrupt)
                if interrupted:
                    self._status["signal"] = signal_name(getattr(exc, "signum", 2))
                self._status.update(status="interrupted" if interrupted else "failed", ended_utc=_now_utc(),
                                    error=(os_error_line(exc) if isinstance(exc, OSError) else
                                           " ".join(str(exc).split())[:500] or exc_type.__name__),
                                    partial=self.partial,
                                    report=STATUS_REPORT if (self.path / "report.json").exists() else None)
                try:
                    self._write_status()
                except (OSError, UserError):
                    pass
        finally:
            self._release()

    def mark_partial_report(self) -> None:
        """A partial report.json was written for a failed run (the status says so)."""
        self.partial = True

    def _write_status(self) -> None:
        text = json.dumps(self._status, indent=2, sort_keys=True) + "\n"
        try:
            write_text_atomic(self.path / STATUS_NAME, text)
        except OSError:
            # a full disk has no room for a second file: rewrite the one there (its page is freed
            # by the truncation and taken again), so the status still says how the run ended
            fd = open_private(self.path / STATUS_NAME, os.O_WRONLY | os.O_TRUNC, "run status")
            with os.fdopen(fd, "w", encoding="utf-8") as fh:
                fh.write(text)

    def _release(self) -> None:
        if self._fd is not None:
            os.close(self._fd)  # (closing the descriptor releases the flock)
            self._fd = None


STATUS_REPORT = "report.json"


def _read_holder(fd: int) -> str:
    try:
        d = json.loads(os.pread(fd, 4096, 0).decode("utf-8", "replace") or "{}")
        return f"pid {d.get('pid')}, started {d.get('started_utc')}: {str(d.get('command'))[:120]}"
    except (OSError, ValueError):
        return "its pid is unknown"
