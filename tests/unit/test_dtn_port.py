"""The bundle agent's port on the lockstep bus (sat_node/dtn/port.py), on drawn plans by hand.

Oracles: a sent bundle stays with its sender until two steps have passed since it was emitted and
one since its end (the contract's delivery rule: the medium's failure report for it, stamped at the
attempt's end, has arrived by then), worked out by hand for two step grids; a failure report always
finds its transmission in flight, whatever the step length, and the bundle leaves again after the
report's time (the attempt's end, not its start); a report naming no transmission of ours is a
ValueError (the node counts it).
"""

from __future__ import annotations

import re

import pytest

from bringup.analysis.dtn_alone import run_dtn
from msgs_json import codec
from msgs_json import schemas as S
from msgs_json import topics as T
from msgs_json.envelope import Envelope
from orbit_clock.contact_faults import truth_plan
from orbit_clock.contact_plan import Contact, ContactPlan
from sat_node.dtn.agent import AgentConfig, BundleAgent
from sat_node.dtn.port import DtnPort
from sat_node.dtn.traffic import TrafficItem
from tests.keys import TEST_BPSEC_KEY

S_ = 10**9
LINK = ContactPlan([Contact(0.0, 1000.0, "sat_11", "sat_12", 1000.0, 0.5),
                    Contact(0.0, 1000.0, "sat_12", "sat_11", 1000.0, 0.5)])


def _port(plan=LINK, **kw):
    return DtnPort("sat_11", BundleAgent("sat_11", plan, AgentConfig(key=TEST_BPSEC_KEY, settle_delay_s=None, **kw)))


@pytest.mark.parametrize("grid_s,settled_at_s", [
    # 10 s steps: emitted at step 0 (t=0, on air 0-2 s); step 1 (t=10) is too early (the medium
    # sees it only now), step 2 (t=20): two steps on and the previous step (10 s) is past its end
    ((0, 10, 20, 30), 20),
    # 1 s steps: steps 1 and 2 come before the medium can report the end (2 s); at step 3 (t=3 s)
    # the previous step (2 s) has reached it
    ((0, 1, 2, 3, 4), 3),
])
def test_a_sent_bundle_is_settled_when_no_report_can_still_come(grid_s, settled_at_s):
    port = _port()
    port.originate(b"x", [("sat_12", 1)], 0)
    held = {}
    for t in grid_s:
        emits = port.radio(t * S_)
        if t == 0:
            assert [e.topic for e in emits if e.topic == T.dtn_out_topic("sat_11")] == [T.dtn_out_topic("sat_11")]
        held[t] = port.agent.held_count()
    assert held == {t: (0 if t >= settled_at_s else 1) for t in grid_s}


def test_port_needs_an_agent_it_can_settle():
    with pytest.raises(ValueError, match="settles transmissions itself"):
        DtnPort("sat_11", BundleAgent("sat_11", LINK, AgentConfig(key=TEST_BPSEC_KEY)))
    with pytest.raises(ValueError, match="fixed bundle size"):
        DtnPort("sat_11", BundleAgent("sat_11", LINK, AgentConfig(key=TEST_BPSEC_KEY, settle_delay_s=None, bundle_bits=None)))


def test_a_report_naming_no_transmission_of_ours_is_an_error():
    port = _port()
    st = S.TransmissionFailed(sat="sat_11", t_ns=5, bundle_id="ipn11.1-0-0", next_hop="sat_12", start_ns=0,
                              reason="contact_ended")
    with pytest.raises(ValueError, match="names no transmission of ours"):
        port.receive(Envelope(5, "dtn_router", 0, port.status_topic, codec.encode(st)), 10)
    other = S.TransmissionFailed(sat="sat_12", t_ns=5, bundle_id="x", next_hop="sat_11", start_ns=0,
                                 reason="contact_ended")
    with pytest.raises(ValueError, match="status for sat_12"):
        port.receive(Envelope(5, "dtn_router", 1, port.status_topic, codec.encode(other)), 10)
    with pytest.raises(ValueError, match="carries text"):
        port.receive(Envelope(5, "dtn_router", 2, port.in_topic, "text"), 10)


# The plan has sat_11 -> sat_12 open 0-100 s and again 60-100 s (a second, later contact); the truth
# cuts 11-50 s: the first contact ends at 11 s in truth. A bundle created at 10 s goes at once
# (10-12 s on air), the medium finds it cut at 11 s and reports it failed at the attempt's end (12 s);
# the sender takes it back and re-routes it without that contact: on the 60 s one, 60-62 s, +0.5 s.
CUT_PLAN = ContactPlan([Contact(0.0, 100.0, "sat_11", "sat_12", 1000.0, 0.5),
                        Contact(60.0, 100.0, "sat_11", "sat_12", 1000.0, 0.5)])


@pytest.mark.parametrize("max_step_s", [0.5, 3.0, 10.0, 60.0])
def test_failure_is_reported_at_the_attempts_end_and_always_finds_its_transmission(max_step_s):
    truth = truth_plan(CUT_PLAN, cuts=[("sat_11", "sat_12", 11.0, 50.0)])
    envs = []
    run = run_dtn(CUT_PLAN, [TrafficItem(10.0, "sat_11", "sat_12", 1, "p0", "r", 0)], truth=truth,
                  max_step_s=max_step_s, sink=envs.append)
    status = [(e.t_ns, codec.decode(e.topic, e.data)) for e in envs if e.topic == T.dtn_status_topic("sat_11")]
    assert [(t, m.reason, m.start_ns) for t, m in status] == [(12 * S_, "contact_ended", 10 * S_)]
    sends = [e.t_ns for e in run.events if e.kind == "forwarded"]
    assert sends == [10 * S_, 60 * S_]
    rep = run.report()
    assert rep["dtn.delivery_ratio"] == 1.0 and rep["dtn.latency_s.mean"] == pytest.approx(52.5)
    assert rep["dtn.conservation_ok"] and rep["dtn.bundles_held_at_end"] == 0
    assert rep["dtn.tx_failed"] == 1 and rep["dtn.transmissions"] == 2
    assert all(n.rejected == 0 for n in run.nodes)  # the report found its transmission in flight


def test_traffic_node_counts_a_bad_message_and_goes_on():
    from sat_node.dtn.traffic import TrafficNode

    node = TrafficNode(BundleAgent("sat_11", LINK, AgentConfig(key=TEST_BPSEC_KEY, settle_delay_s=None)),
                       [(0, TrafficItem(1.0, "sat_11", "sat_12", 1, "p0", "r", 0))])
    r = node.step(5 * S_, [Envelope(1, "dtn_router", 0, node.port.in_topic, "not bytes"),
                           Envelope(1, "dtn_router", 1, node.port.status_topic, b"\xff")])
    assert node.rejected == 2 and node.rejected_by_reason == {"in.ValueError": 1, "status.MessageError": 1}
    assert [e.topic for e in r.emits][:1] == [T.dtn_out_topic("sat_11")]  # the bundle created at 1 s goes
    c = codec.decode(T.dtn_counters_topic("sat_11"), node.finish(10 * S_)[-1].data).counters
    assert c["rejected_messages"] == 2 and c["rejected.in.ValueError"] == 1


class _NoMemo(dict):
    """A bundle-info memo that keeps nothing: every node computes its own (the reference)."""

    def get(self, key, default=None):
        return default

    def __setitem__(self, key, value):
        return None


class _CountingMemo(dict):
    hits = 0

    def get(self, key, default=None):
        got = super().get(key, default)
        if got is not None:
            _CountingMemo.hits += 1
        return got


def test_bundle_info_kept_per_received_bytes_equals_each_nodes_own(paper_scenario, monkeypatch):
    """sat_node/dtn/port.py: the bundle info kept per received bytes (one multicast copy reaches
    several recipients in one process) gives every message of 96 satellites x 0.25 h - each bundle
    event included - exactly as when every node decodes its own; and it is used."""
    from bringup.engine.local import run_local
    from bringup.scenario.participants import all_participants
    from bringup.scenario.world import World
    from sat_node.dtn import port as port_mod

    sc = paper_scenario.with_overrides(sats=96, planes=6, hours=0.25)
    world = World.build(sc)
    out = {}
    for name, memo in (("kept", _CountingMemo()), ("own", _NoMemo())):
        monkeypatch.setattr(port_mod, "_INFO", memo)
        res = run_local(all_participants(world, "distributed", bpsec_key=TEST_BPSEC_KEY), horizon_ns=sc.horizon_ns,
                        max_step_ns=int(sc.scenario.lockstep_max_step_s * 1e9))
        # (the planners' own CPU seconds, in their schedules, differ from run to run)
        out[name] = [(e.t_ns, e.source, e.seq, e.topic, re.sub(r'"(\w*cpu\w*)":[-+0-9.eE]+', r'"\1":0', e.data)
                      if isinstance(e.data, str) else e.data) for e in res.envelopes]
    events = [e for e in out["own"] if e[3].endswith("/dtn/events")]
    assert len(events) > 1000
    assert _CountingMemo.hits > 50
    assert out["kept"] == out["own"]
