"""rclpy QoS profiles from a bag's recorded ones: what the live topics and ``constellation replay`` offer.

A bag records each topic's ``offered_qos_profiles`` in metadata.yaml (bringup/recording/bag.py
``topic_qos``, as rosbags' ``Qos`` records); :func:`qos_profile` turns one into the rclpy
``QoSProfile`` with the same reliability, durability, history and depth, liveliness, and deadline,
lifespan and lease when they are non-zero (zero: left to the middleware's default).

How we know it is right: tests/ros/test_replay.py (the graph reports, for the replayer's
publishers, the reliability and durability the bag's metadata.yaml names, read with PyYAML) and
tests/ros/test_live_run.py (a live subscriber with the recorded QoS receives the run's topics).
"""

from __future__ import annotations

from rclpy.duration import Duration
from rclpy.qos import DurabilityPolicy, HistoryPolicy, LivelinessPolicy, QoSProfile, ReliabilityPolicy
from rosbags.interfaces import QosDurability, QosHistory, QosLiveliness, QosReliability

__all__ = ["qos_profile"]


def qos_profile(q) -> QoSProfile:
    """A rosbags ``Qos`` record (a bag's ``offered_qos_profiles`` entry) as an rclpy QoSProfile."""
    keep_all = q.history == QosHistory.KEEP_ALL
    p = QoSProfile(
        history=HistoryPolicy.KEEP_ALL if keep_all else HistoryPolicy.KEEP_LAST,
        depth=max(1, int(q.depth)) if not keep_all else 0,
        reliability={QosReliability.RELIABLE: ReliabilityPolicy.RELIABLE,
                     QosReliability.BEST_EFFORT: ReliabilityPolicy.BEST_EFFORT}.get(q.reliability,
                                                                                   ReliabilityPolicy.SYSTEM_DEFAULT),
        durability={QosDurability.TRANSIENT_LOCAL: DurabilityPolicy.TRANSIENT_LOCAL,
                    QosDurability.VOLATILE: DurabilityPolicy.VOLATILE}.get(q.durability,
                                                                          DurabilityPolicy.SYSTEM_DEFAULT),
        liveliness={QosLiveliness.AUTOMATIC: LivelinessPolicy.AUTOMATIC,
                    QosLiveliness.MANUAL_BY_TOPIC: LivelinessPolicy.MANUAL_BY_TOPIC}.get(q.liveliness,
                                                                                        LivelinessPolicy.SYSTEM_DEFAULT),
    )
    for attr in ("deadline", "lifespan", "liveliness_lease_duration"):
        t = getattr(q, attr)
        if t.sec or t.nsec:
            setattr(p, attr, Duration(seconds=t.sec, nanoseconds=t.nsec))
    p.avoid_ros_namespace_conventions = bool(q.avoid_ros_namespace_conventions)
    return p
