"""tf2_msgs built by scripts/build_ros_interfaces.py (scripts/setup.sh runs it) is ROS 2 Jazzy's.

Oracles: the type hash the ROS graph reports for our publisher is the one a Jazzy install reports
for tf2_msgs/msg/TFMessage (``ros2 topic info -v /tf`` on Jazzy prints
RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087), so a Jazzy RViz or
Foxglove bridge matches it; a message crosses DDS between two rclpy contexts intact; its CDR bytes
are read by rosbags (an independent
serializer that knows tf2_msgs) as the same message, and rosbags' bytes by rclpy.
"""

from __future__ import annotations

import threading
import time

import pytest

pytestmark = [pytest.mark.ros, pytest.mark.timeout(120)]

JAZZY_TFMESSAGE_HASH = "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087"


def _message():
    from geometry_msgs.msg import TransformStamped
    from tf2_msgs.msg import TFMessage

    out = TFMessage()
    for i, (name, x) in enumerate([("sat_11", 7.08e6), ("sat_12", -3.5e6)]):
        t = TransformStamped()
        t.header.frame_id = "earth"
        t.header.stamp.sec, t.header.stamp.nanosec = 946727968 + i, 500
        t.child_frame_id = name
        t.transform.translation.x, t.transform.translation.z = x, 1.25e6
        t.transform.rotation.x, t.transform.rotation.w = 0.6, 0.8
        out.transforms.append(t)
    return out


def test_cdr_equals_rosbags():
    from rclpy.serialization import deserialize_message, serialize_message
    from tf2_msgs.msg import TFMessage

    from bringup.recording.bag import TYPESTORE

    m = _message()
    cdr = serialize_message(m)
    T = TYPESTORE.types
    ref = T["tf2_msgs/msg/TFMessage"](transforms=[
        T["geometry_msgs/msg/TransformStamped"](
            header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](
                sec=tr.header.stamp.sec, nanosec=tr.header.stamp.nanosec), frame_id=tr.header.frame_id),
            child_frame_id=tr.child_frame_id,
            transform=T["geometry_msgs/msg/Transform"](
                translation=T["geometry_msgs/msg/Vector3"](x=tr.transform.translation.x, y=0.0,
                                                           z=tr.transform.translation.z),
                rotation=T["geometry_msgs/msg/Quaternion"](x=tr.transform.rotation.x, y=0.0, z=0.0,
                                                           w=tr.transform.rotation.w)))
        for tr in m.transforms])
    # both directions (CDR padding bytes are unspecified, so compare what each side decodes)
    ours_read_by_rosbags = TYPESTORE.deserialize_cdr(bytes(cdr), "tf2_msgs/msg/TFMessage")
    assert ours_read_by_rosbags == ref
    rosbags_read_by_ours = deserialize_message(bytes(TYPESTORE.serialize_cdr(ref, "tf2_msgs/msg/TFMessage")), TFMessage)
    assert rosbags_read_by_ours == m
    assert len(cdr) == len(TYPESTORE.serialize_cdr(ref, "tf2_msgs/msg/TFMessage"))


def test_publishes_over_dds_with_jazzy_type_hash():
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from tf2_msgs.msg import TFMessage

    from bringup.engine.ros.launcher import lease_domain_id

    with lease_domain_id() as lease:
        ctxs = [Context(), Context()]
        for c in ctxs:
            rclpy.init(context=c, domain_id=lease.domain_id)
        try:
            pub_node = rclpy.create_node("tf_pub", context=ctxs[0])
            sub_node = rclpy.create_node("tf_sub", context=ctxs[1])
            got: list = []
            cond = threading.Condition()

            def cb(msg):
                with cond:
                    got.append(msg)
                    cond.notify_all()

            sub_node.create_subscription(TFMessage, "/tf", cb, 10)
            pub = pub_node.create_publisher(TFMessage, "/tf", 10)
            ex = SingleThreadedExecutor(context=ctxs[1])
            ex.add_node(sub_node)
            deadline = time.monotonic() + 30
            while pub.get_subscription_count() < 1:
                assert time.monotonic() < deadline, "subscriber never matched"
                ex.spin_once(timeout_sec=0.05)
            m = _message()
            while not got:
                assert time.monotonic() < deadline, "no TFMessage arrived"
                pub.publish(m)
                ex.spin_once(timeout_sec=0.2)
            assert got[0] == m
            infos = sub_node.get_publishers_info_by_topic("/tf")
            assert [i.topic_type for i in infos] == ["tf2_msgs/msg/TFMessage"]
            assert str(infos[0].topic_type_hash) == JAZZY_TFMESSAGE_HASH
        finally:
            for c in ctxs:
                rclpy.try_shutdown(context=c)
