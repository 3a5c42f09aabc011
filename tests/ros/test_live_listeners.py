"""A host's live publications are built only for topics someone subscribes to (bringup/engine/ros/live.py).

Oracle: publisher stand-ins whose subscription count the test sets and which record what they are
given; a participant that counts its ``live_state`` calls. With no subscriber nothing is asked or
published (the period still advances); with a /diagnostics subscriber only, every participant's
state goes into one DiagnosticArray and no fix is built; with one satellite's fix subscribed only,
that fix (the bag's NavSatFix bytes for the instant) and nothing else. The whole path with real
subscribers is tests/ros/test_live_run.py.
"""

from __future__ import annotations

from types import SimpleNamespace

import pytest
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import NavSatFix

from bringup.engine.ros.live import HostLive
from bringup.recording.viz_messages import navsat_fixes_cdr
from msgs_json.envelope import LiveState

pytestmark = [pytest.mark.ros]
S = 10**9


class _Pub:
    def __init__(self):
        self.subscribers = 0
        self.sent = []

    def get_subscription_count(self):
        return self.subscribers

    def publish(self, msg):
        self.sent.append(msg)


class _Node:
    def __init__(self, fqn):
        self.fqn = fqn
        self.pubs = {}

    def create_publisher(self, _type, topic, _qos):
        return self.pubs.setdefault(topic, _Pub())

    def get_fully_qualified_name(self):
        return self.fqn


class _Sat:
    def __init__(self, name):
        self.name = name
        self.asked = 0

    def live_state(self, t_ns):
        self.asked += 1
        return LiveState(position_ecef_km=(7000.0, 0.0, float(t_ns // S)), values={"n": self.asked})


def _host():
    slots = [SimpleNamespace(name=n, p=_Sat(n), node=_Node(f"/{n}/{n}")) for n in ("sat_11", "sat_12")]
    gate = SimpleNamespace(rejections=SimpleNamespace(counts=dict))
    return SimpleNamespace(slots=slots, host_node=_Node("/host_x"), duplicates=0, republished=0, done_k=3,
                           gate=gate, role="sats_1")


def test_nothing_is_built_without_subscribers_then_only_what_is_subscribed():
    host = _host()
    live = HostLive(host, epoch_ns=5 * S, period_s=60.0)
    diag = host.host_node.pubs["/diagnostics"]
    fix11, fix12 = (s.node.pubs["fix"] for s in host.slots)
    sats = [s.p for s in host.slots]

    assert live.publish(0) is False  # due, but no one listens
    assert [s.asked for s in sats] == [0, 0] and not diag.sent and not fix11.sent and live.skipped == 1
    assert live.next_ns == 60 * S

    diag.subscribers = 1
    assert live.publish(30 * S) is False  # not due yet
    assert live.publish(60 * S) is True
    assert [s.asked for s in sats] == [1, 1] and not fix11.sent and not fix12.sent
    (arr,) = diag.sent
    assert [st.name for st in arr.status] == ["/sat_11/sat_11", "/sat_12/sat_12", "/host_x"]
    assert arr.header.stamp.sec == 65

    diag.subscribers = 0
    fix12.subscribers = 1
    assert live.publish(120 * S) is True
    assert [s.asked for s in sats] == [1, 2] and len(diag.sent) == 1 and not fix11.sent
    (cdr,) = fix12.sent
    assert bytes(cdr) == bytes(navsat_fixes_cdr([[7000.0, 0.0, 120.0]], 125 * S)[0])
    assert deserialize_message(bytes(cdr), NavSatFix).header.stamp.sec == 125

    fix12.subscribers = 0
    assert live.publish(130 * S, final=True) is False  # the final one too: no one listens
    assert [s.asked for s in sats] == [1, 2]
