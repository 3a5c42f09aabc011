"""Live operator requests (ground_station/operator_requests.py, bringup/cli/operator.py) against the
ground gateway (ground_station/commander.py) stepped by the test.

Oracles: the request's tag recomputed with Python's hmac (RFC 2104); a request under another run's
key or not the user's own file is refused and counted; the gateway's uplinked command verifies under
the addressed satellite's command key (and no other) and carries the request's target and deadline;
the CLI's one-line errors.
"""

from __future__ import annotations

import hashlib
import hmac
import json
import os
import threading
from pathlib import Path

import msgspec
import pytest

from bringup.engine.keys import RunKeys
from bringup.errors import UserError
from ground_station.operator_requests import (
    OPERATOR_DIR,
    RequestInbox,
    encode_request,
    operator_key,
    parse_request,
)
from msgs_json import codec
from sat_node.operations.commands import CommandRejected, parse_command, satellite_command_key

_NS = 1_000_000_000
GROUND_KEY = bytes(range(1, 33))
STATIONS = [{"name": "svalbard", "lat_deg": 78.2298, "lon_deg": 15.4078, "alt_m": 500.0},
            {"name": "troll", "lat_deg": -72.0117, "lon_deg": 2.535, "alt_m": 1270.0}]
DALLAS = {"request": "task", "sat": "sat_12", "lat_deg": 32.7767, "lon_deg": -96.797, "priority": 1,
          "by": "2000-01-01T12:24:28Z"}


def test_request_tag_is_hmac_sha256_under_the_operator_key():
    key = operator_key(b"r" * 32)
    assert key == hmac.new(b"r" * 32, b"constellation operator request v1", hashlib.sha256).digest()
    blob = encode_request(DALLAS, key)
    body, tag = blob.rstrip(b"\n").split(b"\n")
    assert tag == hmac.new(key, body, hashlib.sha256).hexdigest().encode()
    assert parse_request(blob, key) == DALLAS
    with pytest.raises(ValueError, match="^forged"):
        parse_request(encode_request(DALLAS, operator_key(b"o" * 32)), key)
    with pytest.raises(ValueError, match="^malformed"):
        parse_request(encode_request({"request": "launch", "sat": "sat_12"}, key), key)


def test_inbox_reads_each_request_once_and_refuses_untrusted_files(tmp_path):
    key = operator_key(b"r" * 32)
    (tmp_path / "a.req").write_bytes(encode_request(DALLAS, key))
    os.chmod(tmp_path / "a.req", 0o600)
    (tmp_path / "b.req").write_bytes(encode_request(DALLAS, key))
    os.chmod(tmp_path / "b.req", 0o644)  # readable by others: not a file only its user made
    (tmp_path / "c.req").write_bytes(encode_request(DALLAS, operator_key(b"x" * 32)))
    os.chmod(tmp_path / "c.req", 0o600)
    box = RequestInbox(tmp_path, key)
    got = box.poll()
    assert [(n, r is not None, e.split(":")[0]) for n, r, e in got] == [
        ("a.req", True, ""), ("b.req", False, "untrusted"), ("c.req", False, "forged")]
    assert box.refused == {"untrusted": 1, "forged": 1}
    assert box.poll() == []  # read once
    box.reply("a.req", {"ok": True})
    assert json.loads((tmp_path / "a.reply").read_text()) == {"ok": True}
    assert (tmp_path / "a.reply").stat().st_mode & 0o777 == 0o600


@pytest.fixture(scope="module")
def world():
    from bringup.scenario.config import _validate, load_scenario
    from bringup.scenario.world import World

    raw = msgspec.to_builtins(load_scenario("paper").with_overrides(sats=12, hours=0.5))
    raw.pop("source_path", None)
    raw["ground"]["stations"] = STATIONS
    return World.build(_validate(raw, "<test>"))


def _run_folder(tmp_path: Path) -> tuple[Path, RunKeys]:
    out = tmp_path / "run"
    (out / OPERATOR_DIR).mkdir(parents=True, mode=0o700)
    (out / "run_spec.json").write_text("{}")
    keys = RunKeys.generate(env={})
    keys.write(out / "run.keys")
    return out, keys


def _ask(out: Path, req: dict, answers: list) -> threading.Thread:
    from bringup.cli.operator import send_request

    def go():
        try:
            answers.append(send_request(out, req, wait_s=30))
        except UserError as exc:
            answers.append(exc)

    th = threading.Thread(target=go)
    th.start()
    return th


def _step_until_answered(g, th, t_ns: int) -> int:
    emits = []
    while th.is_alive():
        emits += g.step(t_ns, []).emits
        th.join(0.3)
    return emits


def test_the_cli_tasks_a_gateway_that_steps(world, tmp_path):
    from bringup.scenario.participants import make_participant

    out, keys = _run_folder(tmp_path)
    g = make_participant(world, "commander", "distributed", store_dir=None, router_kw=None, bpsec_key=b"b" * 32,
                         command_key=GROUND_KEY, live=(out / OPERATOR_DIR, keys.run))
    g.start(0)
    answers: list = []
    emits = _step_until_answered(g, _ask(out, DALLAS, answers), 100 * _NS)
    assert answers[0]["ok"] and answers[0]["commands"] == ["op1"] and answers[0]["issued_s"] == 100.0
    up = codec.decode(emits[0].topic, emits[0].data)
    assert up.relay == "sat_12" and up.t_ns == 100 * _NS  # sat_12 is in contact with Svalbard then
    cmd = parse_command(up.payload.encode(), satellite_command_key(GROUND_KEY, "sat_12"))
    assert (cmd.id, cmd.kind, cmd.issued_ns, cmd.args["priority"]) == ("op1", "task", 100 * _NS, 1)
    assert cmd.args["by_ns"] == 1500 * _NS and cmd.args["lat_deg"] == 32.7767
    with pytest.raises(CommandRejected, match="forged"):
        parse_command(up.payload.encode(), satellite_command_key(GROUND_KEY, "sat_11"))
    # refusals come back as one line: an unknown satellite, a target off every region, a past deadline
    for bad, why in (({"sat": "sat_99"}, "not a satellite"), ({"lat_deg": 0.0, "lon_deg": 0.0}, "km from the nearest"),
                     ({"by": "2000-01-01T12:00:00Z"}, "not after the issue time")):
        answers = []
        _step_until_answered(g, _ask(out, DALLAS | bad, answers), 200 * _NS)
        assert isinstance(answers[0], UserError) and why in str(answers[0]) and "\n" not in str(answers[0])
    answers = []
    _step_until_answered(g, _ask(out, {"request": "mode", "sat": "sat_33", "mode": "safe"}, answers), 210 * _NS)
    assert answers[0]["commands"] == ["op2"]
    # a parameter, live: the uplinked command verifies under sat_33's key and carries name and value
    answers = []
    emits = _step_until_answered(g, _ask(out, {"request": "set", "sat": "sat_33",
                                             "name": "operations.store_max_bundles", "value": 500}, answers), 220 * _NS)
    assert answers[0]["commands"] == ["op3"]
    cmds = [parse_command(codec.decode(e.topic, e.data).payload.encode(), satellite_command_key(GROUND_KEY, "sat_33"))
            for e in emits]
    assert [(c.id, c.kind, c.args) for c in cmds] == [("op3", "set", {"name": "operations.store_max_bundles",
                                                                      "value": 500})]
    for bad, why in (({"name": "scheduler.dp_step_s"}, "not settable"), ({"value": 0}, "is not an integer in [1, "),
                     ({"value": 2.5}, "is not an integer")):
        answers = []
        req = {"request": "set", "sat": "sat_33", "name": "operations.store_max_bundles", "value": 500} | bad
        _step_until_answered(g, _ask(out, req, answers), 230 * _NS)
        assert isinstance(answers[0], UserError) and why in str(answers[0]) and "\n" not in str(answers[0])
    assert g.live.refused == {"refused": 6}
    assert json.loads((out / OPERATOR_DIR / "now.json").read_text()) == {"t_s": 230.0}  # the run's time


def test_cli_errors_are_one_line(tmp_path, capsys):
    from bringup.cli.main import main

    out = tmp_path / "r"
    out.mkdir()
    assert main(["command", "--out", str(out), "sat_12", "mode", "safe"]) == 2
    assert "not the folder of a ROS run" in capsys.readouterr().err
    (out / "run_spec.json").write_text("{}")
    assert main(["task", "--out", str(out), "--lat", "1", "--lon", "2", "--by", "2000-01-01T12:00:00Z"]) == 2
    assert "does not take live commands" in capsys.readouterr().err
    (out / OPERATOR_DIR).mkdir()
    assert main(["command", "--out", str(out), "sat_12", "mode", "safe"]) == 2
    err = capsys.readouterr().err
    assert "is the run over" in err and len(err.strip().splitlines()) == 1
    # the command's own arguments are checked before anything is written
    for argv, why in ((["mode", "off"], "expected safe or nominal"), (["set", "operations.nope", "1"], "not settable"),
                      (["set", "operations.store_max_bundles", "x"], "is not an integer"),
                      (["set", "operations.pointing_error_max_deg", "500"], "outside [0.0, 180.0]"),
                      (["set", "operations.store_max_bundles"], "expected NAME VALUE")):
        assert main(["command", "--out", str(out), "sat_12", *argv]) == 2
        err = capsys.readouterr().err
        assert why in err and len(err.strip().splitlines()) == 1, err
    assert not list((out / OPERATOR_DIR).glob("*.req"))
