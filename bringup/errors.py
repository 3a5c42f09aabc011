"""Errors a user can fix; the CLI prints them as one line without a traceback.

:func:`os_error_line` turns an OSError (a full disk, a read-only or missing folder, a file where a
folder should be) into one line naming what happened and the file.

Checked by tests/unit/test_cli_exit.py (printed as one line, exit code 2) and
tests/faults/test_hostile_inputs.py (a full disk named, an unwritable --out named).
"""

import errno

__all__ = ["UserError", "os_error_line"]


class UserError(Exception):
    """Bad input from the user (a file, a flag, a bag): the message names what and where."""


_WHAT = {
    errno.ENOSPC: "no space left on device",
    errno.EDQUOT: "disk quota exceeded",
    errno.EFBIG: "file too large (the file size limit, ulimit -f, was reached)",
    errno.EROFS: "read-only file system",
    errno.EACCES: "permission denied",
    errno.EPERM: "operation not permitted",
    errno.ENOENT: "no such file or directory",
    errno.ENOTDIR: "a path component is not a folder",
    errno.EISDIR: "is a folder",
    errno.EEXIST: "already exists",
    errno.ENAMETOOLONG: "file name too long",
}


def os_error_line(exc: OSError, doing: str = "writing") -> str:
    """One line for an OSError: "no space left on device writing /runs/x/bag/bag.mcap"."""
    what = _WHAT.get(exc.errno) or (exc.strerror or type(exc).__name__).lower()
    where = exc.filename if exc.filename is not None else None
    if where is None:
        return what
    line = f"{what} {doing} {where}"
    if exc.filename2 is not None:
        line += f" -> {exc.filename2}"
    return line
