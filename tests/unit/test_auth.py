"""The run key's MACs (msgs_json/auth.py) and the rejection counter (bringup/engine/lockstep.py).

Oracles: by construction - every single-byte change of an authenticated wire text (a field, the
payload, the tag) makes it fail to verify; a wrong key, another run's envelope, another topic and a
missing tag fail with their reasons; random envelopes (text with escapes, quotes, non-ASCII and
surrogate-free Unicode; random bytes) sealed by one RunAuth verify under another built from the
same key. The MAC inputs are unambiguous: envelopes that differ only in where a field boundary
falls get different MACs.
"""

from __future__ import annotations

import json
import random

import pytest

from bringup.engine.lockstep import (
    ACK_TOPIC,
    STEP_TOPIC,
    AckMsg,
    Rejections,
    StepMsg,
    decode_ack,
    decode_step,
    encode_msg,
)
from msgs_json.auth import AuthError, RunAuth
from msgs_json.envelope import Envelope
from msgs_json.wire import WireError, decode_envelope_mac, encode_envelope

KEY = bytes(range(32))
OTHER_RUN = bytes(range(1, 33))


def _sealed(auth: RunAuth, env: Envelope) -> str:
    return encode_envelope(env, auth.mac(env))


def _check(auth: RunAuth, text: str, topic: str) -> Envelope:
    env, mac = decode_envelope_mac(text, topic)
    auth.verify(env, mac)
    return env


def _random_env(rng: random.Random, seq: int) -> Envelope:
    topic = rng.choice(["/sat_11/observations", "/sat_12/dtn/in", "/toy/ping"])
    if topic.endswith("/dtn/in"):
        data: str | bytes = rng.randbytes(rng.randint(0, 300))
    else:
        alphabet = 'ab"\\/\n\t{}é中😀\x00 '
        data = "".join(rng.choice(alphabet) for _ in range(rng.randint(0, 80)))
    return Envelope(rng.randrange(10**15), rng.choice(["sat_11", "router", "ground", "é"]), seq, topic, data)


def test_round_trip_of_random_envelopes():
    rng = random.Random(3)
    a, b = RunAuth(KEY), RunAuth(KEY)
    for i in range(500):
        env = _random_env(rng, i)
        assert _check(b, _sealed(a, env), env.topic) == env


def test_every_flipped_byte_is_rejected():
    auth = RunAuth(KEY)
    for env in (Envelope(12_300_000_000, "sat_11", 7, "/sat_11/observations", '{"v":1,"gp":42}'),
                Envelope(5, "router", 0, "/sat_12/dtn/in", bytes(range(40)))):
        text = _sealed(auth, env)
        assert _check(auth, text, env.topic) == env
        rejected = 0
        for i in range(len(text)):
            for new in {"0", "7", "a", "Z"} - {text[i]}:
                forged = text[:i] + new + text[i + 1:]
                try:
                    got = _check(auth, forged, env.topic)
                except (WireError, AuthError):
                    rejected += 1
                    continue
                # a change the JSON parser ignores can only leave the same envelope and tag
                same_tag = decode_envelope_mac(forged, env.topic)[1] == decode_envelope_mac(text, env.topic)[1]
                assert got == env and same_tag
        assert rejected > 3 * len(text) - 50


def test_wrong_key_other_run_other_topic_missing_tag():
    env = Envelope(1_000, "sat_11", 3, "/sat_11/observations", '{"v":1}')
    auth = RunAuth(KEY)
    with pytest.raises(AuthError) as e:
        _check(auth, _sealed(RunAuth(OTHER_RUN), env), env.topic)  # another run's envelope (replayed)
    assert e.value.reason == "bad_mac"
    with pytest.raises(AuthError) as e:
        _check(auth, _sealed(auth, env), "/sat_12/observations")  # moved to another topic
    assert e.value.reason == "bad_mac"
    with pytest.raises(AuthError) as e:
        _check(auth, encode_envelope(env), env.topic)
    assert e.value.reason == "unauthenticated"
    with pytest.raises(AuthError) as e:
        _check(auth, encode_envelope(env, "é" * 32), env.topic)
    assert e.value.reason == "bad_mac"


def test_mac_inputs_are_unambiguous():
    auth = RunAuth(KEY)
    a = Envelope(12, "sat_1", 34, "/t", "x")
    variants = [a._replace(t_ns=1, seq=234), a._replace(source="sat_13", seq=4), a._replace(topic="/t5"),
                a._replace(data=b"x"), a._replace(source="sat_", data="1x"), a._replace(t_ns=123, seq=4)]
    macs = {auth.mac(v) for v in [a, *variants]}
    assert len(macs) == len(variants) + 1


def test_lockstep_texts_sealed_and_opened():
    auth = RunAuth(KEY)
    step = StepMsg(k=3, t_ns=30, sent={"/a": 2}, seq_end={"x": 5})
    sealed = auth.seal(STEP_TOPIC, encode_msg(step))
    assert json.loads(sealed)["mac"] and decode_step(auth.open(STEP_TOPIC, sealed)) == step
    ack = AckMsg(participant="sat_11", k=3, t_ns=30, error="boom", rejected={"/x": {"bad_mac": 2}})
    assert decode_ack(auth.open(ACK_TOPIC, auth.seal(ACK_TOPIC, encode_msg(ack)))) == ack
    for forged, reason in [
        (encode_msg(StepMsg(k=0, t_ns=0, stop=True)), "unauthenticated"),  # the forged stop of the issue
        (RunAuth(OTHER_RUN).seal(STEP_TOPIC, encode_msg(step)), "bad_mac"),
        (sealed.replace('"k":3', '"k":4'), "bad_mac"),
        (auth.seal(ACK_TOPIC, encode_msg(step)), "bad_mac"),  # an ack's MAC on a step
        (sealed[:-3] + 'X"}', "bad_mac"),
        ("", "unauthenticated"), ('{"mac":"' + "0" * 32 + '"}', "unauthenticated"),
        ("not json at all" + "x" * 60, "unauthenticated"),
    ]:
        with pytest.raises(AuthError) as e:
            auth.open(STEP_TOPIC, forged)
        assert e.value.reason == reason, forged
    with pytest.raises(AuthError) as e:
        auth.open(STEP_TOPIC, b"\xff\xfe" * 40)
    assert e.value.reason == "malformed"


def test_rejections_are_counted_and_their_log_rate_limited():
    now = [0.0]
    r = Rejections(period_s=5.0, clock=lambda: now[0])
    lines = []
    for i in range(1000):
        now[0] = i * 0.01  # 1000 rejections in 10 s
        line = r.add("/sim/ack", "unauthenticated", f"#{i}")
        if line:
            lines.append(line)
    r.add("/sim/step", "bad_mac", "x")
    assert r.counts() == {"/sim/ack": {"unauthenticated": 1000}, "/sim/step": {"bad_mac": 1}}
    assert r.total() == 1001
    assert len(lines) == 2 and "#0" in lines[0] and "1000 so far" not in lines[0]
    assert "500 on /sim/ack in the last 5 s, 501 so far" in lines[1]
