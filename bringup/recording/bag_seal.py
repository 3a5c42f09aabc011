"""A bag's seal: proof that its content is what its run wrote, under a key only the run's owner holds.

Why: a bag's chunk CRCs (bag.py) catch a damaged file, not an edited one - anyone can rewrite a
bag with valid CRCs (every observation's ground point moved, the security section erased) and
``constellation report`` would rebuild another run's figures from it without a word. The envelopes'
MACs (msgs_json/auth.py) do not help afterwards: they are under the run key, which dies with the run.

The seal (RFC 2104 HMAC with SHA-256, Python's ``hmac``): when a run ends (complete, failed or
interrupted) ``constellation run`` computes an HMAC over the bag's ``.mcap`` file - every byte,
after a domain-separation prefix and the file's name and size - and writes it beside the file as
``seal.json`` (``{"v": 1, "alg": "HMAC-SHA256", "key_id", "mcap", "bytes", "hmac"}``). The key is
the user's own, not the run's: 32 random bytes made on first use in
``${XDG_CONFIG_HOME:-~/.config}/agile-dtn/bag-seal.key`` (hex, mode 0600 in a 0700 folder; read
without following a symlink and only when owned by the user, bringup/private_files.py), or the file
named by ``$AGILE_DTN_SEAL_KEY_FILE`` (e.g. one key shared by a team's machines, kept like any
secret). ``key_id`` is the first 16 hex digits of the key's SHA-256: it names the key, it does not
reveal it. The .mcap is the bag's truth (bag_reader.py: metadata.yaml is only checked against it),
so the seal covers the .mcap alone.

:func:`check_bag` is what ``report``, ``bag-info`` and ``replay`` (and the run's own report) call
before they read a bag. Its answer, :class:`Integrity`:

* ``verified``: the seal is there and its HMAC matches under the user's key;
* ``unverified``: the bag has no seal (written before seals, by another tool, or a run killed
  before it could seal), or it was sealed under a key this user does not hold (another user's or
  machine's): it is read, and every output says "unverified";
* a seal that does not match (the file was changed, cut or replaced after its run sealed it) or a
  malformed ``seal.json``: refused, one line naming integrity (:class:`IntegrityError`, exit 2),
  unless the caller asks to read it anyway (``--unverified``), and then it reads as ``unverified``
  with the failure in its detail.

Limits: the seal proves the file is the one a run of this user sealed, not that the run was honest
(a user can seal anything with their own key), nor which run; whoever reads the key file can forge
seals. How we know it is right: tests/faults/test_bag_seal.py (a bag rewritten with valid CRCs, a
seal erased, a metadata section changed, a byte flipped, a file cut: refused or unverified; the
same bag under another user's key: unverified; the HMAC against an independent computation with
the ``cryptography`` package's HMAC).
"""

from __future__ import annotations

import hashlib
import hmac
import json
import os
import secrets
import stat
from dataclasses import dataclass
from pathlib import Path

from bringup.errors import UserError
from bringup.private_files import open_private, read_private_bytes, write_private_atomic

__all__ = ["ENV_SEAL_KEY_FILE", "SEAL_NAME", "Integrity", "IntegrityError", "check_bag", "seal_bag",
           "seal_key_path"]

SEAL_NAME = "seal.json"
ENV_SEAL_KEY_FILE = "AGILE_DTN_SEAL_KEY_FILE"
_PREFIX = b"agile-dtn bag seal v1\0"
_CHUNK = 1 << 20


class IntegrityError(UserError):
    """A bag's seal does not match its content (or is malformed)."""


@dataclass(frozen=True)
class Integrity:
    """``status``: "verified" or "unverified"; ``detail``: one line saying why."""

    status: str
    detail: str

    def as_dict(self) -> dict:
        return {"status": self.status, "detail": self.detail}


def seal_key_path() -> Path:
    """``$AGILE_DTN_SEAL_KEY_FILE``, else ``${XDG_CONFIG_HOME:-~/.config}/agile-dtn/bag-seal.key``."""
    env = os.environ.get(ENV_SEAL_KEY_FILE)
    if env:
        return Path(env).expanduser()
    base = os.environ.get("XDG_CONFIG_HOME") or str(Path.home() / ".config")
    return Path(base) / "agile-dtn" / "bag-seal.key"


def _read_key(path: Path) -> bytes:
    fd = open_private(path, os.O_RDONLY, "bag seal key")  # (FileNotFoundError passes)
    try:
        mode = os.fstat(fd).st_mode
        raw = os.read(fd, 4097)
    finally:
        os.close(fd)
    if mode & 0o077:
        raise UserError(f"bag seal key {path}: permissions {stat.S_IMODE(mode):04o} are too open: readable by "
                        f"others than its owner (chmod 600 {path})")
    try:
        key = bytes.fromhex(raw.decode("ascii").strip())
    except (UnicodeDecodeError, ValueError):
        raise UserError(f"bag seal key {path}: not a key (hex digits on one line)") from None
    if len(key) < 16:
        raise UserError(f"bag seal key {path}: {len(key)} bytes; at least 16 are needed")
    return key


def _user_key(create: bool) -> bytes | None:
    """The user's seal key; made (0600 in a 0700 folder) when ``create`` and missing; None when
    missing and not ``create``."""
    path = seal_key_path()
    try:
        return _read_key(path)
    except FileNotFoundError:
        if not create:
            return None
    try:
        path.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
        fd = open_private(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, "bag seal key", 0o600)
    except FileExistsError:  # (made meanwhile by another run)
        return _read_key(path)
    except OSError as exc:
        raise UserError(f"bag seal key {path}: cannot make it: {exc.strerror}") from None
    try:
        os.write(fd, secrets.token_bytes(32).hex().encode() + b"\n")
        os.fsync(fd)
    finally:
        os.close(fd)
    return _read_key(path)


def _key_id(key: bytes) -> str:
    return hashlib.sha256(key).hexdigest()[:16]


def _mcap_of(bag: Path) -> Path | None:
    if bag.is_file():
        return bag
    mcaps = sorted(bag.glob("*.mcap"))
    return mcaps[0] if len(mcaps) == 1 else None


def _hmac(key: bytes, mcap: Path) -> tuple[str, int]:
    """(hex HMAC-SHA256 of the prefix, the file's name and size, and its bytes; the size read)."""
    with open(mcap, "rb") as fh:
        size = os.fstat(fh.fileno()).st_size
        h = hmac.new(key, _PREFIX + mcap.name.encode() + b"\0" + str(size).encode() + b"\0", hashlib.sha256)
        n = 0
        while chunk := fh.read(_CHUNK):
            h.update(chunk)
            n += len(chunk)
    if n != size:
        raise UserError(f"bag {mcap}: changed while it was being sealed or checked")
    return h.hexdigest(), size


def seal_bag(bag_dir: str | Path) -> Path | None:
    """Seal the bag in ``bag_dir`` (its single .mcap) under the user's key; returns the seal's path,
    None when there is no single .mcap to seal."""
    bag_dir = Path(bag_dir)
    mcap = _mcap_of(bag_dir) if bag_dir.is_dir() else None
    if mcap is None:
        return None
    key = _user_key(create=True)
    mac, size = _hmac(key, mcap)  # type: ignore[arg-type]
    seal = {"v": 1, "alg": "HMAC-SHA256", "key_id": _key_id(key), "mcap": mcap.name, "bytes": size,  # type: ignore[arg-type]
            "hmac": mac}
    return write_private_atomic(bag_dir / SEAL_NAME, (json.dumps(seal, indent=2) + "\n").encode(), "bag seal", 0o644)


def check_bag(bag: str | Path, *, unverified_ok: bool = False) -> Integrity:
    """The bag's integrity (module docstring); :class:`IntegrityError` (one line) when its seal
    does not match and ``unverified_ok`` is False."""
    bag = Path(bag)
    if not bag.exists():  # the reader's own one line says so; nothing to check
        raise UserError(f"bag {bag}: not found")
    folder = bag.parent if bag.is_file() else bag
    mcap = _mcap_of(bag)
    seal_path = folder / SEAL_NAME

    def failed(why: str) -> Integrity:
        if not unverified_ok:
            raise IntegrityError(f"bag {folder}: integrity check failed: {why}; it was changed after its run sealed "
                                 "it (--unverified reads it anyway, marked unverified)")
        return Integrity("unverified", f"integrity check FAILED: {why}")

    if not seal_path.exists():
        return Integrity("unverified", f"no seal ({SEAL_NAME}): written before bags were sealed, by another tool, or "
                                       "by a run that ended before it could seal")
    try:
        seal = json.loads(read_private_bytes(seal_path, "bag seal", 1 << 16))
        if not isinstance(seal, dict) or seal.get("v") != 1 or seal.get("alg") != "HMAC-SHA256":
            raise ValueError("not a version 1 HMAC-SHA256 seal")
        want_mac, key_id, name, size = (str(seal["hmac"]), str(seal["key_id"]), str(seal["mcap"]), seal["bytes"])
    except (ValueError, KeyError, TypeError, UnicodeDecodeError) as exc:
        return failed(f"{SEAL_NAME} is malformed ({' '.join(str(exc).split())[:120]})")
    except UserError as exc:
        return failed(str(exc))
    if mcap is None or mcap.name != name:
        return failed(f"the seal is for {name!r}, the bag holds {mcap.name if mcap else 'no single .mcap'}")
    key = _user_key(create=False)
    if key is None or _key_id(key) != key_id:
        return Integrity("unverified", f"sealed under key {key_id}, which is not this user's seal key "
                                       f"({seal_key_path()}): cannot be checked here")
    mac, got = _hmac(key, mcap)
    if got != size:
        return failed(f"{name} has {got} bytes, the seal says {size}")
    if not hmac.compare_digest(mac, want_mac):
        return failed(f"{name}'s HMAC-SHA256 does not match its seal")
    return Integrity("verified", f"sealed by its run under key {key_id}")
