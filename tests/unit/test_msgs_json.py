"""msgs_json: golden encodings, validation, topics, fuzzing (never any exception but MessageError)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import msgspec
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import msgs_json as M
from msgs_json import schemas as S
from msgs_json import topics as T
from msgs_json.codec import MessageError, decode, decode_as, encode
from msgs_json.envelope import Envelope
from msgs_json.wire import decode_envelope, encode_envelope

GOLDEN = Path(M.__file__).parent / "golden"

# the topic each type travels on (one example per type)
TOPIC_OF = {
    S.SimStep: T.SIM_STEP,
    S.SimAck: T.SIM_ACK,
    S.ContactWindow: T.CONTACTS,
    S.AcsCommand: T.acs_command_topic("sat_11"),
    S.AcsState: T.acs_state_topic("sat_11"),
    S.Schedule: T.schedule_topic("sat_23"),
    S.Observation: T.observations_topic("sat_23"),
    S.GroundDownlink: T.GROUND_DOWNLINK,
    S.GroundUplink: T.GROUND_UPLINK,
    S.BundleCreated: T.dtn_events_topic("sat_11"),
    S.BundleForwarded: T.dtn_events_topic("sat_11"),
    S.BundleDelivered: T.dtn_events_topic("sat_12"),
    S.BundleDropped: T.dtn_events_topic("sat_12"),
    S.CopyDiscarded: T.dtn_events_topic("sat_18"),
    S.DtnCounters: T.dtn_counters_topic("sat_11"),
    S.TransmissionFailed: T.dtn_status_topic("sat_11"),
    S.CopiesOverheard: T.dtn_overheard_topic("sat_11"),
    S.ModeChange: T.ops_mode_topic("sat_11"),
    S.CommandEvent: T.ops_command_topic("sat_11"),
    S.GroundCommand: T.GROUND_COMMANDS,
    S.CommandAck: T.GROUND_ACKS,
    S.GroundBundle: T.GROUND_BUNDLES,
    S.Housekeeping: T.ops_hk_topic("sat_11"),
}
TYPES = list(S.MESSAGE_TYPES)


def golden(tp) -> bytes:
    return (GOLDEN / f"{tp.__name__}.json").read_bytes()


def test_one_golden_per_type_and_no_strays():
    assert set(TOPIC_OF) == set(TYPES)
    assert {p.stem for p in GOLDEN.glob("*.json")} == {t.__name__ for t in TYPES}


@pytest.mark.parametrize("tp", TYPES, ids=lambda t: t.__name__)
def test_golden_decodes_and_reencodes_to_same_bytes(tp):
    raw = golden(tp)
    msg = decode(TOPIC_OF[tp], raw)
    assert type(msg) is tp
    assert encode(msg).encode() == raw
    # and through the wire envelope as both engines carry it
    env = Envelope(7, "sat_11", 3, TOPIC_OF[tp], raw.decode())
    back = decode_envelope(encode_envelope(env), TOPIC_OF[tp])
    assert back == env and decode(back.topic, back.data) == msg


def _mutate(tp, **changes) -> str:
    d = json.loads(golden(tp))
    for k, v in changes.items():
        if v is _DEL:
            del d[k]
        else:
            d[k] = v
    return json.dumps(d)


_DEL = object()


@pytest.mark.parametrize(
    "tp,changes,expect",
    [
        (S.SimStep, {"v": 2}, "schema version 2"),
        (S.SimStep, {"extra": 1}, "unknown field `extra`"),
        (S.SimStep, {"t_ns": -5}, r"\$\.t_ns"),
        (S.SimStep, {"k": _DEL}, "missing required field `k`"),
        (S.SimAck, {"sent": {"not a topic": 1}}, r"\$\.sent"),
        (S.SimAck, {"participant": ""}, r"\$\.participant"),
        (S.ContactWindow, {"end_ns": 0}, "end_ns must be after start_ns"),
        (S.ContactWindow, {"dst": "sat_11"}, "src and dst must differ"),
        (S.ContactWindow, {"rate_bps": 0}, r"\$\.rate_bps"),
        (S.ContactWindow, {"event": "ajar"}, r"\$\.event"),
        (S.AcsCommand, {"sat": "Sat11"}, r"\$\.sat"),
        (S.AcsCommand, {"target_ecef_km": [1, 2]}, r"\$\.target_ecef_km"),
        (S.AcsState, {"slew_end_ns": None}, "slewing state needs slew_end_ns"),
        (S.Schedule, {"items": [{"gp": 1, "t_ns": 6, "value": 1}, {"gp": 2, "t_ns": 5, "value": 1}]}, "increasing t_ns"),
        (S.Schedule, {"items": [{"gp": 2, "t_ns": 5, "value": 1}, {"gp": 2, "t_ns": 5, "value": 1}]}, "increasing gp"),
        (S.Schedule, {"items": [{"gp": 1, "t_ns": 5, "value": -1}]}, r"\$\.items\[0\]\.value"),
        (S.Schedule, {"cutoff_ns": 10**16}, "cutoff_ns must not be after planned_ns"),
        (S.Observation, {"gp": "12"}, r"\$\.gp"),
        (S.GroundDownlink, {"sat": "sat_24"}, "must belong to sat"),
        (S.GroundDownlink, {"station": "svalbard"}, r"\$\.station"),
        (S.GroundUplink, {"sat": "sat_24"}, "schedule.sat must equal sat"),
        (S.BundleCreated, {"priority": 16}, r"\$\.priority"),
        (S.BundleCreated, {"event": "teleported"}, "Invalid value 'teleported'"),
        (S.BundleDelivered, {"sat": "sat_13"}, "sat must be its dst"),
        (S.BundleDropped, {"reason": "boredom"}, r"\$\.reason"),
        (S.BundleForwarded, {"t_ns": 0}, "before creation_ns"),
    ],
)
def test_invalid_payloads_are_rejected_naming_topic_and_field(tp, changes, expect):
    topic = TOPIC_OF[tp]
    with pytest.raises(MessageError, match=expect) as ei:
        decode(topic, _mutate(tp, **changes))
    msg = str(ei.value)
    assert msg.startswith(topic + ": ") and "\n" not in msg


def test_non_json_and_wrong_topics():
    for bad in (b"", b"{", b"\xff\xfe", "[]", "null", 3, None, b"{}" * 3):
        with pytest.raises(MessageError):
            decode(T.SIM_STEP, bad)  # type: ignore[arg-type]
    with pytest.raises(MessageError, match="raw bytes"):
        decode(T.dtn_out_topic("sat_11"), "{}")
    with pytest.raises(MessageError, match="unknown topic"):
        decode("/sat_11/nonsense", "{}")


def test_constructing_an_invalid_message_fails_at_the_producer():
    with pytest.raises(ValueError, match="end_ns"):
        S.ContactWindow(event="open", kind="isl", src="sat_11", dst="sat_12", start_ns=5, end_ns=5,
                        rate_bps=1000.0, range_light_s=0.0)


def test_topics_map_to_schemas():
    assert T.schema_for(T.schedule_topic("sat_38")) is S.Schedule
    assert T.schema_for(T.dtn_events_topic("sat_11")) is S.BundleEvent
    assert T.is_bytes_topic(T.dtn_in_topic("sat_11")) and T.is_bytes_topic(T.dtn_out_topic("sat_21"))
    assert not T.is_bytes_topic(T.CONTACTS) and T.schema_for(T.dtn_in_topic("sat_11")) is None
    assert T.schema_for("/clock") is None and not T.is_known_topic("/sat_11/fix")
    assert T.schema_for("/sat_1/schedule") is None and T.schema_for("/sat_11/schedule/x") is None
    assert T.sat_of_topic("/sat_23/observations") == "sat_23" and T.sat_of_topic("/ground/uplink") is None
    assert T.fix_topic("sat_12") == "/sat_12/fix"
    # per-satellite topics moved by a namespace push or remap keep their schema
    assert T.design_topic("/fleet/a/sat_11/schedule") == "/sat_11/schedule"
    assert T.schema_for("/fleet/a/sat_11/schedule") is S.Schedule
    assert T.is_bytes_topic("/moved/sat_12/dtn/out") and T.sat_of_topic("/moved/sat_12/dtn/out") == "sat_12"
    assert T.design_topic("/fleet/orbit/contacts") == "/fleet/orbit/contacts"
    assert T.schema_for("/fleet/sat_11/fix") is None and T.schema_for("/x/sat_1/schedule") is None
    assert T.design_topic("/sat_11/sat_12/schedule") == "/sat_12/schedule"
    assert T.schema_for("/fleet/sat_0001_0012/schedule") is S.Schedule  # names beyond 9 x 9 (msgs_json/names.py)
    assert T.sat_of_topic("/fleet/sat_0001_0012/dtn/in") == "sat_0001_0012"
    for bad in ("sat_1", "sat_01", "Sat11", "", None):
        with pytest.raises(ValueError):
            T.schedule_topic(bad)  # type: ignore[arg-type]


# --- fuzzing -----------------------------------------------------------------------------------------
json_values = st.recursive(
    st.none() | st.booleans() | st.integers(min_value=-(2**70), max_value=2**70)
    | st.floats(allow_nan=False) | st.text(max_size=20),
    lambda ch: st.lists(ch, max_size=4) | st.dictionaries(st.text(max_size=12), ch, max_size=4),
    max_leaves=12,
)
ALL_TOPICS = sorted(set(TOPIC_OF.values()))
_FUZZ = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def _decode_ok_or_message_error(topic, payload):
    try:
        out = decode(topic, payload)
    except MessageError as exc:
        assert "\n" not in str(exc) and str(exc).startswith(topic)
        return None
    assert isinstance(out, msgspec.Struct)
    return out


@_FUZZ
@given(topic=st.sampled_from(ALL_TOPICS), payload=st.binary(max_size=200))
def test_fuzz_random_bytes(topic, payload):
    _decode_ok_or_message_error(topic, payload)


@_FUZZ
@given(topic=st.sampled_from(ALL_TOPICS), value=json_values)
def test_fuzz_random_json(topic, value):
    _decode_ok_or_message_error(topic, json.dumps(value))


@_FUZZ
@given(tp=st.sampled_from(TYPES), data=st.data())
def test_fuzz_mutated_goldens(tp, data):
    d = json.loads(golden(tp))
    key = data.draw(st.sampled_from(sorted(d)))
    d[key] = data.draw(json_values)
    out = _decode_ok_or_message_error(TOPIC_OF[tp], json.dumps(d))
    if out is not None:  # accepted: must re-encode to something that decodes to the same message
        assert decode(TOPIC_OF[tp], encode(out)) == out


def test_decode_as_names_where():
    with pytest.raises(MessageError, match=r"^here: \$\.k: "):
        decode_as(S.SimStep, '{"k": -1, "t_ns": 0}', "here")


def test_pure_modules_import_no_rclpy():
    code = (
        "import sys, msgs_json, bringup.engine.local, bringup.recording.bag, bringup.recording.viz_messages;"
        "print('rclpy' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=False)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().splitlines()[-1] == "False"
