"""Files only the run's user controls (bringup/private_files.py, run_folder.py, engine/keys.py, launcher.py).

Each case is one of the breaks found against main 8408404, reproduced here:

* a ``.run.lock`` planted as a symlink made the run truncate and write the file it points to:
  now the run is refused in one line (exit 2) and that file is untouched;
* an ``--out`` owned by another user, or writable by group or everyone, let another user swap the
  run's files: refused in one line, exit 2, before anything is written;
* a ``run.keys`` renamed over the launcher's after it was written made every process trust another
  user's keys: a keys file owned by another user, a symlink, or one whose content differs from the
  digest the launcher hands its processes is refused;
* the domain-lease lock files lived in a fixed /tmp folder any user could pre-create: the folder is
  per user, made 0700, and one owned by someone else is refused.

The other user: when the test runs as root, a second local user made with ``useradd`` for the test
and removed after it; otherwise root itself (every file of ``/`` belongs to it) stands in.
"""

from __future__ import annotations

import hashlib
import os
import pwd
import shutil
import subprocess
import uuid
from pathlib import Path

import pytest

from bringup.cli.main import main
from bringup.engine.keys import ENV_KEYS_DIGEST, RunKeys
from bringup.errors import UserError
from bringup.private_files import check_private_dir, open_private, private_state_dir

pytestmark = [pytest.mark.faults]

RUN = ["run", "--engine", "local", "--sats", "6", "--hours", "0.1", "--no-plots", "--no-progress"]


@pytest.fixture(scope="module")
def other_uid():
    """The uid of another local user (module docstring)."""
    if os.geteuid() != 0:
        yield 0
        return
    # (root's sbin folders may be off a minimal PATH)
    useradd = shutil.which("useradd", path=os.pathsep.join([os.environ.get("PATH", ""), "/usr/sbin", "/sbin"]))
    if useradd is None:
        raise RuntimeError("tests run as root need useradd to make a second local user")
    name = f"agdtn{uuid.uuid4().hex[:8]}"
    subprocess.run([useradd, "--no-create-home", "--shell", "/usr/sbin/nologin", name], check=True)
    try:
        yield pwd.getpwnam(name).pw_uid
    finally:
        subprocess.run([str(Path(useradd).with_name("userdel")), name], check=False)


def _give(path: Path, uid: int) -> None:
    os.chown(path, uid, -1)


def _one_line_error(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "Traceback" not in err, err
    return err


def test_symlinked_lock_is_refused_and_its_target_untouched(tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    victim = tmp_path / "precious"
    victim.write_text("keep me\n")
    victim.chmod(0o600)
    (out / ".run.lock").symlink_to(victim)
    assert main([*RUN, "--out", str(out)]) == 2
    err = _one_line_error(capsys)
    assert "symbolic link" in err and ".run.lock" in err, err
    assert victim.read_text() == "keep me\n"
    assert not (out / "run_status.json").exists()


def test_symlinked_status_is_not_written_through(tmp_path, capsys):
    """run_status.json planted as a symlink: the status is written to a new file renamed over the
    link, never through it."""
    out = tmp_path / "out"
    out.mkdir()
    victim = tmp_path / "precious"
    victim.write_text("keep me\n")
    (out / "run_status.json").symlink_to(victim)
    assert main([*RUN, "--out", str(out)]) == 0
    assert victim.read_text() == "keep me\n"
    assert not (out / "run_status.json").is_symlink()


def test_foreign_owned_out_is_refused(tmp_path, capsys, other_uid):
    out = tmp_path / "theirs"
    out.mkdir(mode=0o755)
    _give(out, other_uid)
    assert main([*RUN, "--out", str(out)]) == 2
    err = _one_line_error(capsys)
    assert "owned by" in err and "not by you" in err and str(out) in err, err
    assert os.listdir(out) == []


@pytest.mark.parametrize("mode, who", [(0o777, "everyone"), (0o775, "its group"), (0o1777, "everyone")])
def test_writable_out_is_refused(tmp_path, capsys, mode, who):
    out = tmp_path / "shared"
    out.mkdir()
    out.chmod(mode)
    assert main([*RUN, "--out", str(out)]) == 2
    err = _one_line_error(capsys)
    assert f"writable by {who}" in err and str(out) in err, err
    assert os.listdir(out) == []


def test_out_in_a_parent_others_can_write_is_refused(tmp_path, capsys):
    parent = tmp_path / "open"
    parent.mkdir()
    parent.chmod(0o777)  # (no sticky bit: another user could rename the run folder away)
    out = parent / "run"
    out.mkdir(mode=0o755)
    assert main([*RUN, "--out", str(out)]) == 2
    assert "its parent" in _one_line_error(capsys)


def test_a_new_out_is_made_private(tmp_path):
    out = tmp_path / "a" / "b"
    old = os.umask(0o002)  # (even under a umask that leaves group write)
    try:
        assert main([*RUN, "--out", str(out)]) == 0
    finally:
        os.umask(old)
    assert not out.stat().st_mode & 0o022 and not out.parent.stat().st_mode & 0o022
    assert (out / ".run.lock").stat().st_mode & 0o777 == 0o600


# -- the run's keys -------------------------------------------------------------------------------------

def _keys_file(tmp_path: Path) -> tuple[Path, RunKeys]:
    keys = RunKeys.generate(env={})
    return keys.write(tmp_path / "run.keys"), keys


def test_keys_read_back_with_the_launchers_digest(tmp_path):
    path, keys = _keys_file(tmp_path)
    assert RunKeys.read(path, env={ENV_KEYS_DIGEST: keys.digest()}) == keys
    assert keys.digest() == hashlib.sha256(path.read_bytes()).hexdigest()


def test_keys_replaced_after_writing_are_refused(tmp_path, other_uid):
    """Another user's own 0600 keys file renamed over the launcher's (the issue's attack): refused
    by its owner and, for one with the run's owner too, by the digest."""
    path, keys = _keys_file(tmp_path)
    digest = keys.digest()
    theirs = RunKeys.generate(env={}).write(tmp_path / "theirs.keys")
    _give(theirs, other_uid)
    os.replace(theirs, path)
    with pytest.raises(UserError, match="owned by") as e:
        RunKeys.read(path, env={ENV_KEYS_DIGEST: digest})
    assert "\n" not in str(e.value)
    # the same file made by the run's user (e.g. a copy of theirs): the digest refuses it
    os.chown(path, os.geteuid(), -1)
    with pytest.raises(UserError, match="SHA-256 differs"):
        RunKeys.read(path, env={ENV_KEYS_DIGEST: digest})


def test_symlinked_or_linked_keys_are_refused(tmp_path):
    path, keys = _keys_file(tmp_path)
    link = tmp_path / "link.keys"
    link.symlink_to(path)
    with pytest.raises(UserError, match="symbolic link"):
        RunKeys.read(link, env={ENV_KEYS_DIGEST: keys.digest()})
    hard = tmp_path / "hard.keys"
    os.link(path, hard)
    with pytest.raises(UserError, match="hard links"):
        RunKeys.read(hard, env={ENV_KEYS_DIGEST: keys.digest()})


def test_run_keys_are_written_past_a_planted_symlink(tmp_path):
    """A symlink planted at run.keys is removed, never written through."""
    victim = tmp_path / "precious"
    victim.write_text("keep me\n")
    (tmp_path / "run.keys").symlink_to(victim)
    _path, keys = _keys_file(tmp_path)
    assert victim.read_text() == "keep me\n"
    assert RunKeys.read(tmp_path / "run.keys") == keys


# -- the domain leases -----------------------------------------------------------------------------------

def test_lease_folder_is_private_and_per_user(tmp_path, monkeypatch, other_uid):
    from bringup.engine.ros.launcher import ENV_LEASE_DIR, lease_domain_id

    monkeypatch.delenv(ENV_LEASE_DIR, raising=False)
    monkeypatch.delenv("XDG_RUNTIME_DIR", raising=False)
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", None)
    d = private_state_dir("agile_dtn_ros_domains")
    assert d == tmp_path / f"agile_dtn_ros_domains-{os.geteuid()}"
    assert d.stat().st_mode & 0o777 == 0o700
    with lease_domain_id(90, 91) as lease:
        assert lease.domain_id in (90, 91)
        assert (d / f"domain_{lease.domain_id}.lock").stat().st_mode & 0o777 == 0o600
    # another user pre-created the folder (the hold on every id): refused, not used
    theirs = tmp_path / "theirs"
    theirs.mkdir(mode=0o700)
    _give(theirs, other_uid)
    monkeypatch.setenv(ENV_LEASE_DIR, str(theirs))
    with pytest.raises(UserError, match="owned by"):
        lease_domain_id(90, 91)
    # a lock file planted as a symlink inside one's own folder: refused
    mine = tmp_path / "mine"
    mine.mkdir(mode=0o700)
    monkeypatch.setenv(ENV_LEASE_DIR, str(mine))
    for i in (90, 91):
        (mine / f"domain_{i}.lock").symlink_to(tmp_path / "precious")
    with pytest.raises(UserError, match="symbolic link"):
        lease_domain_id(90, 91)
    assert not (tmp_path / "precious").exists()


def test_open_private_checks_the_file_it_opened(tmp_path, other_uid):
    f = tmp_path / "f"
    f.write_text("x")
    _give(f, other_uid)
    with pytest.raises(UserError, match="owned by"):
        open_private(f, os.O_RDONLY, "run file")
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    with pytest.raises(UserError, match="not a regular file"):
        open_private(fifo, os.O_RDONLY | os.O_NONBLOCK, "run file")
    with pytest.raises(UserError, match="is a file, not a folder"):
        check_private_dir(tmp_path / "fifo", "--out")
