"""A run's secrets: the BPSec key of the constellation, the run's envelope key and the ground's command key.

Three keys, none of them in the source:

* the **BPSec key** (RFC 9172/9173 BIB-HMAC-SHA2, sat_node/dtn/bpsec.py): every satellite's bundle
  agent signs the bundles it makes with it and drops bundles whose BIB does not verify. It comes
  from the deployment, in this order: ``--bpsec-key-file FILE``, the environment
  (``AGILE_DTN_BPSEC_KEY_FILE`` = a file, or ``AGILE_DTN_BPSEC_KEY`` = the key in hex), else a key
  generated for the run (``os.urandom``, 32 bytes). A key file holds the key in hex on one line
  (``openssl rand -hex 32 > key``), at least 16 bytes, and must not be readable by group or others.
* the **run key** (msgs_json/auth.py): 32 random bytes per run; every envelope of the run (data
  topics, lockstep steps and acks) carries a MAC under it, and anything without a valid one is
  rejected. Only the run's processes have it.

* the **ground's command key** (sat_node/operations/commands.py): 32 random bytes per run, independent
  of the BPSec key. The command gateway signs each operator command under the key derived from it
  for the addressed satellite; a satellite's flight software is given only its own derived key
  (bringup/scenario/participants.py). Every process of a ROS run reads this file, so the separation
  is in what each satellite's software holds, not enforced by the operating system: a deployment that
  must keep the ground's key off the satellites' computers gives each one its derived key alone
  (not built here).

:class:`RunKeys` holds all three. The launcher (bringup/engine/ros/launcher.py) writes them into the run
folder as ``run.keys`` with owner-only permissions (created with mode 0600, never widened) and
names the file in the run spec; every process of the run reads it at start (a restarted one too),
and the launcher removes it when the run ends. ``constellation compose`` writes it beside the
compose file and mounts it read-only into every container, like the run spec. Why a file and not
the environment or an inherited fd: an environment variable is inherited by every descendant and
shows in ``podman inspect`` / ``docker inspect`` of a container (and in compose files); an inherited
descriptor does not cross into a container nor survive a process restart. A file with mode 0600
is readable by its owner only (the same protection as ``/proc/PID/environ``), goes into containers
by the same bind mount as the run spec, and is reread by a restarted process.

The file is not trusted for being there: it is opened without following a symlink and must be a
regular file owned by the reading process's user, with one link and mode 0600
(bringup/private_files.py), and the launcher gives every process it starts the file's SHA-256 in
``AGILE_DTN_RUN_KEYS_SHA256`` (the environment of a process is readable by its user only): a
process refuses a keys file whose digest differs, so a file renamed over the launcher's after it was
written (by a user who can write the run folder) is refused by every process, a restarted one too,
instead of making the run trust another user's keys. (``constellation run`` refuses such a folder
before it starts: bringup/cli/run_folder.py.)

Checked by tests/unit/test_run_keys.py (key sources and their order, hex and length errors, file
permissions refused when open to others, the written file's mode, round trip) and
tests/faults/test_trust_files.py (a symlinked, foreign or replaced keys file refused).
"""

from __future__ import annotations

import hashlib
import json
import os
import secrets
import stat
from dataclasses import dataclass
from pathlib import Path

from bringup.errors import UserError
from bringup.private_files import open_private
from sat_node.dtn.agent import MIN_KEY_BYTES

__all__ = ["ENV_BPSEC_KEY", "ENV_BPSEC_KEY_FILE", "ENV_KEYS_DIGEST", "KEYS_FILE_NAME", "RunKeys", "read_key_file",
           "resolve_bpsec_key", "write_key_file"]

ENV_BPSEC_KEY = "AGILE_DTN_BPSEC_KEY"
ENV_BPSEC_KEY_FILE = "AGILE_DTN_BPSEC_KEY_FILE"
KEYS_FILE_NAME = "run.keys"
ENV_KEYS_DIGEST = "AGILE_DTN_RUN_KEYS_SHA256"
_RUN_KEY_BYTES = 32


def _from_hex(text: str, where: str) -> bytes:
    t = "".join(text.split())
    try:
        key = bytes.fromhex(t)
    except ValueError:
        raise UserError(f"{where}: the BPSec key must be hexadecimal digits (e.g. `openssl rand -hex 32`)") from None
    if len(key) < MIN_KEY_BYTES:
        raise UserError(f"{where}: the BPSec key has {len(key)} bytes; at least {MIN_KEY_BYTES} are needed")
    return key


def _check_private(path: Path, st: os.stat_result) -> None:
    if not stat.S_ISREG(st.st_mode):
        raise UserError(f"{path}: not a regular file")
    if st.st_mode & 0o077:
        raise UserError(f"{path}: permissions {stat.S_IMODE(st.st_mode):04o} are too open for a key file: "
                        f"readable by others than its owner (chmod 600 {path})")


def _read_private(path: Path, what: str, missing: str, *, run_file: bool = False) -> bytes:
    """Up to 4097 bytes of an owner-only file (one more than any key file may hold, so the caller
    sees an oversized one); one-line UserError naming ``what`` when missing, unreadable or open to
    others. ``run_file``: a file of the run folder (never a symlink, owned by this user, one link:
    bringup/private_files.py ``open_private``)."""
    try:
        if run_file:
            fd = open_private(path, os.O_RDONLY, "run keys")
        else:
            fd = os.open(path, os.O_RDONLY)
    except FileNotFoundError:
        raise UserError(f"{what}: {missing}") from None
    except OSError as exc:
        raise UserError(f"{what}: {exc.strerror}") from None
    try:
        _check_private(path, os.fstat(fd))
        return os.read(fd, 4097)
    finally:
        os.close(fd)


def read_key_file(path: Path) -> bytes:
    """The BPSec key in ``path`` (hex on one line; owner-only permissions)."""
    path = Path(path)
    raw = _read_private(path, f"BPSec key file {path}", "no such file")
    if len(raw) > 4096:
        raise UserError(f"BPSec key file {path}: larger than 4 KiB: not a key")
    try:
        text = raw.decode("ascii")
    except UnicodeDecodeError:
        raise UserError(f"BPSec key file {path}: not text; the key must be written in hex") from None
    return _from_hex(text, f"BPSec key file {path}")


def write_key_file(path: Path, key: bytes) -> Path:
    """Write ``key`` in hex to a new file ``path`` with mode 0600 (the form :func:`read_key_file` reads)."""
    return _write_private(Path(path), key.hex().encode() + b"\n")


def _write_private(path: Path, data: bytes) -> Path:
    path.unlink(missing_ok=True)  # never reuse a file someone else made, with its permissions
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC, 0o600)
    try:
        os.fchmod(fd, 0o600)  # whatever the umask
        os.write(fd, data)
    finally:
        os.close(fd)
    return path


def resolve_bpsec_key(path: Path | None = None, env: dict[str, str] | None = None) -> tuple[bytes, str]:
    """(key, where it came from): ``path``, else ``$AGILE_DTN_BPSEC_KEY_FILE``, else
    ``$AGILE_DTN_BPSEC_KEY`` (hex), else a new random key for this run."""
    env = os.environ if env is None else env
    if path is not None:
        return read_key_file(Path(path)), f"file {path}"
    if env.get(ENV_BPSEC_KEY_FILE):
        p = env[ENV_BPSEC_KEY_FILE]
        return read_key_file(Path(p)), f"file {p} (${ENV_BPSEC_KEY_FILE})"
    if env.get(ENV_BPSEC_KEY):
        return _from_hex(env[ENV_BPSEC_KEY], f"${ENV_BPSEC_KEY}"), f"${ENV_BPSEC_KEY}"
    return secrets.token_bytes(_RUN_KEY_BYTES), "generated for this run"


@dataclass(frozen=True)
class RunKeys:
    """The run key (envelope MACs) and the BPSec key of one run, and where the BPSec key came from."""

    run: bytes
    bpsec: bytes
    bpsec_from: str = ""
    command: bytes = b""  # the ground's command key (sat_node/operations/commands.py); b"": none

    @classmethod
    def generate(cls, bpsec_key_file: Path | None = None, env: dict[str, str] | None = None) -> RunKeys:
        """A new run key; the BPSec key from the deployment (:func:`resolve_bpsec_key`)."""
        bpsec, where = resolve_bpsec_key(bpsec_key_file, env)
        return cls(secrets.token_bytes(_RUN_KEY_BYTES), bpsec, where, secrets.token_bytes(_RUN_KEY_BYTES))

    def encoded(self) -> bytes:
        """The file's content (:meth:`write`)."""
        return json.dumps({"v": 1, "run": self.run.hex(), "bpsec": self.bpsec.hex(),
                           "bpsec_from": self.bpsec_from, "command": self.command.hex()}).encode()

    def digest(self) -> str:
        """SHA-256 (hex) of the file's content: what the launcher hands its processes
        (``AGILE_DTN_RUN_KEYS_SHA256``) to check the file they read against."""
        return hashlib.sha256(self.encoded()).hexdigest()

    def write(self, path: Path) -> Path:
        """Write to a new file ``path`` created with mode 0600 (an existing file is replaced: it is
        unlinked first, so a file someone else made is never reused with its permissions)."""
        return _write_private(Path(path), self.encoded())

    @classmethod
    def read(cls, path: Path, env: dict[str, str] | None = None) -> RunKeys:
        """Read a file written by :meth:`write`; one-line UserError when missing, a symlink, not the
        user's own, open to others, malformed, or (with ``$AGILE_DTN_RUN_KEYS_SHA256`` in ``env``,
        default the process's) not the file the launcher wrote."""
        path = Path(path)
        env = os.environ if env is None else env
        raw = _read_private(path, f"run keys {path}", "no such file (the launcher writes it; is the run over?)",
                            run_file=True)
        want = env.get(ENV_KEYS_DIGEST)
        if want and hashlib.sha256(raw).hexdigest() != want.strip().lower():
            raise UserError(f"run keys {path}: not the file the launcher wrote (its SHA-256 differs from "
                            f"${ENV_KEYS_DIGEST}): replaced after it was written; refusing its keys")
        try:
            d = json.loads(raw)
            keys = cls(bytes.fromhex(d["run"]), bytes.fromhex(d["bpsec"]), str(d.get("bpsec_from", "")),
                       bytes.fromhex(d.get("command", "")))
        except (ValueError, KeyError, TypeError):
            raise UserError(f"run keys {path}: not a run keys file") from None
        if len(keys.run) < MIN_KEY_BYTES or len(keys.bpsec) < MIN_KEY_BYTES:
            raise UserError(f"run keys {path}: keys shorter than {MIN_KEY_BYTES} bytes")
        return keys
