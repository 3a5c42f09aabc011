"""ROS names of a run's nodes and topics: namespaces and relative names, so a push or remap moves them.

Participants speak the topic names of docs/design.md section 4 (``/sat_11/dtn/out``, ``/ground/uplink``;
msgs_json/topics.py). The ROS engine gives each participant its own rclpy node and names it the ROS
way (REP 2 / ROS 2 "Topic and Service name mapping"):

* a satellite's node is ``<push>/<sat>/<sat>`` (namespace ``<push>/<sat>``, node name = the
  satellite's name, so a node-qualified remap ``sat_12:__ns:=/x`` names exactly one satellite even
  when one process hosts several); its own topics are *relative* (``dtn/out``), so a namespace
  remap or push moves all of them;
* the other participants (router, ground segment, contact announcer) sit in ``<push>`` (the root
  namespace by default) and name per-satellite topics relatively too (``sat_11/dtn/in``), so a push
  of the whole run moves both ends of every satellite's link together;
* global topics (``/ground/uplink``, ``/orbit/contacts``, and the ROS conventions ``/clock``, ``/tf``,
  ``/diagnostics``) stay absolute.

``<push>`` is the run spec's ``namespace`` (what launch's PushRosNamespace gives every node; empty by
default), so by default every name resolves to docs/design.md's. Remaps come from the run's ROS arguments
(``ros_args``: ``constellation run --ros-args ...``, every node process's rclpy context) and act as
in any ROS 2 node. The host keys the lockstep's counting by the *resolved* names (what DDS
carries) and gives participants their logical names back (bringup/engine/ros/host.py).

How we know it is right: tests/ros/test_ros_naming.py (every topic of a paper run's participants:
default resolution = docs/design.md's names; a push moves both ends of each per-satellite link; rclpy's
own resolver with remaps), tests/ros/test_live_run.py (a live run with one satellite remapped: its
topics appear under the new namespace, the run completes).
"""

from __future__ import annotations

from msgs_json.topics import is_sat_name

__all__ = ["check_namespace", "node_name_and_namespace", "ros_topic_name"]


def check_namespace(ns: str) -> str:
    """A push namespace, normalised: '' (none) or '/a/b' (absolute, no trailing '/'); ValueError else."""
    if not ns or ns == "/":
        return ""
    if not ns.startswith("/") or ns.endswith("/") or "//" in ns:
        raise ValueError(f"namespace {ns!r}: expected an absolute name like /fleet")
    for tok in ns[1:].split("/"):
        if not tok or not (tok[0].isalpha() or tok[0] == "_") or not all(c.isalnum() or c == "_" for c in tok):
            raise ValueError(f"namespace {ns!r}: {tok!r} is not a valid ROS name token")
    return ns


def node_name_and_namespace(participant: str, push: str = "") -> tuple[str, str]:
    """(node name, namespace) of ``participant``'s node under the push namespace ``push``."""
    push = check_namespace(push)
    if is_sat_name(participant):
        return participant, f"{push}/{participant}"
    return participant, push or "/"


def ros_topic_name(topic: str, participant: str) -> str:
    """The name ``participant``'s node uses for the logical ``topic`` (module docstring): per-satellite
    topics are ``/<sat>/...`` (any leaf: data, ``fix``)."""
    sat = topic[1:].split("/", 1)[0] if topic.startswith("/") and topic.count("/") >= 2 else ""
    if not is_sat_name(sat):
        return topic  # global: absolute
    if is_sat_name(participant):
        return topic[len(sat) + 2:] if sat == participant else topic
    return topic[1:]  # a root-namespace node: relative to the (pushed) root
