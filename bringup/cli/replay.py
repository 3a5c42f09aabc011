"""`constellation replay BAG [--rate R]`: republish a recorded bag onto a live ROS 2 graph.

Every recorded message is published as its raw CDR bytes (rclpy ``Publisher.publish(bytes)``) on
its topic and type, in log-time order, paced at ``--rate`` x the recorded sim time (``--rate 0``:
as fast as possible). Each topic is offered with the QoS the bag recorded for it (metadata.yaml's
``offered_qos_profiles``), chosen as rosbag2's player does (rosbag2_storage ``Rosbag2QoS::
adapt_offer_to_recorded_offers``): when every recorded offer of the topic agrees on the policies
that decide compatibility (reliability, durability, deadline, liveliness and its lease), that
profile; when they disagree (with a warning) or none was recorded, rosbag2's default offer
(reliable, volatile, keep last 10). History and depth are the recorded offer's too (they take no part
in matching; the envelopes' keep-all means a fast replay to a slow subscriber loses none).
So ``/clock`` goes out best effort (as rclpy's TimeSource subscribes), ``/tf_static``
transient local, the envelope topics reliable, volatile, keep-all (bringup/recording/bag.py
``topic_qos``; converted by bringup/engine/ros/qos.py). The bag's own ``/clock`` is republished
with it; a bag without ``/clock`` gets one synthesised from the log times (like ``ros2 bag play
--clock``), so nodes with ``use_sim_time`` follow the replay.

The bag's seal is checked first (bringup/recording/bag_seal.py): a bag whose seal does not match is
refused in one line naming integrity (exit 2) unless ``--unverified`` is given; an unverified bag
(no seal, another user's key, or ``--unverified``) is replayed with a warning line saying so, and
the summary line says "unverified" (tests/faults/test_bag_seal.py).

Network safety (docs/design.md section 7): the process runs with ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``
and the domain from ``--domain-id`` or ``ROS_DOMAIN_ID`` (default 0); the project's FastDDS profile
(5 ms heartbeats) is used unless ``FASTRTPS_DEFAULT_PROFILES_FILE`` is already set.
``--wait-subscribers N`` waits (up to ``--wait-timeout``) until every topic has N matched
subscribers before the first message; at the end every publisher waits until its reliable
samples are acknowledged, so nothing is lost when the process exits.

Oracle: tests/ros/test_replay.py replays a small bag to a subscriber in an isolated rclpy Context
on a leased domain and checks every message arrives byte-identical, in order (/clock, best effort:
those that arrive, at least one), and that the graph reports the replayer's publishers with the
reliability and durability metadata.yaml records (read with PyYAML); the choice between
disagreeing offers is checked on its own.
"""

from __future__ import annotations

import importlib
import os
import sys
import time
from pathlib import Path

import rclpy
from rclpy.context import Context
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException

from bringup.engine.ros.qos import qos_profile
from bringup.errors import UserError
from bringup.recording.bag import CLOCK_TYPE, BagReader, clock_cdr, make_qos, topic_qos
from bringup.recording.bag_seal import check_bag


def add_arguments(p) -> None:
    p.add_argument("bag", type=Path, help="bag directory (metadata.yaml + .mcap)")
    p.add_argument("--rate", type=float, default=1.0,
                   help="sim seconds per wall second (default 1; 0 = as fast as possible)")
    p.add_argument("--domain-id", type=int, default=None, help="ROS_DOMAIN_ID (default: env or 0)")
    p.add_argument("--topics", nargs="+", default=None, help="replay only these topics (and /clock)")
    p.add_argument("--wait-subscribers", type=int, default=0, metavar="N",
                   help="before starting, wait until every topic has N matched subscribers")
    p.add_argument("--wait-timeout", type=float, default=10.0, help="[s] for --wait-subscribers (default 10)")
    p.add_argument("--quiet", action="store_true", help="no summary line")
    p.add_argument("--unverified", action="store_true",
                   help="replay a bag whose seal does not match (the output says unverified)")


_ROSBAG2_DEFAULT = make_qos(depth=10)  # rosbag2's default publisher offer: reliable, volatile, keep last 10


def _compat(q) -> tuple:
    return (q.reliability, q.durability, q.deadline, q.liveliness, q.liveliness_lease_duration)


def replay_qos(topic: str, offers: list):
    """The rclpy QoS to replay ``topic`` with, from its recorded offers (module docstring)."""
    if offers and all(_compat(q) == _compat(offers[0]) for q in offers):
        return qos_profile(offers[0])
    if offers:
        print(f"replay: warning: the recorded offers on {topic} disagree; offering rosbag2's default "
              "(reliable, volatile, keep last 10)", file=sys.stderr)
    return qos_profile(_ROSBAG2_DEFAULT)


def _msg_class(msgtype: str):
    try:
        pkg, kind, name = msgtype.split("/")
        return getattr(importlib.import_module(f"{pkg}.{kind}"), name)
    except (ValueError, ImportError, AttributeError):
        raise UserError(f"replay: message type {msgtype!r} is not available in this ROS install") from None


def _domain_id(arg: int | None) -> int:
    raw = arg if arg is not None else os.environ.get("ROS_DOMAIN_ID", "0")
    try:
        d = int(raw)
    except ValueError:
        raise UserError(f"replay: ROS_DOMAIN_ID {raw!r} is not an integer") from None
    if not 0 <= d <= 232:
        raise UserError(f"replay: domain id {d} outside 0..232")
    return d


def run(args) -> int:
    if args.rate < 0:
        raise UserError(f"replay: --rate must be >= 0, got {args.rate}")
    domain = _domain_id(args.domain_id)
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    os.environ["ROS_DOMAIN_ID"] = str(domain)
    if "FASTRTPS_DEFAULT_PROFILES_FILE" not in os.environ:
        profile = Path(__file__).resolve().parents[1] / "engine" / "ros" / "dds" / "fastdds_profile.xml"
        if profile.exists():
            os.environ["FASTRTPS_DEFAULT_PROFILES_FILE"] = str(profile)

    integrity = check_bag(args.bag, unverified_ok=args.unverified)
    unverified = "" if integrity.status == "verified" else " (unverified bag)"
    if unverified:
        print(f"constellation replay: warning: bag {args.bag}: unverified: {integrity.detail}", file=sys.stderr)
    reader = BagReader(args.bag)
    stats = reader.topics()
    end_ns = reader.end_ns
    want = None if args.topics is None else set(args.topics) | {"/clock"}
    types = {t.topic: t.msgtype for t in stats if want is None or t.topic in want}
    if args.topics is not None and not set(args.topics) <= set(types):
        missing = sorted(set(args.topics) - set(types))
        raise UserError(f"replay: topics not in the bag: {', '.join(missing)}")
    synth_clock = "/clock" not in types
    classes = {topic: _msg_class(mt) for topic, mt in types.items()}
    if synth_clock:
        classes["/clock"] = _msg_class(CLOCK_TYPE)
    offered = reader.offered_qos()
    qos = {topic: replay_qos(topic, offered.get(topic, [])) for topic in classes}
    if synth_clock:
        qos["/clock"] = qos_profile(topic_qos("/clock", CLOCK_TYPE))
    ctx = Context()
    rclpy.init(context=ctx, domain_id=domain)
    node = None
    n = 0
    wall0 = time.monotonic()
    try:
        node = rclpy.create_node("bag_replay", context=ctx)
        pubs = {topic: node.create_publisher(cls, topic, qos[topic]) for topic, cls in classes.items()}
        if args.wait_subscribers > 0:
            deadline = time.monotonic() + args.wait_timeout
            while not all(p.get_subscription_count() >= args.wait_subscribers for p in pubs.values()):
                if time.monotonic() > deadline:
                    short = sorted(t for t, p in pubs.items() if p.get_subscription_count() < args.wait_subscribers)
                    raise UserError(f"replay: no {args.wait_subscribers} subscriber(s) within "
                                    f"{args.wait_timeout} s on: {', '.join(short)}")
                time.sleep(0.01)  # polling the graph for matches; there is no blocking wait in rclpy
        clock_pub = pubs["/clock"]
        t_first = None
        last_clock = None
        wall0 = time.monotonic()
        for m in reader.messages(list(types)):
            if t_first is None:
                t_first = m.log_time_ns
            if args.rate > 0:
                due = wall0 + (m.log_time_ns - t_first) / 1e9 / args.rate
                delay = due - time.monotonic()
                if delay > 0:
                    time.sleep(delay)
            if synth_clock and m.log_time_ns != last_clock:  # the bag's instant: its epoch + t_ns
                clock_pub.publish(clock_cdr(reader.epoch_ns + m.log_time_ns))
                last_clock = m.log_time_ns
            pubs[m.topic].publish(m.cdr)
            n += 1
        for p in pubs.values():
            p.wait_for_all_acked(Duration(seconds=5.0))
    except (KeyboardInterrupt, ExternalShutdownException):
        print("replay: interrupted")
        return 130
    finally:
        reader.close()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown(context=ctx)
    if not args.quiet:
        span = 0.0 if t_first is None else (end_ns - t_first) / 1e9
        print(f"replayed {n} messages on {len(types)} topics (domain {domain}): "
              f"{span:.3f} s of sim time in {time.monotonic() - wall0:.3f} s{unverified}")
    return 0
