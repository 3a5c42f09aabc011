"""Bags that prove they are unedited (bringup/recording/bag_seal.py) and reports that never trace back.

Against main 8408404: a bag rewritten with valid CRCs (every observation's GP + 7) gave
``constellation report BAG`` another value, exit 0, no warning; /run/meta's security section
erased gave ``security = {}``, no warning; /run/meta records gone gave a traceback.

Oracles, on one sealed bag of a real local run:

* the seal's HMAC equals ``openssl dgst -sha256 -mac HMAC`` over the same bytes (an independent
  implementation);
* the bag rewritten with valid CRCs (observations' GPs moved and values halved; the security section erased) and a
  single byte flipped: ``report``, ``bag-info`` and ``replay`` refuse it in one line naming
  integrity, exit 2; with ``--unverified`` report and bag-info read it and say "unverified"
  (report.json ``integrity``, a warning line) - and the moved GPs do change the value, so the
  check is what stood between the edit and a wrong report;
* the seal removed, or the bag read by a user holding another seal key: read, "unverified";
* a bag whose /run/meta channel holds no run record: one line, exit 2, no traceback.
"""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import pytest

from bringup.cli.main import main
from bringup.recording.bag import BagReader, BagWriter, string_cdr, string_from_cdr
from bringup.recording.bag_seal import ENV_SEAL_KEY_FILE, SEAL_NAME, seal_key_path
from msgs_json import codec
from msgs_json import schemas as S
from msgs_json.wire import decode_envelope, encode_envelope

pytestmark = [pytest.mark.faults]


@pytest.fixture(scope="module")
def sealed(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("seal") / "run"
    assert main(["run", "--engine", "local", "--sats", "6", "--hours", "1", "--no-plots", "--no-progress",
                 "--out", str(out)]) == 0
    assert (out / "bag" / SEAL_NAME).exists()
    return out


def _copy(sealed: Path, tmp_path: Path) -> Path:
    bag = tmp_path / "bag"
    shutil.copytree(sealed / "bag", bag)
    return bag


def _rewrite(bag: Path, edit) -> None:
    """Write the bag again with the bag writer (valid CRCs), each message through ``edit(topic, msgtype,
    cdr) -> cdr | None`` (None: dropped); the seal stays as it was."""
    new = bag.parent / "new" / "bag"  # (the .mcap is named after its folder)
    with BagReader(bag) as r, BagWriter(new, epoch_ns=r.epoch_ns) as w:
        for m in r.messages():
            cdr = edit(m.topic, m.msgtype, m.cdr)
            if cdr is not None:
                w.write_raw(m.topic, m.msgtype, cdr, m.log_time_ns)
    for f in ("bag.mcap", "metadata.yaml"):
        (new / f).replace(bag / f)
    shutil.rmtree(new.parent)


def _forge_observations(topic, msgtype, cdr):
    if not topic.endswith("/observations"):
        return cdr
    env = decode_envelope(string_from_cdr(cdr), topic)
    obs = codec.decode(topic, env.data)
    assert isinstance(obs, S.Observation)
    moved = codec.encode(S.Observation(**{**{f: getattr(obs, f) for f in obs.__struct_fields__}, "gp": obs.gp + 7,
                                          "recorded_value": obs.recorded_value / 2}))
    return string_cdr(encode_envelope(env._replace(data=moved)))


def _erase_security(topic, msgtype, cdr):
    if topic != "/run/meta":
        return cdr
    env = decode_envelope(string_from_cdr(cdr), topic)
    d = json.loads(env.data)
    d.pop("security", None)
    return string_cdr(encode_envelope(env._replace(data=json.dumps(d))))


def _line(capsys) -> str:
    cap = capsys.readouterr()
    err = cap.err.strip()
    assert err.count("\n") == 0 and "Traceback" not in err, err
    return err


def test_seal_is_hmac_sha256_of_the_file(sealed, tmp_path):
    seal = json.loads((sealed / "bag" / SEAL_NAME).read_text())
    key = seal_key_path().read_text().strip()
    mcap = sealed / "bag" / "bag.mcap"
    data = tmp_path / "sealed-bytes"
    data.write_bytes(b"agile-dtn bag seal v1\0bag.mcap\0" + str(mcap.stat().st_size).encode() + b"\0"
                     + mcap.read_bytes())
    got = subprocess.run(["openssl", "dgst", "-sha256", "-mac", "HMAC", "-macopt", f"hexkey:{key}", str(data)],
                         capture_output=True, text=True, check=True).stdout.split()[-1]
    assert got == seal["hmac"] and seal["bytes"] == mcap.stat().st_size


@pytest.mark.parametrize("edit", [_forge_observations, _erase_security])
def test_edited_bag_with_valid_crcs_is_refused(sealed, tmp_path, capsys, edit):
    bag = _copy(sealed, tmp_path)
    _rewrite(bag, edit)
    for cmd in (["report", str(bag)], ["bag-info", str(bag)], ["replay", str(bag), "--rate", "0"]):
        assert main(cmd) == 2, cmd
        err = _line(capsys)
        assert "integrity check failed" in err and "--unverified" in err, err
    assert main(["report", str(bag), "--unverified"]) == 0
    cap = capsys.readouterr()
    rep = json.loads(cap.out)
    assert rep["integrity"]["status"] == "unverified" and "FAILED" in rep["integrity"]["detail"]
    assert "unverified" in cap.err
    honest = json.loads((sealed / "report.json").read_text())
    if edit is _forge_observations:  # (the edit matters: the figures it gives are another run's)
        assert rep["value"]["cumulative"] < honest["value"]["cumulative"]
    assert main(["bag-info", str(bag), "--unverified"]) == 0
    assert "integrity: unverified" in capsys.readouterr().out


def test_flipped_byte_is_refused(sealed, tmp_path, capsys):
    bag = _copy(sealed, tmp_path)
    mcap = bag / "bag.mcap"
    raw = bytearray(mcap.read_bytes())
    raw[len(raw) // 2] ^= 0x01
    mcap.write_bytes(bytes(raw))
    assert main(["report", str(bag)]) == 2
    assert "HMAC-SHA256 does not match" in _line(capsys)
    mcap.write_bytes(bytes(raw[: len(raw) // 2]))  # cut: the size differs
    assert main(["bag-info", str(bag)]) == 2
    assert "bytes, the seal says" in _line(capsys)


def test_unsealed_or_foreign_key_reads_as_unverified(sealed, tmp_path, capsys, monkeypatch):
    assert main(["report", str(sealed / "bag")]) == 0
    assert json.loads(capsys.readouterr().out)["integrity"]["status"] == "verified"
    bag = _copy(sealed, tmp_path)
    (bag / SEAL_NAME).unlink()
    assert main(["report", str(bag)]) == 0
    cap = capsys.readouterr()
    assert json.loads(cap.out)["integrity"]["status"] == "unverified" and "no seal" in cap.err
    # another user's key (or another machine's): cannot be checked here, read as unverified
    other = tmp_path / "other"
    other.mkdir(mode=0o700)
    monkeypatch.setenv(ENV_SEAL_KEY_FILE, str(other / "k"))
    (other / "k").write_text("ab" * 32 + "\n")
    (other / "k").chmod(0o600)
    assert main(["bag-info", str(sealed / "bag")]) == 0
    cap = capsys.readouterr()
    assert "integrity: unverified (sealed under key" in cap.out and "unverified" in cap.err


def test_missing_run_meta_is_one_line(sealed, tmp_path, capsys):
    bag = _copy(sealed, tmp_path)
    # the /run/meta channel kept but its records replaced by something that is not a run record
    _rewrite(bag, lambda t, m, cdr: cdr if t != "/run/meta" else None)
    (bag / SEAL_NAME).unlink()
    assert main(["report", str(bag)]) == 2
    assert "no /run/meta record" in _line(capsys)
    bag2 = _copy(sealed, tmp_path / "b2")
    new = bag2.parent / "new" / "bag"
    with BagReader(bag2) as r, BagWriter(new, epoch_ns=r.epoch_ns) as w:
        for m in r.messages():
            if m.topic == "/run/meta":
                w.write_raw("/run/meta", "rosgraph_msgs/msg/Clock", bytes(12), m.log_time_ns)
            else:
                w.write_raw(m.topic, m.msgtype, m.cdr, m.log_time_ns)
    for f in ("bag.mcap", "metadata.yaml"):
        (new / f).replace(bag2 / f)
    (bag2 / SEAL_NAME).unlink()
    assert main(["report", str(bag2)]) == 2
    assert "/run/meta holds no run record" in _line(capsys)
