"""Reading the text files a user hands the project (scenarios, contact plans, traffic tables).

Every one is UTF-8 text (a UTF-8 byte-order mark, as spreadsheet programs write, is skipped). A file
that is not - UTF-16 (a byte-order mark, or NUL bytes between ASCII letters), binary, or UTF-8 with
a bad byte - fails with one line naming the file, what it is and where the first bad byte is, not a
UnicodeDecodeError from deep inside a parser. A file larger than its kind allows is refused before
it is read (a scenario is a page of TOML; a multi-gigabyte one is a wrong path).

:func:`open_text` gives a stream for line-by-line readers (traffic tables: their size is bounded by
what they describe, checked as they are read); :func:`read_text` the whole text, size-capped.
Both raise :class:`TextInputError` (a ValueError) with the one line.

How we know it is right: tests/faults/test_hostile_inputs.py feeds binary, UTF-16 (both byte
orders, with and without BOM), Latin-1 and oversized files as scenario, contact plan and traffic:
one line each, naming the file.
"""

from __future__ import annotations

import codecs
import io
import os
from pathlib import Path

__all__ = ["TextInputError", "decode_error_line", "open_text", "read_text"]


class TextInputError(ValueError):
    """A text input file that cannot be read as UTF-8 text; the message is one line naming it."""


def _sniff(head: bytes) -> str | None:
    """Why ``head`` (the file's first bytes) is not UTF-8 text, or None."""
    if head.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        return "UTF-16 text (a byte-order mark); save it as UTF-8"
    if head.startswith((codecs.BOM_UTF32_LE, codecs.BOM_UTF32_BE)):
        return "UTF-32 text (a byte-order mark); save it as UTF-8"
    sample = head[:4096]
    if b"\x00" in sample:
        # UTF-16 without a BOM: ASCII letters with a NUL beside each
        even, odd = sample[0::2], sample[1::2]
        if sample and (even.count(0) > 0.4 * len(even) or odd.count(0) > 0.4 * len(odd)):
            return "UTF-16 text (NUL bytes between the letters); save it as UTF-8"
        return "binary data (it holds NUL bytes), not text"
    return None


def decode_error_line(exc: UnicodeDecodeError, where: str | Path, offset: int = 0) -> str:
    """One line for a UTF-8 decoding failure at byte ``offset + exc.start`` of ``where``."""
    bad = exc.object[exc.start:exc.start + 1].hex() if isinstance(exc.object, (bytes, bytearray)) else "?"
    return f"{where}: not UTF-8 text (byte 0x{bad} at offset {offset + exc.start}); save it as UTF-8"


def _check_file(path: Path, what: str, max_bytes: int | None) -> bytes:
    try:
        st = os.stat(path)
        if max_bytes is not None and st.st_size > max_bytes:
            raise TextInputError(f"{path}: {st.st_size:,} bytes, over the {max_bytes:,}-byte limit for a {what} "
                                 "(is this the right file?)")
        with open(path, "rb") as fh:
            head = fh.read(4096)
    except OSError as exc:
        raise TextInputError(f"{path}: cannot read {what}: {exc.strerror or exc}") from None
    why = _sniff(head)
    if why is not None:
        raise TextInputError(f"{path}: {what} is {why}")
    return head


def read_text(path: str | Path, what: str, max_bytes: int | None = None) -> str:
    """The whole UTF-8 text of ``path`` (a leading BOM dropped); TextInputError (one line) if it is
    missing, unreadable, larger than ``max_bytes``, or not UTF-8 text."""
    path = Path(path)
    _check_file(path, what, max_bytes)
    try:
        with open(path, "rb") as fh:
            data = fh.read(max_bytes + 1 if max_bytes is not None else -1)
    except OSError as exc:
        raise TextInputError(f"{path}: cannot read {what}: {exc.strerror or exc}") from None
    if max_bytes is not None and len(data) > max_bytes:  # (a file that grew, a device)
        raise TextInputError(f"{path}: over the {max_bytes:,}-byte limit for a {what}")
    skip = 3 if data.startswith(codecs.BOM_UTF8) else 0
    try:
        return data[skip:].decode("utf-8")
    except UnicodeDecodeError as exc:
        raise TextInputError(decode_error_line(exc, path, skip)) from None


def open_text(path: str | Path, what: str) -> io.TextIOWrapper:
    """A text stream over ``path`` for reading line by line (UTF-8, BOM dropped, universal
    newlines as the csv module wants: ``newline=""``). A decoding failure later in the file raises
    UnicodeDecodeError while reading: turn it into a line with :func:`decode_error_line`."""
    path = Path(path)
    _check_file(path, what, None)
    try:
        return open(path, encoding="utf-8-sig", newline="")
    except OSError as exc:
        raise TextInputError(f"{path}: cannot read {what}: {exc.strerror or exc}") from None
