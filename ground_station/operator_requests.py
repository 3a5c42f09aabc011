"""Live operator requests to a running run's ground gateway: a folder of signed request files.

``constellation task`` / ``constellation command`` (bringup/cli/operator.py) write one request per
file into the run's operator folder (``RUN/operator``, mode 0700, made by ``constellation run
--live-commands``): ``<name>.req``, created exclusively with mode 0600, holding one line of JSON
and the hex HMAC-SHA256 (RFC 2104) of that line under the **operator key** - derived from the run
key of the run's keys file (``RUN/run.keys``, owner-only; bringup/engine/keys.py), which only the
run's user can read: so only the run's user can command it. The ground gateway
(ground_station/commander.py), stepped with the run, reads the new files at each step
(:class:`RequestInbox`), in name order, verifies them and answers each in ``<name>.reply`` (JSON:
``ok`` with the command ids and the issue time, or ``error`` with one line); a request it refuses
is counted by reason and changes nothing. It also keeps ``now.json`` (the run's time at its latest
step) up to date.

Request forms: ``{"request":"task","sat":SAT|"all","lat_deg":..,"lon_deg":..,"priority":P,"by":ISO}``
``{"request":"mode","sat":SAT,"mode":"safe"|"nominal"}`` and ``{"request":"set","sat":SAT,"name":NAME,
"value":V}`` (a parameter of sat_node/operations/commands.py ``SETTABLE``).

Oracle: tests/unit/test_operator_requests.py (the MAC recomputed with Python's hmac; a request under
another key, a malformed one, a file that is not the user's own are refused and counted; each
request is read once); tests/system/test_operator_live.py (a live ROS run tasked from the CLI).
"""

from __future__ import annotations

import hashlib
import hmac
import json
import os
import stat
from pathlib import Path

__all__ = ["NOW_FILE", "OPERATOR_DIR", "REQUEST_KINDS", "RequestInbox", "encode_request", "operator_key", "parse_request"]

OPERATOR_DIR = "operator"
NOW_FILE = "now.json"  # the run's time at its latest step (RequestInbox.mark_time)
REQUEST_KINDS = ("task", "mode", "set")
_MAX_BYTES = 4096


def operator_key(run_key: bytes) -> bytes:
    """The key operator requests are signed with: HMAC-SHA256 of a fixed label under the run key."""
    return hmac.new(run_key, b"constellation operator request v1", hashlib.sha256).digest()


def encode_request(req: dict, key: bytes) -> bytes:
    body = json.dumps(req, separators=(",", ":"), sort_keys=True).encode()
    return body + b"\n" + hmac.new(key, body, hashlib.sha256).hexdigest().encode() + b"\n"


def parse_request(blob: bytes, key: bytes) -> dict:
    """The request in ``blob`` when its tag verifies and it has a known form; ValueError (one line) else."""
    body, sep, tag = blob.rstrip(b"\n").rpartition(b"\n")
    if not sep:
        raise ValueError("malformed: not a JSON line followed by a tag line")
    if not hmac.compare_digest(hmac.new(key, body, hashlib.sha256).hexdigest().encode(), tag):
        raise ValueError("forged: the tag does not verify under this run's operator key")
    try:
        d = json.loads(body)
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"malformed: not JSON ({exc})") from None
    if not isinstance(d, dict) or d.get("request") not in REQUEST_KINDS or not isinstance(d.get("sat"), str):
        raise ValueError(f"malformed: expected request {'|'.join(REQUEST_KINDS)} with a sat")
    return d


class RequestInbox:
    """The gateway's side of the operator folder ``folder``: new requests, verified, each read once."""

    def __init__(self, folder: Path, key: bytes):
        self.folder = Path(folder)
        self._key = key
        self.done: set[str] = set()
        self.refused: dict[str, int] = {}

    def poll(self) -> list[tuple[str, dict | None, str]]:
        """[(name, request or None, error)] of the request files not read before, in name order."""
        try:
            names = sorted(n for n in os.listdir(self.folder) if n.endswith(".req") and n not in self.done)
        except FileNotFoundError:
            return []
        out = []
        for n in names:
            self.done.add(n)
            try:
                req, err = parse_request(self._read(self.folder / n), self._key), ""
            except ValueError as exc:
                req, err = None, str(exc)
                why = err.split(":", 1)[0]
                self.refused[why] = self.refused.get(why, 0) + 1
            out.append((n, req, err))
        return out

    @staticmethod
    def _read(path: Path) -> bytes:
        try:
            fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_CLOEXEC)
        except OSError as exc:
            raise ValueError(f"unreadable: {exc.strerror}") from None
        try:
            st = os.fstat(fd)
            if not stat.S_ISREG(st.st_mode) or st.st_uid != os.getuid() or st.st_mode & 0o077:
                raise ValueError("untrusted: not a regular owner-only file of this user")
            return os.read(fd, _MAX_BYTES + 1)[:_MAX_BYTES + 1]
        finally:
            os.close(fd)

    def reply(self, name: str, answer: dict) -> None:
        """Write ``<name>.reply`` (JSON) atomically, owner-only."""
        self._write(self.folder / (name.removesuffix(".req") + ".reply"), answer)

    def mark_time(self, t_ns: int) -> None:
        """Write ``now.json`` (``{"t_s": ...}``): the run's time at its latest step, for the operator."""
        self._write(self.folder / NOW_FILE, {"t_s": t_ns / 1e9})

    @staticmethod
    def _write(final: Path, answer: dict) -> None:
        tmp = final.with_suffix(".tmp")
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_NOFOLLOW | os.O_CLOEXEC, 0o600)
        try:
            os.write(fd, json.dumps(answer, sort_keys=True).encode() + b"\n")
        finally:
            os.close(fd)
        os.replace(tmp, final)
