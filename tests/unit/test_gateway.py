"""The ground gateway's convergence-layer side (ground_station/gateway.py) against the project's own
listeners (sat_node/dtn/cl: the ``bundles listen`` machinery) on loopback: URL forms and their
one-line errors; every bundle arrives byte-identical, in order, and is reported acknowledged only
after the listener has it; a lost session is opened again and the unacknowledged bundles sent
again; bundles the peer sends (on the ground's session or to its ``listen`` address) are taken in;
an unreachable peer is one line at start."""

from __future__ import annotations

import asyncio
import socket
import threading
import time

import pytest

from ground_station.gateway import Gateway, GatewaySpec, parse_gateway
from sat_node.dtn.bpv7 import Bundle, encode_bundle, ipn
from sat_node.dtn.cl import ClError, tcpcl3, tcpcl4, udp


def test_url_forms():
    assert parse_gateway("tcpcl4://127.0.0.1:4556?node=2") == GatewaySpec("tcpcl4", "127.0.0.1", 4556, 2)
    s = parse_gateway("udp://localhost:4556?node=7&listen=127.0.0.1:4557&foreign=refuse")
    assert (s.cl, s.host, s.port, s.node, s.listen, s.foreign) == (
        "udp", "localhost", 4556, 7, ("127.0.0.1", 4557), "refuse")
    assert parse_gateway(s.url) == s
    assert parse_gateway("tcpcl3://127.0.0.1:4556/?node=3").cl == "tcpcl3"


@pytest.mark.parametrize("url,words", [
    ("http://127.0.0.1:1?node=2", "scheme must be one of"),
    ("tcpcl4://127.0.0.1?node=2", "expected HOST:PORT"),
    ("tcpcl4://127.0.0.1:0?node=2", "expected HOST:PORT"),
    ("tcpcl4://127.0.0.1:4556", "node=N"),
    ("tcpcl4://127.0.0.1:4556?node=x", "node=N"),
    ("tcpcl4://127.0.0.1:4556?node=100", "ground segment's own node"),
    ("tcpcl4://127.0.0.1:4556?node=2&node=3", "node given 2 times"),
    ("tcpcl4://127.0.0.1:4556?node=2&port=3", "unknown parameter 'port'"),
    ("tcpcl4://127.0.0.1:4556?node=2&foreign=maybe", "foreign='maybe'"),
    ("tcpcl4://127.0.0.1:4556?node=2&listen=here", "listen 'here'"),
    ("tcpcl4://127.0.0.1:4556/x?node=2", "nothing may follow"),
])
def test_bad_urls_are_one_line_errors(url, words):
    with pytest.raises(ValueError, match=words) as e:
        parse_gateway(url)
    assert "\n" not in str(e.value)


class Peer:
    """The project's listener for one layer, in an event loop on its own thread; it can also send."""

    def __init__(self, cl: str, port: int = 0, on_take=None):
        self.cl, self.got, self.sessions, self.on_take = cl, [], [], on_take
        self.loop = asyncio.new_event_loop()
        threading.Thread(target=self.loop.run_forever, daemon=True).start()
        self.lst = self.call(self._serve(port))
        self.port = self.lst.port

    def call(self, coro, timeout=20):
        return asyncio.run_coroutine_threadsafe(coro, self.loop).result(timeout)

    async def _serve(self, port):
        def take(data, session):
            self.got.append(bytes(data))
            if self.on_take is not None:
                self.on_take(self, session)

        if self.cl == "udp":
            return await udp.serve("127.0.0.1", port, take)
        mod = tcpcl4 if self.cl == "tcpcl4" else tcpcl3
        cfg = (tcpcl4.Config(node_id="ipn:2.0", segment_mru=700) if self.cl == "tcpcl4"
               else tcpcl3.Config(eid="ipn:2.0"))
        return await mod.serve("127.0.0.1", port, cfg, on_bundle=take, on_session=self.sessions.append)

    def close(self):
        self.call(self.lst.close())
        self.loop.call_soon_threadsafe(self.loop.stop)


def _bundles(n, tag=b"x"):
    return [encode_bundle(Bundle(dest=ipn(2, 1), src=ipn(11, 1), creation_ms=10**9 + i, seq=i,
                                 lifetime_ms=60_000, payload=tag * (100 + 400 * i))) for i in range(n)]


def _wait(cond, timeout=10.0):
    end = time.monotonic() + timeout
    while not cond() and time.monotonic() < end:
        time.sleep(0.02)
    return cond()


@pytest.mark.parametrize("cl", ["tcpcl4", "tcpcl3", "udp"])
def test_bundles_reach_the_listener_byte_identical_and_acknowledged(cl):
    peer = Peer(cl)
    gw = Gateway(GatewaySpec(cl, "127.0.0.1", peer.port, 2)).start()
    try:
        data = _bundles(5)
        for i, d in enumerate(data):
            gw.submit(f"b{i}", d)
        gw.flush()
        assert _wait(lambda: len(peer.got) == 5)
        assert peer.got == data  # byte-identical, in order (transfers larger than the v4 segment MRU)
        assert gw.take_acks() == [f"b{i}" for i in range(5)]
        c = gw.counters
        assert c["sent"] == 5 and c["bytes_sent"] == sum(map(len, data))
        assert c["acknowledged" if cl != "udp" else "unacknowledged"] == 5
        assert gw.report()["acknowledged"] is (cl != "udp")
    finally:
        gw.close()
        peer.close()


@pytest.mark.parametrize("cl", ["tcpcl4", "tcpcl3"])
def test_a_lost_session_is_opened_again_and_unacknowledged_bundles_sent_again(cl):
    peer = Peer(cl)
    port = peer.port
    gw = Gateway(GatewaySpec(cl, "127.0.0.1", port, 2), reconnect_s=0.2).start()
    try:
        gw.submit("a", _bundles(1, b"a")[0])
        gw.flush()
        assert gw.take_acks() == ["a"]
        peer.close()  # the peer goes away (its sessions ended)
        time.sleep(0.3)
        gw.submit("b", _bundles(1, b"b")[0])
        time.sleep(0.5)
        assert gw.take_acks() == []  # nobody took it: not acknowledged
        peer2 = Peer(cl, port)
        gw.flush()
        assert gw.take_acks() == ["b"] and peer2.got == _bundles(1, b"b")
        assert gw.counters["reconnects"] >= 1 and gw.counters["send_failed"] >= 1
        peer2.close()
    finally:
        gw.close()


def _check_all_delivered_once_acknowledged(gw, data, got):
    """Every bundle reached the peer(s) and was acknowledged exactly once, in order; a bundle the
    peer got twice is one whose acknowledgment was lost when its session ended (got once on each side
    of the loss); the counters add up."""
    ids = [f"b{i}" for i in range(len(data))]
    assert gw.take_acks() == ids, (sorted(gw.counters.items()), gw.last_error)
    assert set(got) == set(data)
    twice = [d for d in data if got.count(d) > 1]
    assert all(got.count(d) == 2 for d in twice)
    assert len(twice) <= gw.counters["send_failed"]  # at most the one in flight at each loss
    c = gw.counters
    assert c["sent"] == c["acknowledged"] == len(data) and c["bytes_sent"] == sum(map(len, data))
    assert c["sessions_opened"] >= 2 and c["reconnects"] == c["sessions_opened"] - 1
    assert c["send_failed"] >= 1 and gw.report()["pending"] == 0


@pytest.mark.parametrize("cl", ["tcpcl4", "tcpcl3"])
def test_the_peer_lost_mid_stream_every_bundle_arrives_on_the_next_session(cl):
    """The peer's listener stops (its sessions ended) as the 5th of 20 bundles arrives, while the
    gateway is streaming; a new listener on the same port takes the rest after the gateway's backoff."""
    n, kill_at = 20, 5
    stopped = threading.Event()

    def kill(p, _session):
        if len(p.got) == kill_at:
            async def stop():
                await p.lst.close()
                stopped.set()
            asyncio.get_running_loop().create_task(stop())

    peer = Peer(cl, on_take=kill)
    port = peer.port
    gw = Gateway(GatewaySpec(cl, "127.0.0.1", port, 2), reconnect_s=0.05, reconnect_max_s=0.4).start()
    peer2 = None
    try:
        data = _bundles(n)
        for i, d in enumerate(data):
            gw.submit(f"b{i}", d)
        assert stopped.wait(10)
        time.sleep(0.5)  # the gateway fails to reach the port meanwhile, backing off
        assert len(peer.got) < n  # the loss was mid-stream
        peer2 = Peer(cl, port)
        gw.flush()
        _check_all_delivered_once_acknowledged(gw, data, peer.got + peer2.got)
        assert peer2.got[-1] == data[-1]
    finally:
        gw.close()
        peer.loop.call_soon_threadsafe(peer.loop.stop)
        if peer2 is not None:
            peer2.close()


@pytest.mark.parametrize("big", [False, True], ids=["small", "6MB"])
@pytest.mark.parametrize("cl", ["tcpcl4", "tcpcl3"])
def test_a_session_that_stops_acknowledging_is_replaced_within_the_flush(cl, big):
    """The peer stops reading the ground's session after the 3rd bundle (a stalled or half-open
    connection: TCP stays up, nothing is acknowledged, nothing closes it) while its listener still
    takes new sessions. The gateway must give the session up after ``ack_s``, end it without
    waiting on the peer, open a new one and send the rest there, all within the flush. (With an
    acknowledgment wait as long as the flush, the flush ran out first: ``send_failed`` = 1,
    ``sessions_opened`` = 1, the rest never sent.) With a 6 MB 4th bundle the socket buffers fill:
    the gateway's writes block, and so does its SESS_TERM / SHUTDOWN; the session is aborted."""
    n, stall_after = 8, 3

    def stall(p, session):
        if len(p.got) == stall_after:
            session._w.transport.pause_reading()  # the peer's side of this one session goes silent

    peer = Peer(cl, on_take=stall)
    gw = Gateway(GatewaySpec(cl, "127.0.0.1", peer.port, 2), reconnect_s=0.05, reconnect_max_s=0.4,
                 ack_s=1.0, flush_s=20.0).start()
    try:
        data = _bundles(n)
        if big:
            data[stall_after] = encode_bundle(Bundle(dest=ipn(2, 1), src=ipn(11, 1), creation_ms=10**9,
                                                     seq=99, lifetime_ms=60_000, payload=b"B" * 6_000_000))
        for i, d in enumerate(data):
            gw.submit(f"b{i}", d)
        gw.flush()
        assert gw.counters["sessions_aborted"] == (1 if big else 0)
        assert peer.got == data  # the 4th was never read on the stalled session: no duplicate
        assert gw.take_acks() == [f"b{i}" for i in range(n)]
        c = gw.counters
        assert c["sent"] == c["acknowledged"] == n and c["send_failed"] == 1
        assert c["sessions_opened"] == 2 and c["reconnects"] == 1 and gw.report()["pending"] == 0
        assert gw.last_error is not None
        if not big:  # the session was up, only the acknowledgement never came: said so, not "connection lost"
            assert "no acknowledgement within" in gw.last_error, gw.last_error
    finally:
        gw.close()
        peer.close()


@pytest.mark.parametrize("cl", ["tcpcl4", "tcpcl3"])
def test_the_peer_sends_on_the_grounds_session(cl):
    peer = Peer(cl)
    gw = Gateway(GatewaySpec(cl, "127.0.0.1", peer.port, 2)).start()
    try:
        assert _wait(lambda: peer.sessions)
        data = _bundles(3, b"p")
        for d in data:
            peer.call(peer.sessions[0].send(d, timeout_s=10))
        assert _wait(lambda: gw.counters["received"] == 3)
        assert gw.take_received() == data
    finally:
        gw.close()
        peer.close()


def _free(kind=socket.SOCK_STREAM) -> int:
    s = socket.socket(socket.AF_INET, kind)
    s.bind(("127.0.0.1", 0))
    p = s.getsockname()[1]
    s.close()
    return p


@pytest.mark.parametrize("cl", ["tcpcl4", "tcpcl3", "udp"])
def test_the_peer_sends_to_the_listen_address(cl):
    peer = Peer(cl)
    lport = _free(socket.SOCK_DGRAM if cl == "udp" else socket.SOCK_STREAM)
    gw = Gateway(GatewaySpec(cl, "127.0.0.1", peer.port, 2, listen=("127.0.0.1", lport))).start()
    try:
        data = _bundles(2, b"q")

        async def send():
            if cl == "udp":
                return await udp.send("127.0.0.1", lport, data)
            mod = tcpcl4 if cl == "tcpcl4" else tcpcl3
            cfg = tcpcl4.Config(node_id="ipn:2.0") if cl == "tcpcl4" else tcpcl3.Config(eid="ipn:2.0")
            s = await mod.connect("127.0.0.1", lport, cfg)
            for d in data:
                await s.send(d, timeout_s=10)
            await (s.terminate() if cl == "tcpcl4" else s.close())

        peer.call(send())
        assert _wait(lambda: gw.counters["received"] == 2)
        assert gw.take_received() == data
    finally:
        gw.close()
        peer.close()


@pytest.mark.parametrize("cl", ["tcpcl4", "tcpcl3"])
def test_an_unreachable_peer_is_one_line_at_start(cl):
    with pytest.raises(ClError, match="cannot connect") as e:
        Gateway(GatewaySpec(cl, "127.0.0.1", _free(), 2)).start()
    assert "\n" not in str(e.value)


@pytest.mark.parametrize("extra,words", [
    (["--ground-gateway", "tcpcl5://127.0.0.1:4556?node=2"], "scheme must be one of"),
    (["--ground-gateway", "tcpcl4://127.0.0.1:4556"], "node=N"),
    (["--ground-gateway", "udp://127.0.0.1:4556?node=2", "--mode", "distributed"],
     "needs --mode centralized"),
    (["--ground-gateway", "udp://127.0.0.1:4556?node=2", "--engine", "ros", "--restart", "1"],
     "with --restart"),
    (["--ground-gateway", "tcpcl4://127.0.0.1:{free}?node=2"], "cannot connect"),
    (["--ground-gateway", "tcpcl3://127.0.0.1:{free}?node=2"], "cannot connect"),
    # the ROS engine: its ground process runs the gateway, but the peer is reached here first
    (["--ground-gateway", "tcpcl4://127.0.0.1:{free}?node=2", "--engine", "ros"], "cannot connect"),
])
def test_the_run_refuses_a_bad_gateway_up_front(extra, words, tmp_path, capsys):
    from bringup.cli.main import main

    argv = ["run", "--mode", "centralized", "--engine", "local", "--sats", "6", "--hours", "1", "--no-plots",
            "--no-progress", "--out", str(tmp_path / "r")]
    argv += [a.replace("{free}", str(_free())) for a in extra]
    if "--mode" in extra:
        argv[1:3] = []
    if "--engine" in extra:
        argv[argv.index("--engine"):argv.index("--engine") + 2] = []
    assert main(argv) == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(err) == 1 and err[0].startswith("constellation run: error: --ground-gateway"), err
    assert words in err[0]
    assert not (tmp_path / "r").exists()  # refused before the run folder or the world


def test_the_ros_engine_processes_get_what_they_need(tmp_path):
    """bringup/engine/ros/ground_gateway.py: a satellite process gets the spec alone (no session), the
    ground's process a started gateway (a session the peer sees) that the ground's finish closes after
    writing its part of gateway.json; bad URLs and unreachable peers are one line."""
    from bringup.cli.gateway_run import write_gateway_report_ros
    from bringup.engine.ros.ground_gateway import gateway_for, report_at_finish
    from bringup.errors import UserError

    assert gateway_for({}, ["sat_11"]) == {}
    with pytest.raises(UserError, match="extra.ground_gateway: .*node=N") as e:
        gateway_for({"ground_gateway": "tcpcl4://127.0.0.1:4556"}, ["sat_11"])
    assert "\n" not in str(e.value)
    with pytest.raises(UserError, match="cannot connect"):
        gateway_for({"ground_gateway": f"tcpcl4://127.0.0.1:{_free()}?node=2"}, ["ground"])
    peer = Peer("tcpcl4")
    url = f"tcpcl4://127.0.0.1:{peer.port}?node=2"
    try:
        assert gateway_for({"ground_gateway": url}, ["sat_11", "sat_12"]) == {"gateway_spec": parse_gateway(url)}
        assert peer.sessions == []  # a satellite's process opens no session
        gw = gateway_for({"ground_gateway": url}, ["ground"])["gateway"]
        assert _wait(lambda: len(peer.sessions) == 1)

        class Ground:  # what report_at_finish needs of GroundLogic
            name, gateway, finished = "ground_station", gw, []

            def finish(self, t_ns):
                self.finished.append(t_ns)
                return ["emit"]

            def gateway_report(self):
                return {"gateway": self.gateway.report(), "agent": {}, "rx_policy": {}, "held_at_end": 0}

        class Sat:
            name = "sat_11"

            def finish(self, t_ns):
                return []

            def ground_deliveries(self):
                return {"counters": {"delivered": 1}, "bundles": [{"bundle": "b"}]}

        g, s = Ground(), Sat()
        extra = {"ground_gateway": url, "gateway_dir": str(tmp_path / "gateway")}
        with pytest.raises(UserError, match="wrote no"):
            write_gateway_report_ros(tmp_path, print)
        report_at_finish([g, s], extra)
        assert g.finish(7) == ["emit"] and g.finished == [7] and s.finish(7) == []
        assert gw._thread is not None and not gw._thread.is_alive()  # closed after the finish
        said = []
        summary = write_gateway_report_ros(tmp_path, said.append)
        assert summary["delivered_at_satellites"] == 1 and summary["url"] == parse_gateway(url).url
        assert "ground gateway tcpcl4://" in said[0]
    finally:
        peer.close()
