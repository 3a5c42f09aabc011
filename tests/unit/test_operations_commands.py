"""Operator commands (sat_node/operations/commands.py) and the ground gateway (ground_station/commander.py).

Oracles: the tag recomputed here with Python's hmac over the exact bytes (RFC 2104 HMAC-SHA256); a
flipped byte anywhere is ``forged``; the acceptance checks' reasons on hand-made commands; the
gateway's uplink slots against a brute-force scan of the world's ground plan.
"""

from __future__ import annotations

import hashlib
import hmac
import json

import msgspec
import pytest

from bringup.scenario.config import ScenarioError, _validate, load_scenario
from ground_station.commander import CommanderLogic, uplink_slot
from msgs_json import codec
from sat_node.operations.commands import (
    Command,
    CommandGuard,
    CommandRejected,
    encode_command,
    is_command,
    parse_command,
    satellite_command_key,
    target_of,
)
from tests.keys import TEST_BPSEC_KEY

GROUND_KEY = bytes(range(32))  # the ground's command key of these tests
KEY = satellite_command_key(GROUND_KEY, "sat_11")
_NS = 1_000_000_000


def _cmd(**kw) -> Command:
    base = dict(id="c1", seq=1, sat="sat_11", kind="mode", args={"mode": "safe"}, issued_ns=10, expires_ns=100)
    return Command(**(base | kw))


def test_tag_is_rfc2104_hmac_sha256_over_the_json_line():
    blob = encode_command(_cmd(), KEY)
    body, tag = blob.split(b"\n")
    assert tag == hmac.new(KEY, body, hashlib.sha256).hexdigest().encode()
    assert json.loads(body)["command"] == "c1" and is_command(blob) and target_of(blob) == "sat_11"
    assert parse_command(blob, KEY) == _cmd()
    assert KEY != TEST_BPSEC_KEY and len(KEY) == 32


def test_any_flipped_byte_is_forged_or_malformed():
    blob = encode_command(_cmd(), KEY)
    for i in range(len(blob)):
        bad = blob[:i] + bytes([blob[i] ^ 0x01]) + blob[i + 1:]
        with pytest.raises(CommandRejected) as ei:
            parse_command(bad, KEY)
        assert ei.value.reason in ("forged", "malformed")
    with pytest.raises(CommandRejected, match="forged"):
        parse_command(encode_command(_cmd(), b"another key"), KEY)


def test_guard_checks_and_counts():
    g = CommandGuard("sat_11", KEY)
    blob = encode_command(_cmd(), KEY)
    assert g.accept(blob, 50).id == "c1"
    cases = [(blob, 60, "replayed"), (encode_command(_cmd(id="c2", expires_ns=70), KEY), 70, "expired"),
             (encode_command(_cmd(id="c3", sat="sat_12"), KEY), 50, "not_for_me"),
             (encode_command(_cmd(id="c4"), b"x" * 32), 50, "forged"),
             (encode_command(_cmd(id="c5", kind="set", args={"name": "scheduler.dp_step_s", "value": 1.0}), KEY),
              50, "malformed"),
             (encode_command(_cmd(id="c6", kind="set", args={"name": "operations.store_max_bundles", "value": 1.5}),
                             KEY), 50, "malformed"),
             (b'{"command":"c7"}', 50, "malformed")]
    for blob_k, t, reason in cases:
        with pytest.raises(CommandRejected) as ei:
            g.accept(blob_k, t)
        assert ei.value.reason == reason, blob_k
    assert g.accepted == 1
    assert g.rejected == {"replayed": 1, "expired": 1, "not_for_me": 1, "forged": 1, "malformed": 3}
    ok = encode_command(_cmd(id="c8", kind="set", args={"name": "operations.store_max_bundles", "value": 5}), KEY)
    assert g.accept(ok, 50).args["value"] == 5


def _scenario(commands):
    raw = msgspec.to_builtins(load_scenario("paper").with_overrides(sats=12, hours=0.5))
    raw.pop("source_path", None)
    raw["commands"] = commands
    return _validate(raw, "<test>")


@pytest.mark.parametrize("cmd, key", [
    ({"sat": "sat_99", "kind": "mode", "mode": "safe", "at_s": 1.0}, "commands[0].sat"),
    ({"sat": "sat_11", "kind": "mode", "at_s": 1.0}, "commands[0].mode"),
    ({"sat": "sat_11", "kind": "task", "at_s": 1.0}, "commands[0].by"),
    ({"sat": "sat_11", "kind": "task", "at_s": 1.0, "by": "2000-01-01T12:30:00"}, "commands[0].by"),
    ({"sat": "sat_11", "kind": "task", "at_s": 4000.0, "by": "2000-01-01T12:30:00Z"}, "commands[0].by"),
    ({"sat": "sat_11", "kind": "task", "at_s": 1.0, "by": "2000-01-01T12:30:00Z", "priority": 4},
     "commands[0].priority"),
    ({"sat": "sat_11", "kind": "task", "at_s": 1.0, "by": "2000-01-01T12:30:00Z", "lat_deg": 91.0},
     "commands[0].lat_deg"),
    ({"sat": "all", "kind": "mode", "mode": "safe", "at_s": 1.0}, "commands[0].sat"),
    ({"sat": "sat_11", "kind": "set", "name": "scheduler.dp_step_s", "value": 1.0, "at_s": 1.0}, "commands[0].name"),
    ({"sat": "sat_11", "kind": "set", "name": "operations.pointing_error_max_deg", "value": 181.0, "at_s": 1.0},
     "commands[0].value"),
])
def test_bad_commands_are_one_line_naming_the_key(cmd, key):
    with pytest.raises(ScenarioError) as ei:
        _scenario([cmd])
    assert "\n" not in str(ei.value) and f"'{key}'" in str(ei.value)


def test_uplink_slots_against_a_brute_force_scan():
    from bringup.scenario.world import World

    world = World.build(_scenario([]))
    contacts = [c for c in world.ground_plan.contacts if c.dst.startswith("gs_")]
    assert contacts
    for t_s in (0.0, 100.0, 250.0, 700.0, 1500.0):
        t = int(t_s * _NS)
        got = uplink_slot(world.ground_plan.contacts, t, "sat_24")
        # brute force: every nanosecond-grid candidate is a contact start or t itself
        cands = sorted((max(t, round(c.start_s * _NS)), c.src != "sat_24", c.src, c.dst) for c in contacts
                       if max(t, round(c.start_s * _NS)) < round(c.end_s * _NS))
        assert got == ((cands[0][0], cands[0][2], cands[0][3]) if cands else None)


def test_gateway_signs_with_the_satellites_key_and_forges_when_told():
    from bringup.scenario.world import World

    world = World.build(_scenario([
        {"sat": "sat_33", "kind": "mode", "mode": "safe", "at_s": 50.0},
        {"sat": "sat_33", "kind": "mode", "mode": "nominal", "at_s": 60.0, "forge": True, "repeat": True}]))
    g = CommanderLogic(world, GROUND_KEY)
    key33 = satellite_command_key(GROUND_KEY, "sat_33")
    r = g.start(0)
    assert r.next_wakeup_ns == 50 * _NS and r.emits == []
    sent = g.step(50 * _NS, []).emits
    up = codec.decode(sent[0].topic, sent[0].data)
    assert parse_command(up.payload.encode(), key33).args == {"mode": "safe"}
    rest = g.step(60 * _NS, []).emits + g.finish(1800 * _NS)
    assert len(rest) == 2  # the forged one and its repeat
    for e in rest:
        with pytest.raises(CommandRejected, match="forged"):
            parse_command(codec.decode(e.topic, e.data).payload.encode(), key33)


def test_compose_refuses_scripted_commands(tmp_path):
    from bringup.deploy.compose import compose_project
    from bringup.errors import UserError
    from bringup.scenario.toml_text import to_toml

    raw = msgspec.to_builtins(_scenario([{"sat": "sat_33", "kind": "mode", "mode": "safe", "at_s": 50.0}]))
    raw.pop("source_path", None)
    (tmp_path / "c.toml").write_text(to_toml(raw))
    with pytest.raises(UserError, match=r"\[\[commands\]\] are not deployed by compose"):
        compose_project(scenario=str(tmp_path / "c.toml"))


def test_a_checkpoint_holds_no_command_key_and_a_restored_satellite_still_verifies():
    import pickle

    from bringup.scenario.world import World
    from sat_node.satellite import SatelliteLogic

    world = World.build(_scenario([{"sat": "sat_33", "kind": "mode", "mode": "safe", "at_s": 50.0}]))
    key = satellite_command_key(GROUND_KEY, "sat_33")
    s = SatelliteLogic(world, "sat_33", "distributed", bpsec_key=TEST_BPSEC_KEY, command_key=key)
    s.start(0)
    assert s.guard.accept(encode_command(_cmd(sat="sat_33"), key), 20).id == "c1"
    blob = s.snapshot()
    assert key not in blob and key not in pickle.dumps(s.guard)
    r = SatelliteLogic(world, "sat_33", "distributed", bpsec_key=TEST_BPSEC_KEY, command_key=key)
    r.restore(blob)
    with pytest.raises(CommandRejected, match="replayed"):  # what it had seen survives
        r.guard.accept(encode_command(_cmd(sat="sat_33"), key), 30)
    assert r.guard.accept(encode_command(_cmd(id="c2", sat="sat_33"), key), 30).id == "c2"


def test_only_the_satellites_own_key_verifies_its_commands():
    """The ground's key is its own: a command signed under the BPSec key every satellite holds, under
    the ground key itself, or under another satellite's key is forged and counted, and changes nothing."""
    g = CommandGuard("sat_11", KEY)
    for i, wrong in enumerate((TEST_BPSEC_KEY, GROUND_KEY, satellite_command_key(GROUND_KEY, "sat_12"),
                               satellite_command_key(TEST_BPSEC_KEY, "sat_11"))):
        with pytest.raises(CommandRejected, match="forged"):
            g.accept(encode_command(_cmd(id=f"w{i}"), wrong), 20)
    assert g.rejected == {"forged": 4} and g.accepted == 0 and g.seen == set()
    assert g.accept(encode_command(_cmd(id="ok"), KEY), 20).id == "ok"
    keys = {satellite_command_key(GROUND_KEY, f"sat_{i}") for i in range(11, 35)}
    assert len(keys) == 24 and KEY in keys and TEST_BPSEC_KEY not in keys
    with pytest.raises(ValueError, match="at least 16"):
        satellite_command_key(b"short", "sat_11")
