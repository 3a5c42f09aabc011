"""Topic names (docs/design.md section 4) and which payload each carries.

Names are contracts: build them only with these functions. A satellite's topics live under
``/<sat>/`` (``sat_PS`` or ``sat_PPPP_SSSS``: msgs_json/names.py). Every lockstep data topic carries a wire envelope (msgs_json/wire.py) on
std_msgs/msg/String; its payload is JSON of the schema ``schema_for(topic)`` names, or raw bytes
(BPv7 bundles) when ``is_bytes_topic(topic)``. Visualisation topics (``fix_topic(sat)``,
``VIZ_MARKERS``, the plotted series ``VIZ_VALUE`` and ``VIZ_IN_FLIGHT``, the TF tree ``TF`` and
``TF_STATIC``), ``/clock`` and the live ``DIAGNOSTICS`` are their own ROS types, not envelopes.

A per-satellite topic moved by the ROS engine's namespaces (``/fleet/sat_11/schedule``) still maps to
its schema (:func:`design_topic`), so a bag of such a run reads and reports like any other.

Oracle: tests/unit/test_msgs_json.py checks every builder's name maps back to the right schema, that
unknown names map to nothing, and that pushed names map like docs/design.md's.
"""

from __future__ import annotations

import re

from msgs_json import schemas as S
from msgs_json.names import SAT_NAME_PATTERN, is_sat_name
from msgs_json.schemas import SCHEMA_VERSION

__all__ = [
    "CLOCK",
    "CONTACTS",
    "DIAGNOSTICS",
    "GROUND_ACKS",
    "GROUND_COMMANDS",
    "GROUND_BUNDLES",
    "GROUND_DOWNLINK",
    "GROUND_UPLINK",
    "SCHEMA_VERSION",
    "SIM_ACK",
    "SIM_STEP",
    "TF",
    "TF_STATIC",
    "VIZ_IN_FLIGHT",
    "VIZ_MARKERS",
    "VIZ_VALUE",
    "acs_command_topic",
    "acs_state_topic",
    "dtn_events_topic",
    "dtn_counters_topic",
    "dtn_in_topic",
    "dtn_out_topic",
    "dtn_overheard_topic",
    "dtn_status_topic",
    "design_topic",
    "fix_topic",
    "is_bytes_topic",
    "is_known_topic",
    "is_sat_name",
    "observations_topic",
    "ops_command_topic",
    "ops_hk_topic",
    "ops_mode_topic",
    "sat_of_topic",
    "schedule_topic",
    "schema_for",
]

CLOCK = "/clock"
SIM_STEP = "/sim/step"
SIM_ACK = "/sim/ack"
CONTACTS = "/orbit/contacts"
GROUND_UPLINK = "/ground/uplink"
GROUND_DOWNLINK = "/ground/downlink"
GROUND_COMMANDS = "/ground/commands"
GROUND_ACKS = "/ground/acks"
GROUND_BUNDLES = "/ground/bundles"  # bundles the ground's agent uplinks (only with a ground gateway)
VIZ_MARKERS = "/viz/constellation"
VIZ_VALUE = "/viz/value"  # std_msgs/msg/Float64: the run's cumulative true value (Eq. 1) so far
VIZ_IN_FLIGHT = "/viz/bundles_in_flight"  # std_msgs/msg/UInt32: bundle copies the ISL medium holds
TF = "/tf"  # tf2_msgs/msg/TFMessage: earth -> each satellite's orbit frame
TF_STATIC = "/tf_static"  # tf2_msgs/msg/TFMessage: earth -> each ground station (ENU)
DIAGNOSTICS = "/diagnostics"  # diagnostic_msgs/msg/DiagnosticArray: live counters of ROS runs



def _sat(sat: str, leaf: str) -> str:
    if not is_sat_name(sat):
        raise ValueError(f"topic for {sat!r}: satellite names are sat_PS or sat_PPPP_SSSS (e.g. sat_11, sat_0012_0020)")
    return f"/{sat}/{leaf}"


def acs_command_topic(sat: str) -> str:
    return _sat(sat, "acs/command")


def acs_state_topic(sat: str) -> str:
    return _sat(sat, "acs/state")


def schedule_topic(sat: str) -> str:
    return _sat(sat, "schedule")


def observations_topic(sat: str) -> str:
    return _sat(sat, "observations")


def dtn_events_topic(sat: str) -> str:
    return _sat(sat, "dtn/events")


def dtn_counters_topic(sat: str) -> str:
    return _sat(sat, "dtn/counters")


def dtn_out_topic(sat: str) -> str:
    return _sat(sat, "dtn/out")


def dtn_in_topic(sat: str) -> str:
    return _sat(sat, "dtn/in")


def dtn_status_topic(sat: str) -> str:
    """The ISL medium's transmission status for sender ``sat`` (TransmissionFailed)."""
    return _sat(sat, "dtn/status")


def dtn_overheard_topic(sat: str) -> str:
    """The ISL medium's count of copies for other next hops that reached ``sat`` (CopiesOverheard)."""
    return _sat(sat, "dtn/overheard")


def ops_mode_topic(sat: str) -> str:
    """The satellite's mode changes (ModeChange, sat_node/operations/modes.py)."""
    return _sat(sat, "ops/mode")


def ops_command_topic(sat: str) -> str:
    """The satellite's operator-command events (CommandEvent, sat_node/operations/)."""
    return _sat(sat, "ops/command")


def ops_hk_topic(sat: str) -> str:
    """The satellite's housekeeping channels (Housekeeping, sat_node/operations/)."""
    return _sat(sat, "ops/hk")


def fix_topic(sat: str) -> str:
    """sensor_msgs/NavSatFix of the sub-satellite point (visualisation, not an envelope)."""
    return _sat(sat, "fix")


_GLOBAL: dict[str, object] = {
    SIM_STEP: S.SimStep,
    SIM_ACK: S.SimAck,
    CONTACTS: S.ContactWindow,
    GROUND_UPLINK: S.GroundUplink,
    GROUND_DOWNLINK: S.GroundDownlink,
    GROUND_COMMANDS: S.GroundCommand,
    GROUND_ACKS: S.CommandAck,
    GROUND_BUNDLES: S.GroundBundle,
}
_PER_SAT: dict[str, object] = {
    "acs/command": S.AcsCommand,
    "acs/state": S.AcsState,
    "schedule": S.Schedule,
    "observations": S.Observation,
    "dtn/events": S.BundleEvent,
    "dtn/counters": S.DtnCounters,
    "dtn/out": bytes,
    "dtn/in": bytes,
    "dtn/status": S.TransmissionFailed,
    "dtn/overheard": S.CopiesOverheard,
    "ops/mode": S.ModeChange,
    "ops/command": S.CommandEvent,
    "ops/hk": S.Housekeeping,
}
_SAT_TOPIC_RE = re.compile(rf"^/({SAT_NAME_PATTERN[1:-1]})/(.+)$")


def design_topic(topic: str) -> str:
    """docs/design.md's name of a per-satellite topic seen under a pushed or remapped namespace (the ROS
    engine's ``--namespace`` / ``__ns`` remaps keep its ``/<sat>/<leaf>`` end):
    ``/fleet/sat_11/schedule`` -> ``/sat_11/schedule``; any other name unchanged."""
    m = _SAT_TOPIC_RE.match(topic)
    if m and m.group(2) in _PER_SAT:
        return topic
    parts = topic.split("/")
    for i in range(2, len(parts) - 1):
        if is_sat_name(parts[i]) and "/".join(parts[i + 1:]) in _PER_SAT:
            return "/" + "/".join(parts[i:])
    return topic


def sat_of_topic(topic: str) -> str | None:
    """The satellite a per-satellite topic belongs to (under any namespace: :func:`design_topic`), else None."""
    m = _SAT_TOPIC_RE.match(design_topic(topic))
    return m.group(1) if m and m.group(2) in _PER_SAT else None


def _lookup(topic: str) -> object | None:
    t = _GLOBAL.get(topic)
    if t is not None:
        return t
    m = _SAT_TOPIC_RE.match(topic)
    if m is not None:
        t = _PER_SAT.get(m.group(2))
        if t is not None:
            return t
    d = design_topic(topic)
    if d == topic:
        return None
    m = _SAT_TOPIC_RE.match(d)
    return _PER_SAT.get(m.group(2)) if m else None


def schema_for(topic: str):
    """The msgspec type (or the BundleEvent union) of a JSON topic's payload; None for byte or
    unknown topics."""
    t = _lookup(topic)
    return None if t is bytes else t


def is_bytes_topic(topic: str) -> bool:
    """True for topics whose envelope payload is raw bytes (BPv7 bundles)."""
    return _lookup(topic) is bytes


def is_known_topic(topic: str) -> bool:
    return _lookup(topic) is not None
