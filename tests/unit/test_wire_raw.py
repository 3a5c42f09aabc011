"""The ROS engine's raw path: std_msgs/String CDR written and read by hand (msgs_json/wire.py
string_cdr / string_from_cdr), the recorded form of a received envelope cut from its text
(without_mac, bringup/engine/lockstep.py Gate.envelope_wire) instead of encoded again, and bad CDR
rejected and counted (Gate.cdr_text). Oracles: encode_envelope itself (the form the bag held
before), the rosbags serializer (tests/unit/test_recording.py checks string_cdr against it byte for
byte), and the Gate's own MAC check."""

import random

from bringup.engine.lockstep import Gate
from msgs_json.envelope import Envelope
from msgs_json.wire import decode_envelope, encode_envelope, string_cdr, string_from_cdr, without_mac

KEY = b"k" * 32


def _envelopes(n: int, seed: int = 7):
    rng = random.Random(seed)
    alphabet = 'ab"\\\n\t\u00e9\u2603{}:,'
    for i in range(n):
        data = (bytes(rng.randrange(256) for _ in range(rng.randrange(0, 40))) if rng.random() < 0.5
                else "".join(rng.choice(alphabet) for _ in range(rng.randrange(0, 30))))
        yield Envelope(rng.randrange(0, 10**15), rng.choice(["sat_11", "router", "gs\u00e9"]), i,
                       rng.choice(["/sat_11/dtn/in", "/obs"]), data)


def test_without_mac_gives_the_recorded_form():
    gate = Gate(KEY, lambda _line: None)
    for env in _envelopes(300):
        text = gate.wire(env)
        mac = gate.auth.mac(env)
        assert without_mac(text, mac) == encode_envelope(env)
        got_env, wire = gate.envelope_wire(text, env.topic)
        assert got_env == env and wire == encode_envelope(env)
        assert decode_envelope(wire, env.topic) == env


def test_without_mac_refuses_other_tails():
    env = next(_envelopes(1))
    assert without_mac(encode_envelope(env), None) is None
    assert without_mac(encode_envelope(env, "ab" * 32), "cd" * 32) is None
    assert without_mac(',"mac":"x"}', "x") is None  # nothing before the field


def test_envelope_wire_rejects_what_does_not_verify():
    gate = Gate(KEY, lambda _line: None)
    env = next(_envelopes(1))
    forged = Gate(b"x" * 32, lambda _line: None).wire(env)
    assert gate.envelope_wire(forged, env.topic) is None
    assert gate.envelope_wire(encode_envelope(env), env.topic) is None  # no MAC
    assert gate.envelope_wire("{not json", env.topic) is None
    counts = gate.rejections.counts()
    assert sum(n for by in counts.values() for n in by.values()) == 3


def test_string_cdr_round_trip_and_bad_cdr_counted():
    for text in ["", "a", '{"k":1}', "\u00e9\u2603" * 50]:
        assert string_from_cdr(string_cdr(text)) == text
    gate = Gate(KEY, lambda _line: None)
    bad = [b"", b"\x00\x01\x00\x00", b"\x00\x01\x00\x00\xff\x00\x00\x00ab\x00", b"\x00\x01\x00\x00\x03\x00\x00\x00\xff\xfe\x00",
           b"\x07\x01\x00\x00\x02\x00\x00\x00a\x00"]
    for raw in bad:
        assert gate.cdr_text("/t", raw) is None
    assert gate.rejections.counts()["/t"]["malformed"] == len(bad)
    assert gate.cdr_text("/t", string_cdr("ok")) == "ok"
