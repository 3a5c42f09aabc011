"""One msgspec Struct per message type: the payloads of docs/design.md section 4's topics.

Every payload travels as JSON text (``body`` of the wire envelope, msgs_json/wire.py, on
std_msgs/msg/String); BPv7 bundles (``/sat_XX/dtn/out|in``) are raw bytes and have no schema here.
Which type goes on which topic: msgs_json/topics.py (``schema_for(topic)``). Encode/decode with
validation: msgs_json/codec.py (``encode(msg) -> str``, ``decode(topic, text) -> Struct``).

Types (all frozen, keyword-only, unknown fields rejected, ``v`` = SCHEMA_VERSION checked):

=====================  ============================  =============================================
topic                  type                          meaning
=====================  ============================  =============================================
/sim/step              SimStep(k, t_ns, final)       the lockstep clock opens step k at t_ns
/sim/ack               SimAck(participant, k, t_ns,  a participant finished step k; what it sent
                       next_wakeup_ns, sent)         (topic -> count) so receivers can wait for it
/orbit/contacts        ContactWindow(event, kind,    a directed contact window opening or closing
                       src, dst, start_ns, end_ns,
                       rate_bps, range_light_s)
/sat_XX/acs/command    AcsCommand                    slew request: point at GP ``gp`` from t_ns
/sat_XX/acs/state      AcsState                      attitude mode / current target / slew timing
/sat_XX/schedule       Schedule(items=[ScheduleItem  the current plan [(gp, t_ns, value)], version,
                       ...])                         the inputs' cut-off time
/sat_XX/observations   Observation                   an executed observation (gp, t_ns, assumed
                                                     value, recorded value)
/sat_XX/dtn/events     BundleCreated | BundleForwar  bundle life cycle, tagged by ``event``:
                       ded | BundleDelivered |       created, forwarded, delivered,
                       BundleDropped | CopyDiscarded dropped(reason), copy_discarded
/sat_XX/dtn/counters   DtnCounters                   cumulative DTN counters (overheard copies, held)
/sat_XX/dtn/status     TransmissionFailed            the ISL medium tells the sender a transmission
                                                     did not get through (bundle goes back to queue)
/sat_XX/dtn/overheard  CopiesOverheard               how many copies for other next hops the medium
                                                     brought the node since its last such message
/sat_XX/ops/mode       ModeChange                    the satellite changed mode (NOMINAL, DEGRADED,
                                                     SAFE; sat_node/operations/modes.py)
/sat_XX/ops/command    CommandEvent                  an operator command received, executed or
                                                     rejected (sat_node/operations/)
/ground/commands       GroundCommand                 a signed command uplinked to satellite ``relay``
/ground/acks           CommandAck                    a satellite's command event acknowledged at a pass
/sat_XX/ops/hk         Housekeeping                  the satellite's housekeeping channels at
                                                     ``operations.hk_period_s`` (sat_node/operations/)
/ground/downlink       GroundDownlink                observations a satellite downlinked at a pass
                                                     (and the bundles carrying them)
/ground/bundles        GroundBundle                  a bundle the ground's agent uplinks (gateway)
/ground/uplink         GroundUplink                  a plan uplinked to a satellite at a pass
=====================  ============================  =============================================

Oracle (tests/unit/test_msgs_json.py): one golden JSON per type (msgs_json/golden/<Type>.json)
decodes and re-encodes to the same bytes; invariants below (e.g. a schedule's times increase, a
contact ends after it starts) are checked on decode; hypothesis fuzzing shows the decoder raises
nothing but MessageError on arbitrary input.
"""

from __future__ import annotations

from typing import Annotated, Literal

import msgspec
from msgspec import Meta

from msgs_json.names import SAT_NAME_PATTERN

__all__ = [
    "DROP_REASONS",
    "MESSAGE_TYPES",
    "SCHEMA_VERSION",
    "AcsCommand",
    "AcsState",
    "BundleCreated",
    "BundleDelivered",
    "BundleDropped",
    "BundleEvent",
    "DtnCounters",
    "BundleForwarded",
    "ContactWindow",
    "CopiesOverheard",
    "CopyDiscarded",
    "GroundDownlink",
    "GroundUplink",
    "CommandAck",
    "CommandEvent",
    "GroundCommand",
    "GroundBundle",
    "ModeChange",
    "Observation",
    "Schedule",
    "ScheduleItem",
    "SimAck",
    "SimStep",
    "TransmissionFailed",
]

SCHEMA_VERSION = 1

# --- field types (constraints are checked by msgspec on decode) ------------------------------------
NsTime = Annotated[int, Meta(ge=0, le=2**63 - 1, description="integer ns since the scenario epoch")]
SatName = Annotated[str, Meta(pattern=SAT_NAME_PATTERN, description="sat_PS, sat_PPPP_SSSS or sat_n<NORAD> (msgs_json/names.py)")]
StationName = Annotated[str, Meta(pattern=r"^gs_[A-Za-z0-9_]{1,32}$")]
NodeName = Annotated[str, Meta(pattern=rf"(?:{SAT_NAME_PATTERN})|(?:^gs_[A-Za-z0-9_]{{1,32}}$)")]
ParticipantName = Annotated[str, Meta(pattern=r"^[A-Za-z0-9_]{1,64}$")]
TopicName = Annotated[str, Meta(pattern=r"^(/[A-Za-z0-9_]+)+$", max_length=256)]
GpIndex = Annotated[int, Meta(ge=0, le=2**31 - 1, description="global ground-point index")]
Count = Annotated[int, Meta(ge=0, le=2**63 - 1)]
NonNeg = Annotated[float, Meta(ge=0.0)]
Priority = Annotated[int, Meta(ge=1, le=15, description="1 = next satellite to reach the region")]
BundleId = Annotated[str, Meta(min_length=1, max_length=128)]
Deg = Annotated[float, Meta(ge=0.0, le=180.0)]

DROP_REASONS = ("ttl", "integrity", "no_route", "malformed", "other")
DropReason = Literal["ttl", "integrity", "no_route", "malformed", "other"]
Mode = Literal["distributed", "centralized", "nonagile"]


class _Msg(msgspec.Struct, kw_only=True, frozen=True, forbid_unknown_fields=True):
    """Base: schema version first; subclasses add their fields after it."""

    v: int = SCHEMA_VERSION

    def __post_init__(self) -> None:
        if self.v != SCHEMA_VERSION:
            raise ValueError(f"schema version {self.v} is not supported (expected {SCHEMA_VERSION})")
        self._check()

    def _check(self) -> None:  # cross-field invariants; override
        return None


# --- lockstep barrier (part B's clock node and hosts) --------------------------------------------
class SimStep(_Msg, kw_only=True, frozen=True):
    """Step ``k`` starts at ``t_ns``; ``final`` marks the last step (at the horizon)."""

    k: Count
    t_ns: NsTime
    final: bool = False


class SimAck(_Msg, kw_only=True, frozen=True):
    """``participant`` finished step ``k``; ``sent`` = messages it emitted in it, per topic."""

    participant: ParticipantName
    k: Count
    t_ns: NsTime
    next_wakeup_ns: NsTime | None = None
    sent: dict[TopicName, Count] = {}


# --- orbit clock -----------------------------------------------------------------------------------
class ContactWindow(_Msg, kw_only=True, frozen=True):
    """A directed contact (src -> dst) opening or closing; rate [bit/s], one-way light time [s]."""

    event: Literal["open", "close"]
    kind: Literal["isl", "ground"]
    src: NodeName
    dst: NodeName
    start_ns: NsTime
    end_ns: NsTime
    rate_bps: Annotated[float, Meta(gt=0.0)]
    range_light_s: NonNeg

    def _check(self) -> None:
        if self.end_ns <= self.start_ns:
            raise ValueError("end_ns must be after start_ns")
        if self.src == self.dst:
            raise ValueError("src and dst must differ")


# --- attitude control --------------------------------------------------------------------------------
class AcsCommand(_Msg, kw_only=True, frozen=True):
    """Slew request: point the boresight at ground point ``gp`` starting at ``t_ns``."""

    sat: SatName
    request_id: Count
    t_ns: NsTime
    gp: GpIndex
    target_ecef_km: tuple[float, float, float]


class AcsState(_Msg, kw_only=True, frozen=True):
    """Attitude state: mode, current target, slew angle [deg] and when the slew ends."""

    sat: SatName
    t_ns: NsTime
    mode: Literal["idle", "slewing", "settled"]
    target_gp: GpIndex | None = None
    request_id: Count | None = None
    slew_angle_deg: Deg = 0.0
    slew_end_ns: NsTime | None = None

    def _check(self) -> None:
        if self.mode == "slewing" and self.slew_end_ns is None:
            raise ValueError("a slewing state needs slew_end_ns")


# --- scheduling and observations ----------------------------------------------------------------------
class ScheduleItem(msgspec.Struct, kw_only=True, frozen=True, forbid_unknown_fields=True):
    """One planned observation: ground point, time, the value the planner assumed, and the time of
    the newest information about the GP's region the planner had (None: not recorded)."""

    gp: GpIndex
    t_ns: NsTime
    value: NonNeg
    info_ns: NsTime | None = None


class Schedule(_Msg, kw_only=True, frozen=True):
    """A satellite's current plan, its version and inputs' cut-off. Items in increasing time; one
    image may cover several GPs (the non-agile footprint): items at one time come in increasing GP."""

    sat: SatName
    version: Count
    mode: Mode
    planned_ns: NsTime
    cutoff_ns: NsTime
    items: list[ScheduleItem] = []
    # CPU time [s] the planner spent on this plan (runtime figure; not part of the plan itself).
    solve_cpu_s: NonNeg = 0.0

    def _check(self) -> None:
        if self.cutoff_ns > self.planned_ns:
            raise ValueError("cutoff_ns must not be after planned_ns")
        for a, b in zip(self.items, self.items[1:]):
            if b.t_ns < a.t_ns or (b.t_ns == a.t_ns and b.gp <= a.gp):
                raise ValueError("items must be in increasing t_ns (at one t_ns: in increasing gp)")


class Observation(_Msg, kw_only=True, frozen=True):
    """An executed observation: what the satellite assumed it was worth, what it recorded, and the
    time of the information it was planned with (None: not recorded; never after ``t_ns``)."""

    sat: SatName
    gp: GpIndex
    t_ns: NsTime
    assumed_value: NonNeg
    recorded_value: NonNeg
    schedule_version: Count = 0
    info_ns: NsTime | None = None

    def _check(self) -> None:
        if self.info_ns is not None and self.info_ns > self.t_ns:
            raise ValueError("info_ns must not be after t_ns")


class GroundDownlink(_Msg, kw_only=True, frozen=True):
    """Observations ``sat`` downlinked to ``station`` during the pass at ``t_ns`` (centralized mode),
    and the BPv7 bundles that carry them to the ground's bundle agent (one per observation, in the
    same order: sat_node/dtn/downlink.py)."""

    station: StationName
    sat: SatName
    t_ns: NsTime
    observations: list[Observation] = []
    bundles: Annotated[list[bytes], Meta(max_length=100_000)] = []

    def _check(self) -> None:
        if any(o.sat != self.sat for o in self.observations):
            raise ValueError("every downlinked observation must belong to sat")


class GroundUplink(_Msg, kw_only=True, frozen=True):
    """A plan ``station`` uplinks to ``sat`` at ``t_ns`` (centralized mode)."""

    station: StationName
    sat: SatName
    t_ns: NsTime
    schedule: Schedule

    def _check(self) -> None:
        if self.schedule.sat != self.sat:
            raise ValueError("schedule.sat must equal sat")


# --- DTN bundle life cycle (/sat_XX/dtn/events), tagged by "event" ----------------------------------
class _BundleEvt(_Msg, kw_only=True, frozen=True, tag_field="event"):
    """Common part: reporting satellite, event time, bundle identity (source, creation time)."""

    sat: SatName
    t_ns: NsTime
    bundle_id: BundleId
    src: NodeName
    dst: NodeName
    priority: Annotated[int, Meta(ge=0, le=15, description="1..15; 0 = unknown (copy not decoded)")]
    creation_ns: NsTime

    def _check(self) -> None:
        if self.t_ns < self.creation_ns:
            raise ValueError("t_ns must not be before creation_ns")


class BundleCreated(_BundleEvt, kw_only=True, frozen=True, tag="created"):
    """A bundle created for observation (gp, obs_t_ns); lifetime from priority (TTL)."""

    gp: GpIndex
    obs_t_ns: NsTime
    lifetime_ns: Annotated[int, Meta(gt=0)]
    size_bits: Annotated[int, Meta(gt=0)]


class BundleForwarded(_BundleEvt, kw_only=True, frozen=True, tag="forwarded"):
    """``sat`` handed the bundle to the router for ``next_hop``."""

    next_hop: NodeName


class BundleDelivered(_BundleEvt, kw_only=True, frozen=True, tag="delivered"):
    """The bundle reached its destination ``sat`` (== dst) after ``hop_count`` hops."""

    hop_count: Count = 0

    def _check(self) -> None:
        super()._check()
        if self.sat != self.dst:
            raise ValueError("a delivered bundle's sat must be its dst")


class BundleDropped(_BundleEvt, kw_only=True, frozen=True, tag="dropped"):
    """The bundle was dropped at ``sat`` for ``reason`` (ttl, integrity, no_route, malformed, other)."""

    reason: DropReason
    detail: Annotated[str, Meta(max_length=256)] = ""


class CopyDiscarded(_BundleEvt, kw_only=True, frozen=True, tag="copy_discarded"):
    """A copy received by ``sat`` and discarded: not its intended next hop (broadcast medium), or a
    duplicate of a bundle it holds or already delivered."""

    intended_next_hop: NodeName | None = None
    reason: Literal["not_next_hop", "duplicate", "other"] = "not_next_hop"


BundleEvent = BundleCreated | BundleForwarded | BundleDelivered | BundleDropped | CopyDiscarded


class DtnCounters(_Msg, kw_only=True, frozen=True):
    """Cumulative DTN counters of satellite ``sat`` at ``t_ns`` (/sat_XX/dtn/counters).

    Copies overheard on the broadcast medium and meant for another next hop are only counted here
    (one event per copy would outnumber every other message of a run); ``counters`` maps names
    such as ``discarded.not_next_hop``, ``held``, ``rejected_messages`` to counts."""

    sat: SatName
    t_ns: NsTime
    counters: dict[Annotated[str, Meta(max_length=64)], Count] = {}

class CopiesOverheard(_Msg, kw_only=True, frozen=True):
    """The ISL medium (dtn_router) tells node ``sat`` that ``copies`` copies of transmissions by other
    nodes reached it, each naming next hops of which it is not one (/sat_XX/dtn/overheard), stamped
    ``t_ns`` (the latest of their arrivals). Sent instead of those copies on /sat_XX/dtn/in: the node
    would only count them (DtnCounters ``discarded.not_next_hop``), so it counts this number."""

    sat: SatName
    t_ns: NsTime
    copies: Annotated[int, Meta(ge=1, le=2**63 - 1)]


class TransmissionFailed(_Msg, kw_only=True, frozen=True):
    """The ISL medium (dtn_router) tells sender ``sat`` that its transmission of ``bundle_id`` to
    ``next_hop`` started at ``start_ns`` did not get through (/sat_XX/dtn/status), stamped ``t_ns``
    (when the attempt ended). ``reason``: contact_ended (the truth contact closed before the last
    bit, e.g. an ISL cut), no_contact (no truth contact to the next hop at the start), radio_busy
    (the sender's radio was still sending). The sender takes the bundle back and re-routes it."""

    sat: SatName
    t_ns: NsTime
    bundle_id: BundleId
    next_hop: NodeName
    start_ns: NsTime
    reason: Literal["contact_ended", "no_contact", "radio_busy", "other"]

    def _check(self) -> None:
        if self.t_ns < self.start_ns:
            raise ValueError("t_ns must not be before start_ns")


# --- operations -----------------------------------------------------------------------------------------
class ModeChange(_Msg, kw_only=True, frozen=True):
    """Satellite ``sat`` entered ``mode`` from ``previous`` at ``t_ns`` for ``reason`` (the rule that
    fired, sat_node/operations/modes.py; "" when back to NOMINAL). ``imaging``: whether it images in
    the new mode; ``plan_value_dropped``: the planner's assumed value of the looks it dropped from its
    plan on stopping imaging (0 otherwise)."""

    sat: SatName
    t_ns: NsTime
    mode: Literal["NOMINAL", "DEGRADED", "SAFE"]
    previous: Literal["NOMINAL", "DEGRADED", "SAFE"]
    reason: Annotated[str, Meta(max_length=64)] = ""
    imaging: bool = True
    plan_value_dropped: NonNeg = 0.0

    def _check(self) -> None:
        if self.mode == self.previous:
            raise ValueError("a mode change needs mode != previous")


class CommandEvent(_Msg, kw_only=True, frozen=True):
    """Satellite ``sat`` received (``stage`` received), executed or rejected (with ``reason``) the operator
    command ``command_id`` at ``t_ns``; ``issued_ns``: when the ground issued it (0 when a rejected
    command could not be read); ``latency_s`` = t_ns - issued_ns."""

    sat: SatName
    t_ns: NsTime
    command_id: Annotated[str, Meta(max_length=64)]
    stage: Literal["received", "executed", "rejected"]
    reason: Annotated[str, Meta(max_length=64)] = ""
    kind: Annotated[str, Meta(max_length=16)] = ""
    issued_ns: NsTime = 0
    latency_s: NonNeg = 0.0
    gp: Annotated[int, Meta(ge=-1)] = -1  # an executed task: the ground point it maps to (-1: none)
    by_ns: NsTime = 0  # an executed task: its deadline


class CommandAck(_Msg, kw_only=True, frozen=True):
    """Satellite ``sat``'s acknowledgement of its command event (``stage`` received, executed or
    rejected at ``event_ns``) reached the ground station ``station`` at ``t_ns``, downlinked in a
    ground contact; ``issued_ns``: the command's issue time; ``latency_s`` = t_ns - event_ns."""

    sat: SatName
    station: StationName
    t_ns: NsTime
    command_id: Annotated[str, Meta(max_length=64)]
    stage: Literal["received", "executed", "rejected"]
    reason: Annotated[str, Meta(max_length=64)] = ""
    event_ns: NsTime
    issued_ns: NsTime = 0
    latency_s: NonNeg = 0.0

    def _check(self) -> None:
        if self.t_ns < self.event_ns:
            raise ValueError(f"CommandAck: reached the ground at {self.t_ns} ns, before its event at {self.event_ns} ns")


class GroundBundle(_Msg, kw_only=True, frozen=True):
    """One BPv7 bundle the ground's bundle agent uplinks from ``station`` to ``sat`` at ``t_ns``
    (ground_station/ground_agent.py: a bundle a gateway's peer sent into the constellation)."""

    station: StationName
    sat: SatName
    t_ns: NsTime
    bundle: Annotated[bytes, Meta(max_length=1 << 24)]


class GroundCommand(_Msg, kw_only=True, frozen=True):
    """The ground gateway uplinks a signed operator command (sat_node/operations/, ASCII)
    to satellite ``relay`` at ``t_ns``, during one of its ground contacts; the relay forwards it over
    the ISLs when it is for another satellite."""

    relay: SatName
    station: StationName
    t_ns: NsTime
    payload: Annotated[str, Meta(max_length=4096)]


class Housekeeping(_Msg, kw_only=True, frozen=True):
    """Satellite ``sat``'s housekeeping channels at ``t_ns``: ``mode`` (0 NOMINAL, 1 DEGRADED, 2 SAFE),
    the pointing error [deg], bundles held in its store, its plan version, bundles created and
    delivered to it, commands accepted and rejected (sat_node/operations/catalogue.py CHANNELS)."""

    sat: SatName
    t_ns: NsTime
    mode: Annotated[int, Meta(ge=0, le=2)]
    pointing_error_deg: Deg = 0.0
    store_bundles: Count = 0
    plan_version: Count = 0
    bundles_created: Count = 0
    bundles_delivered: Count = 0
    commands_accepted: Count = 0
    commands_rejected: Count = 0


MESSAGE_TYPES: tuple[type[msgspec.Struct], ...] = (
    SimStep,
    SimAck,
    ContactWindow,
    AcsCommand,
    AcsState,
    Schedule,
    Observation,
    GroundDownlink,
    GroundUplink,
    BundleCreated,
    BundleForwarded,
    BundleDelivered,
    BundleDropped,
    CopyDiscarded,
    DtnCounters,
    TransmissionFailed,
    CopiesOverheard,
    ModeChange,
    CommandEvent,
    CommandAck,
    GroundCommand,
    GroundBundle,
    Housekeeping,
)
