"""What a ROS run shows live, beside the lockstep: fixes, diagnostics, visualisation, parameters.

The bag has every visualisation message after the run; this module puts the same on the graph while
the run goes on, so RViz, Foxglove (foxglove_bridge / ROS 2 connection) or ``ros2 topic echo``
attached to the run's ROS_DOMAIN_ID see it:

* each host process (bringup/engine/ros/host.py), every ``[viz] period_s`` of sim time while
  someone subscribes (a topic with no subscriber gets nothing built: the fixes' publishers exist
  from the start, so a viewer finds them), for each of its participants that has a ``live_state`` (msgs_json.envelope.LiveState; satellites and the ISL
  medium): a sensor_msgs/NavSatFix on the node's relative ``fix`` (``/<sat>/fix``), the same bytes
  the bag records for that instant (bringup/recording/viz_messages.py ``navsat_fixes_cdr``), and one
  diagnostic_msgs/DiagnosticArray on ``/diagnostics`` with a DiagnosticStatus per participant
  (name = the node's fully qualified name, hardware_id = the participant, its counters as
  KeyValues; level WARN when it rejected messages) plus one for the host process itself
  (duplicates dropped, messages it rejected - malformed, unauthenticated, bad MAC - by reason and topic);
* the clock process (bringup/engine/ros/clock_node.py): the constellation MarkerArray
  (``viz/constellation``) and the TF tree (``/tf``, ``/tf_static``) of every visualisation frame,
  the bytes it records (bringup/recording/viz_feed.py);
* every participant node declares the run's settings as read-only parameters
  (:func:`declare_run_parameters`; RunSpec.parameters: the run's ``run.*`` and the scenario's
  settings), readable with the usual parameter services (rcl_interfaces/srv/GetParameters,
  ListParameters, DescribeParameters).

Publishers use the QoS the bag records for the topic (bringup/recording/bag.py ``topic_qos``,
converted by bringup/engine/ros/qos.py): what ``constellation replay`` offers again. Header stamps are UTC
(the scenario epoch + t), as /clock and the bag.

/tf needs tf2_msgs, which the Jazzy wheels lack: scripts/build_ros_interfaces.py builds it at setup
(tests/ros/test_tf2_msgs.py); without it the clock says so once on stderr and publishes no live /tf
(the bag still has it).

How we know it is right: tests/ros/test_live_run.py (a live 6-satellite run: a subscriber sees
fixes equal to the bag's, markers, /tf and diagnostics, reads a satellite's parameters through the
parameter services; a remapped satellite's topics move), tests/unit/test_contract.py (live_state is
checked like every other participant output).
"""

from __future__ import annotations

import sys

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import ParameterDescriptor
from sensor_msgs.msg import NavSatFix
from visualization_msgs.msg import MarkerArray

from bringup.engine.contract import EngineError, check_live_state, failed
from bringup.engine.ros.qos import qos_profile
from bringup.recording.bag import topic_qos
from bringup.recording.viz_messages import NAVSAT_TYPE, navsat_fixes_cdr
from msgs_json.topics import DIAGNOSTICS, TF, TF_STATIC, VIZ_MARKERS, fix_topic, is_sat_name

try:  # not among the Jazzy wheels: scripts/build_ros_interfaces.py builds it at setup
    from tf2_msgs.msg import TFMessage
except ImportError:
    TFMessage = None

__all__ = ["ClockLive", "HostLive", "declare_run_parameters"]

_DIAG_TYPE = "diagnostic_msgs/msg/DiagnosticArray"


def declare_run_parameters(node, parameters: dict) -> None:
    """Declare ``parameters`` (name -> bool, int, float, str or a list of one of them) read-only."""
    ro = ParameterDescriptor(read_only=True, description="run setting (read-only)")
    for name, value in parameters.items():
        node.declare_parameter(name, value, ro)


class ClockLive:
    """The clock process's live visualisation: the frames' MarkerArray on ``viz/constellation``
    (relative: under the run's namespace) and the TF tree on ``/tf``, ``/tf_static``; ``publish``
    takes the CDR the clock records for a frame's topic (others are not published live)."""

    def __init__(self, node):
        self.pubs = {VIZ_MARKERS: node.create_publisher(
            MarkerArray, VIZ_MARKERS[1:], qos_profile(topic_qos(VIZ_MARKERS, "visualization_msgs/msg/MarkerArray")))}
        if TFMessage is None:
            print("clock: tf2_msgs is not installed (bash scripts/setup.sh builds it): no live /tf; "
                  "the bag has /tf", file=sys.stderr, flush=True)
            return
        for topic in (TF, TF_STATIC):
            self.pubs[topic] = node.create_publisher(TFMessage, topic, qos_profile(topic_qos(topic, "tf2_msgs/msg/TFMessage")))

    def publish(self, topic: str, cdr) -> None:
        pub = self.pubs.get(topic)
        if pub is not None:
            pub.publish(cdr)


def _status(name: str, hardware_id: str, level: int, message: str, values: dict) -> DiagnosticStatus:
    return DiagnosticStatus(level=bytes([level]), name=name, message=message, hardware_id=hardware_id,
                            values=[KeyValue(key=k, value=str(v)) for k, v in values.items()])


class HostLive:
    """The live publications of one host process (module docstring). ``publish(t_ns)`` after each
    step: does nothing until the next period is due (and at the final step, always)."""

    def __init__(self, host, epoch_ns: int, period_s: float):
        self.host = host
        self.epoch_ns = int(epoch_ns)
        self.period_ns = max(1, round(period_s * 1e9))
        self.next_ns = 0
        self.published = 0
        self.skipped = 0  # periods due with no one subscribed
        self.diag = host.host_node.create_publisher(DiagnosticArray, DIAGNOSTICS,
                                                    qos_profile(topic_qos(DIAGNOSTICS, _DIAG_TYPE)))
        self._slots = [s for s in host.slots if callable(getattr(s.p, "live_state", None))]
        # made now, not at the first fix: a viewer must find them to subscribe (see publish)
        self._fix_pubs: dict[str, object] = {s.name: self._fix_pub(s) for s in self._slots if is_sat_name(s.name)}

    def _fix_pub(self, slot):
        """The satellite's NavSatFix publisher, on its node's relative ``fix`` (``/<sat>/fix``)."""
        return slot.node.create_publisher(NavSatFix, "fix", qos_profile(topic_qos(fix_topic(slot.name), NAVSAT_TYPE)))

    def publish(self, t_ns: int, *, final: bool = False) -> bool:
        """The live state at ``t_ns`` when a period is due (or ``final``), to the topics someone
        subscribes to; True when something was published."""
        if t_ns < self.next_ns and not final:
            return False
        self.next_ns = (t_ns // self.period_ns + 1) * self.period_ns
        # nothing is built for topics no one subscribes to (the bag has the fixes from the clock)
        diag_on = self.diag.get_subscription_count() > 0
        fix_on = {name for name, pub in self._fix_pubs.items() if pub.get_subscription_count() > 0}
        if not diag_on and not fix_on:
            self.skipped += 1
            return False
        stamp = self.epoch_ns + t_ns
        sec, nsec = divmod(stamp, 1_000_000_000)
        statuses = []
        for slot in self._slots:
            if not diag_on and slot.name not in fix_on:
                continue
            where = f"live_state at {t_ns}"
            try:
                st = slot.p.live_state(t_ns)
            except Exception as exc:
                raise EngineError(str(failed(slot.name, where, exc))) from exc
            st = check_live_state(slot.name, st, where)
            if st is None:
                continue
            if st.position_ecef_km is not None and slot.name in fix_on:
                cdr = navsat_fixes_cdr(np.asarray([st.position_ecef_km], dtype=float), stamp)[0]
                self._fix_pubs[slot.name].publish(cdr)
            if diag_on:
                statuses.append(_status(slot.node.get_fully_qualified_name(), slot.name, st.level, st.message,
                                        st.values))
        if diag_on:
            h = self.host
            values = {"participants": ",".join(s.name for s in h.slots), "duplicates_dropped": h.duplicates,
                      "republished": h.republished, "steps_done": h.done_k + 1}
            rejected = h.gate.rejections.counts()  # what the host let not in, by topic and reason
            for topic, reasons in rejected.items():
                for reason, n in reasons.items():
                    values[f"rejected.{reason}.{topic}"] = n
            statuses.append(_status(h.host_node.get_fully_qualified_name(), h.role, 1 if rejected else 0,
                                    f"host of {len(h.slots)} participant(s)", values))
            msg = DiagnosticArray(status=statuses)
            msg.header.stamp.sec, msg.header.stamp.nanosec = sec, nsec
            self.diag.publish(msg)
        self.published += 1
        return True
