"""The run's keys come from the deployment, never from the source (bringup/engine/keys.py).

Oracles: the order of the BPSec key's sources by construction (file argument, then
$AGILE_DTN_BPSEC_KEY_FILE, then $AGILE_DTN_BPSEC_KEY, then a fresh random key); a key file open to
group or others is refused, as ssh refuses such a private key; the files we write have mode 0600
whatever the umask; a bundle signed with the constant key the agent used to carry in its source is
rejected by an agent holding the deployment's key (counted as an integrity drop), and one signed
with the deployment's key is accepted.
"""

from __future__ import annotations

import os
import stat

import pytest

from bringup.engine.keys import (
    ENV_BPSEC_KEY,
    ENV_BPSEC_KEY_FILE,
    RunKeys,
    read_key_file,
    resolve_bpsec_key,
    write_key_file,
)
from bringup.errors import UserError
from tests.keys import TEST_BPSEC_KEY

# The key sat_node/dtn/agent.py held as AgentConfig's default before keys came from the deployment.
OLD_SOURCE_KEY = b"constellation-shared-key-0000000"


def _key_file(path, text: str, mode: int = 0o600):
    path.write_text(text)
    os.chmod(path, mode)
    return path


def test_key_sources_in_order(tmp_path):
    a = _key_file(tmp_path / "a.key", "aa" * 32 + "\n")
    b = _key_file(tmp_path / "b.key", "bb" * 32)
    env = {ENV_BPSEC_KEY_FILE: str(b), ENV_BPSEC_KEY: "cc" * 16}
    assert resolve_bpsec_key(a, env) == (bytes.fromhex("aa" * 32), f"file {a}")
    assert resolve_bpsec_key(None, env)[0] == bytes.fromhex("bb" * 32)
    assert resolve_bpsec_key(None, {ENV_BPSEC_KEY: "cc" * 16}) == (bytes.fromhex("cc" * 16), f"${ENV_BPSEC_KEY}")
    k1, w1 = resolve_bpsec_key(None, {})
    k2, _ = resolve_bpsec_key(None, {})
    assert w1 == "generated for this run" and len(k1) == 32 and k1 != k2


@pytest.mark.parametrize("text, what", [("zz" * 20, "hexadecimal"), ("ab" * 15, "at least 16"),
                                        ("", "has 0 bytes")])
def test_bad_keys_are_one_line(tmp_path, text, what):
    with pytest.raises(UserError, match=what) as e:
        read_key_file(_key_file(tmp_path / "k", text))
    assert "\n" not in str(e.value)
    if text:  # (an empty variable is no key given)
        with pytest.raises(UserError, match=what):
            resolve_bpsec_key(None, {ENV_BPSEC_KEY: text})


@pytest.mark.parametrize("mode", [0o644, 0o640, 0o604, 0o660])
def test_key_file_open_to_others_is_refused(tmp_path, mode):
    p = _key_file(tmp_path / "k", "ab" * 32, mode)
    with pytest.raises(UserError, match="too open"):
        read_key_file(p)
    keys = tmp_path / "run.keys"
    RunKeys(b"r" * 32, b"b" * 32).write(keys)
    os.chmod(keys, mode)
    with pytest.raises(UserError, match="too open"):
        RunKeys.read(keys)


def test_missing_and_binary_files(tmp_path):
    with pytest.raises(UserError, match="no such file"):
        read_key_file(tmp_path / "nope")
    with pytest.raises(UserError, match="no such file"):
        RunKeys.read(tmp_path / "nope")
    p = tmp_path / "bin"
    p.write_bytes(b"\xff\xfe" + os.urandom(40))
    os.chmod(p, 0o600)
    with pytest.raises(UserError, match="not text"):
        read_key_file(p)
    with pytest.raises(UserError, match="not a run keys file"):
        RunKeys.read(p)


def test_written_files_are_owner_only_whatever_the_umask(tmp_path):
    old = os.umask(0)
    try:
        keys = RunKeys.generate(None, {})
        p = keys.write(tmp_path / "run.keys")
        k = write_key_file(tmp_path / "bpsec.key", keys.bpsec)
    finally:
        os.umask(old)
    assert stat.S_IMODE(p.stat().st_mode) == 0o600 and stat.S_IMODE(k.stat().st_mode) == 0o600
    assert RunKeys.read(p) == keys
    assert read_key_file(k) == keys.bpsec
    # written again: a new file (a file planted there before is replaced, not reused)
    p.chmod(0o644)
    keys.write(p)
    assert stat.S_IMODE(p.stat().st_mode) == 0o600


def test_agent_needs_a_key_from_outside():
    from sat_node.dtn.agent import AgentConfig

    with pytest.raises(TypeError):
        AgentConfig()  # no default key in the source
    with pytest.raises(ValueError, match="length >= 16"):
        AgentConfig(key=b"short")


def test_bundle_forged_with_the_old_source_key_is_rejected():
    from orbit_clock.contact_plan import Contact, ContactPlan, node_number
    from sat_node.dtn.agent import AgentConfig, BundleAgent
    from sat_node.dtn.bpsec import add_bib
    from sat_node.dtn.bpv7 import Bundle, encode_bundle, ipn
    from sat_node.dtn.routing_blocks import set_routing

    plan = ContactPlan([Contact(0.0, 1000.0, "sat_11", "sat_12", 1000.0, 0.0),
                        Contact(0.0, 1000.0, "sat_12", "sat_11", 1000.0, 0.0)])
    cfg = AgentConfig(key=TEST_BPSEC_KEY)
    events = []
    rx = BundleAgent("sat_12", plan, cfg, on_event=events.append)

    def bundle(key: bytes, seq: int) -> bytes:
        b = Bundle(dest=ipn(node_number("sat_12"), 1), src=ipn(node_number("sat_11"), 1),
                   creation_ms=cfg.epoch_dtn_ms + 1000, seq=seq, lifetime_ms=900_000, payload=b"forged")
        to = node_number("sat_12")
        set_routing(b, [(to, 1, 900_000)], {to: (to,)})
        b.hop_count = (cfg.hop_limit, 0)
        add_bib(b, key, ipn(node_number("sat_11"), 0))
        return encode_bundle(b)

    assert rx.receive(bundle(OLD_SOURCE_KEY, 1), "sat_11", 2_000_000_000) == "dropped.integrity"
    assert [(e.kind, e.reason) for e in events] == [("dropped", "integrity")]
    assert rx.receive(bundle(TEST_BPSEC_KEY, 2), "sat_11", 2_000_000_000) == "delivered"
