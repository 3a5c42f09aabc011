"""Files and folders only the run's user controls: checked before a run writes or reads its secrets.

A run writes its lock, state, keys, bag and report into its ``--out`` folder, and its processes read
their keys and run spec from there. If another local user owns that folder or can write into it (a
shared /tmp, a group project folder, a CI workspace), they can replace any of those files between
two system calls: a symlink planted where the run opens a file makes the run truncate and write the
file it points to (with the run's rights), and a key file renamed over the launcher's makes every
process of the run trust the other user's keys. So:

* :func:`check_private_dir`: a folder is refused (one line) unless the effective user owns it, it
  is writable by no one else (no group or other write bit), and its parent is not writable by others
  without the sticky bit (else another user could rename the folder away and put their own in its
  place);
* :func:`open_private`: every run file is opened with ``O_NOFOLLOW`` (a symlink is refused, never
  followed) and ``O_CLOEXEC``, and the descriptor's own ``fstat`` must show a regular file owned by
  the effective user with one link (a hard link to a file elsewhere is refused); new files are made
  with ``O_EXCL`` and mode 0600 (or the given mode), whatever the umask;
* :func:`private_state_dir`: a per-user folder for state that outlives one run folder (the ROS
  domain leases, bringup/engine/ros/launcher.py; the bag seal key, bringup/recording/bag_seal.py),
  made with mode 0700 and checked as above every time it is used.

How we know it is right: tests/faults/test_trust_files.py (a symlinked lock or key file, a foreign
owned and a world-writable --out, a key file replaced after writing, each with a second local user
when the test runs as root, refused in one line and the symlink's target untouched).
"""

from __future__ import annotations

import errno
import os
import pwd
import stat
import tempfile
from pathlib import Path

from bringup.errors import UserError

__all__ = ["check_private_dir", "open_private", "private_state_dir", "read_private_bytes",
           "write_private_atomic"]


def _user(uid: int) -> str:
    try:
        return f"user {pwd.getpwuid(uid).pw_name} (uid {uid})"
    except KeyError:
        return f"uid {uid}"


def check_private_dir(path: str | Path, what: str) -> Path:
    """``path`` (a folder, symlinks resolved) if only the effective user controls it; else a
    one-line UserError naming ``what``, the folder and who else controls it."""
    p = Path(path)
    try:
        st = os.stat(p)
    except OSError as exc:
        raise UserError(f"{what} {p}: {exc.strerror}") from None
    if not stat.S_ISDIR(st.st_mode):
        raise UserError(f"{what} {p}: is a file, not a folder")
    me = os.geteuid()
    if st.st_uid != me:
        raise UserError(f"{what} {p}: owned by {_user(st.st_uid)}, not by you ({_user(me)}): another user "
                        "could replace the run's files; choose a folder of your own")
    if st.st_mode & 0o022:
        who = "everyone" if st.st_mode & 0o002 else "its group"
        raise UserError(f"{what} {p}: writable by {who} (mode {stat.S_IMODE(st.st_mode):04o}): another user could "
                        f"replace the run's files (chmod go-w {p}, or choose a folder of your own)")
    parent = p.resolve().parent
    try:
        pst = os.stat(parent)
    except OSError:
        return p
    if pst.st_mode & 0o022 and not pst.st_mode & stat.S_ISVTX:
        raise UserError(f"{what} {p}: its parent {parent} is writable by others without the sticky bit "
                        f"(mode {stat.S_IMODE(pst.st_mode):04o}): another user could move the folder and put "
                        "their own in its place; choose a folder of your own")
    return p


def _check_fd(fd: int, path: Path, what: str) -> os.stat_result:
    st = os.fstat(fd)
    if not stat.S_ISREG(st.st_mode):
        raise UserError(f"{what} {path}: not a regular file")
    me = os.geteuid()
    if st.st_uid != me:
        raise UserError(f"{what} {path}: owned by {_user(st.st_uid)}, not by you ({_user(me)}): "
                        "refusing a file another user made")
    if st.st_nlink != 1:
        raise UserError(f"{what} {path}: has {st.st_nlink} hard links: refusing a file linked from elsewhere")
    return st


def open_private(path: str | Path, flags: int, what: str, mode: int = 0o600) -> int:
    """``os.open`` of a run file that refuses symlinks and checks the file it opened (module
    docstring); ``O_CREAT|O_EXCL`` files are made with ``mode`` exactly. Returns the descriptor;
    one-line UserError naming ``what`` otherwise (FileNotFoundError passes through)."""
    path = Path(path)
    try:
        fd = os.open(path, flags | os.O_NOFOLLOW | os.O_CLOEXEC, mode)
    except FileNotFoundError:
        raise
    except OSError as exc:
        if exc.errno == errno.ELOOP or os.path.islink(path):  #: O_NOFOLLOW met a symlink
            raise UserError(f"{what} {path}: is a symbolic link: refusing to follow it (someone may have planted "
                            "it to make the run overwrite another file)") from None
        raise UserError(f"{what} {path}: {exc.strerror}") from None
    try:
        _check_fd(fd, path, what)
        if flags & os.O_CREAT and flags & os.O_EXCL:
            os.fchmod(fd, mode)  # whatever the umask
    except BaseException:
        os.close(fd)
        raise
    return fd


def read_private_bytes(path: str | Path, what: str, limit: int = 1 << 20) -> bytes:
    """Up to ``limit`` bytes of a run file opened by :func:`open_private`."""
    fd = open_private(path, os.O_RDONLY, what)
    try:
        return os.read(fd, limit)
    finally:
        os.close(fd)


def write_private_atomic(path: str | Path, data: bytes, what: str, mode: int = 0o600) -> Path:
    """Write ``data`` to ``path`` whole or not at all: a new temporary file beside it (``O_EXCL``,
    never a symlink), fsync, rename over ``path``. OSError names ``path``."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    try:
        tmp.unlink(missing_ok=True)
        fd = open_private(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, what, mode)
        try:
            view = memoryview(data)
            while view:
                view = view[os.write(fd, view):]
            os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, path)
    except OSError as exc:
        try:
            tmp.unlink()
        except OSError:
            pass
        raise OSError(exc.errno, exc.strerror, str(path)) from None
    return path


def private_state_dir(name: str, env: str | None = None) -> Path:
    """A per-user folder ``name`` for state beyond one run: ``$env`` when set, else under
    ``$XDG_RUNTIME_DIR`` (per user, mode 0700, by systemd) or the temporary folder as
    ``NAME-<uid>``; made with mode 0700 and checked by :func:`check_private_dir`."""
    if env and os.environ.get(env):
        d = Path(os.environ[env])
    else:
        base = os.environ.get("XDG_RUNTIME_DIR")
        if base and os.path.isdir(base):
            d = Path(base) / name
        else:
            d = Path(tempfile.gettempdir()) / f"{name}-{os.geteuid()}"
    try:
        d.mkdir(mode=0o700, parents=True, exist_ok=True)
    except OSError as exc:
        raise UserError(f"private folder {d}: cannot make it: {exc.strerror}") from None
    if d.is_symlink():
        raise UserError(f"private folder {d}: is a symbolic link: refusing it (another user may have planted it)")
    return check_private_dir(d, "private folder")
