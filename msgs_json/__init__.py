"""msgs_json: the message contracts (docs/design.md section 4).

Front door: schemas (one msgspec Struct per message type), topic names and their schemas,
validating encode/decode, and the lockstep envelope and its wire form.
"""

from msgs_json.codec import MessageError, decode, decode_as, encode, encode_bytes
from msgs_json.envelope import Emit, Envelope, Participant, StepResult
from msgs_json.schemas import (
    DROP_REASONS,
    MESSAGE_TYPES,
    SCHEMA_VERSION,
    AcsCommand,
    AcsState,
    BundleCreated,
    BundleDelivered,
    BundleDropped,
    BundleEvent,
    BundleForwarded,
    ContactWindow,
    CopyDiscarded,
    GroundDownlink,
    GroundUplink,
    Observation,
    Schedule,
    ScheduleItem,
    SimAck,
    SimStep,
    TransmissionFailed,
)
from msgs_json.topics import (
    CLOCK,
    CONTACTS,
    GROUND_DOWNLINK,
    GROUND_UPLINK,
    SIM_ACK,
    SIM_STEP,
    VIZ_MARKERS,
    acs_command_topic,
    acs_state_topic,
    dtn_events_topic,
    dtn_in_topic,
    dtn_out_topic,
    dtn_status_topic,
    fix_topic,
    is_bytes_topic,
    is_known_topic,
    observations_topic,
    sat_of_topic,
    schedule_topic,
    schema_for,
)
from msgs_json.wire import WireError, decode_envelope, encode_envelope

__all__ = [
    "CLOCK", "CONTACTS", "DROP_REASONS", "GROUND_DOWNLINK", "GROUND_UPLINK", "MESSAGE_TYPES",
    "SCHEMA_VERSION", "SIM_ACK", "SIM_STEP", "VIZ_MARKERS",
    "AcsCommand", "AcsState", "BundleCreated", "BundleDelivered", "BundleDropped", "BundleEvent",
    "BundleForwarded", "ContactWindow", "CopyDiscarded", "Emit", "Envelope", "GroundDownlink",
    "GroundUplink", "MessageError", "Observation", "Participant", "Schedule", "ScheduleItem", "SimAck",
    "SimStep", "StepResult", "TransmissionFailed", "WireError",
    "acs_command_topic", "acs_state_topic", "decode", "decode_as", "decode_envelope", "dtn_events_topic",
    "dtn_in_topic", "dtn_out_topic", "dtn_status_topic", "encode", "encode_bytes", "encode_envelope", "fix_topic",
    "is_bytes_topic", "is_known_topic", "observations_topic", "sat_of_topic", "schedule_topic",
    "schema_for",
]
