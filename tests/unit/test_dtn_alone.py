"""The DTN alone (bringup/analysis/dtn_alone.py: traffic nodes and the ISL medium on the local engine)
and its latency bounds (bringup/analysis/dtn_bounds.py): drawn plans with hand-worked delivery
times and bounds, conservation, send orders and hop tolerance through the CLI, the study's inputs."""

import random

import pytest

from bringup.analysis.dtn_alone import run_dtn
from bringup.analysis.dtn_bounds import latency_lower_bounds, store_forward_bound_mean
from orbit_clock.contact_plan import Contact, ContactPlan
from orbit_clock.contact_plan_io import read_contact_plan
from sat_node.dtn.traffic import TrafficItem, read_traffic
from tests.keys import TEST_BPSEC_KEY

#   sat_11 --[0;1000] owlt 0.5--> sat_12 --[0;1000] owlt 0.5--> sat_13   (and reverse)
PLAN = ContactPlan([Contact(0.0, 1000.0, a, b, 1000.0, 0.5) for a, b in
                    [("sat_11", "sat_12"), ("sat_12", "sat_11"), ("sat_12", "sat_13"), ("sat_13", "sat_12")]])


def test_chain_hand_worked_latencies():
    traffic = [TrafficItem(10.0, "sat_11", "sat_12", 1, "p1", "r", 2), TrafficItem(10.0, "sat_11", "sat_13", 2, "p1", "r", 2)]
    run = run_dtn(PLAN, traffic)
    rep = run.report(latency_lower_bounds(PLAN, traffic, 2000, run.created_ids))
    # P1 to sat_12: 10-12 on air, +0.5 -> 2.5 s. P2 to sat_13: waits 12, 12-14, +0.5, 14.5-16.5, +0.5 -> 7 s
    assert rep["dtn.latency_s_by_priority.1.median"] == pytest.approx(2.5)
    assert rep["dtn.latency_s_by_priority.2.median"] == pytest.approx(7.0)
    assert rep["dtn.delivery_ratio"] == 1.0 and rep["dtn.conservation_ok"]
    # bound: max(no-contention arrival 5 s, serial leave 4 s) = 5 s for P2; 2.5 s for P1
    assert rep["dtn.latency_s.lower_bound_mean"] == pytest.approx((2.5 + 5.0) / 2)
    assert rep["dtn.copies_discarded"] == 1  # sat_11 hears sat_12's relay to sat_13


def test_store_forward_bound_hand_worked_and_tight_on_the_chain():
    """Two bundles for sat_13 created together at sat_11: one radio, one relay. Sum bound: finish at
    the source 2 and 4 s (creation order), then one relay (2 s) and two light times (1 s) each:
    (5 + 7) / 2 = 6 s. The run is that schedule (pipelined), so it meets the bound exactly; the issue's
    bound, max(no-contention arrival 5 s, leave 2 / 4 s), is 5 s: the optimal schedule is 1.2x it (and
    1.27x it on the mixed pair below: 4.75 s against 3.75 s)."""
    traffic = [TrafficItem(10.0, "sat_11", "sat_13", 1, "p1", "r", 2), TrafficItem(10.0, "sat_11", "sat_13", 2, "p1", "r", 2)]
    run = run_dtn(PLAN, traffic)
    rep = run.report(latency_lower_bounds(PLAN, traffic, 2000, run.created_ids))
    sf = store_forward_bound_mean(PLAN, traffic, 2000, {1: 900.0, 15: 3000.0})
    assert sf == pytest.approx(6.0)
    assert rep["dtn.delivery_ratio"] == 1.0 and rep["dtn.latency_s.mean"] == pytest.approx(sf)
    assert rep["dtn.latency_s.lower_bound_mean"] == pytest.approx(5.0)
    # the mixed pair of test_chain_hand_worked_latencies: sum bound (2.5 + 7) / 2, met; the 3.75
    mixed = [TrafficItem(10.0, "sat_11", "sat_12", 1, "p1", "r", 2), TrafficItem(10.0, "sat_11", "sat_13", 2, "p1", "r", 2)]
    assert store_forward_bound_mean(PLAN, mixed, 2000, {15: 3000.0}) == pytest.approx(4.75)


def test_store_forward_bound_hops_within_ttl_and_unreachable():
    """Hops count over contacts open within [created, created + TTL]: a direct sat_11 -> sat_13 contact
    from 100 s shortens the path only for bundles whose TTL reaches it; a node no contact reaches is left
    out of the mean."""
    plan = ContactPlan(PLAN.contacts + [Contact(100.0, 200.0, "sat_11", "sat_13", 1000.0, 0.5),
                                        Contact(0.0, 10.0, "sat_14", "sat_11", 1000.0, 0.5)])
    item = TrafficItem(10.0, "sat_11", "sat_13", 1, "p1", "r", 2)
    assert store_forward_bound_mean(plan, [item], 2000, {15: 50.0}) == pytest.approx(2 + 1 + 2)
    assert store_forward_bound_mean(plan, [item], 2000, {15: 100.0}) == pytest.approx(2 + 0.5)
    lost = TrafficItem(10.0, "sat_11", "sat_14", 1, "p1", "r", 2)
    assert store_forward_bound_mean(plan, [lost], 2000, {15: 3000.0}) is None
    assert store_forward_bound_mean(plan, [item, lost], 2000, {15: 50.0}) == pytest.approx(5.0)


def test_bounds_do_not_depend_on_the_order_of_the_traffic_list():
    """Both bounds serve each source's radio in creation order, whatever order the list is in: items at
    t=100 s and t=0 s (listed in that order) on one 1000 b/s contact, light 0.5 s: each leaves 2 s after
    its creation, so the mean is 2.5 s (not (2.5 + 102.5) / 2, as a list-order radio would give)."""
    plan = ContactPlan([Contact(0.0, 1000.0, "sat_11", "sat_12", 1000.0, 0.5)])
    traffic = [TrafficItem(100.0, "sat_11", "sat_12", 1, "p1", "r", 1), TrafficItem(0.0, "sat_11", "sat_12", 1, "p0", "r", 0)]
    assert store_forward_bound_mean(plan, traffic, 2000, {15: 3000.0}) == pytest.approx(2.5)
    lb = latency_lower_bounds(plan, traffic, 2000, {0: "late", 1: "early"})
    assert lb == pytest.approx({("late", "sat_12"): 2.5, ("early", "sat_12"): 2.5})
    assert store_forward_bound_mean(plan, traffic[::-1], 2000, {15: 3000.0}) == pytest.approx(2.5)


@pytest.mark.timeout(30)
def test_transmission_ending_exactly_at_contact_end_does_not_loop():
    """Regression: a transmission whose ceil-to-ns end passes the contact's end by rounding is re-routed
    without that contact; the route memo used to keep naming the contact, so the agent re-tried it
    forever. Here no other contact exists: the bundle is dropped (no route) and the run ends."""
    plan = ContactPlan([Contact(31.19, 32.19, "sat_11", "sat_12", 4000.0, 0.5)])
    run = run_dtn(plan, [TrafficItem(31.69, "sat_11", "sat_12", 1, "p0", "r", 0)])
    rep = run.report()
    assert rep["dtn.bundles_created"] == 1 and rep["dtn.conservation_ok"]
    assert rep["dtn.bundles_delivered"] + rep["dtn.dropped_detail.no_route"] == 1


@pytest.mark.parametrize("seed", range(12))
def test_store_forward_bound_below_every_full_delivery(seed):
    """The invariant the bound claims: on random plans and bursty traffic, any run that delivers every
    bundle within its TTL has a mean latency at or above it (both send orders, several rates)."""
    from sat_node.dtn.agent import AgentConfig, deadline_delays
    rng = random.Random(seed)
    nodes = [f"sat_{p}{s}" for p in (1, 2) for s in (1, 2, 3)]
    rate = rng.choice([500.0, 1000.0, 4000.0])
    contacts = []
    for a, b in zip(nodes, nodes[1:] + nodes[:1]):  # a ring always open, plus random chords
        contacts += [Contact(0.0, 3000.0, a, b, rate, 0.1), Contact(0.0, 3000.0, b, a, rate, 0.1)]
    for _ in range(8):
        a, b = rng.sample(nodes, 2)
        t0 = rng.uniform(0, 2500)
        t1 = t0 + rng.uniform(20, 500)
        light = rng.uniform(0.01, 0.3)
        contacts += [Contact(t0, t1, a, b, rate, light), Contact(t0, t1, b, a, rate, light)]
    plan = ContactPlan(contacts)
    traffic = []
    for k in range(rng.randint(15, 40)):
        src = rng.choice(nodes)
        t = round(rng.uniform(0, 1500), 1)
        for j, dst in enumerate(rng.sample([n for n in nodes if n != src], rng.randint(1, 4)), start=1):
            traffic.append(TrafficItem(t, src, dst, j, f"p{k}", "r", k))
    traffic.sort(key=lambda it: it.t_s)
    ttl = {1: 900.0, 3: 1800.0, 15: 3000.0}
    sf = store_forward_bound_mean(plan, traffic, 2000, ttl)
    checked = 0
    for cfg in (AgentConfig(key=TEST_BPSEC_KEY), AgentConfig(key=TEST_BPSEC_KEY, priority_delay_s=deadline_delays(ttl))):
        rep = run_dtn(plan, traffic, config=cfg).report()
        if rep["dtn.delivery_ratio"] == 1.0:
            assert rep["dtn.latency_s.mean"] >= sf - 1e-6, (rep["dtn.latency_s.mean"], sf)
            checked += 1
    assert checked, "no run delivered everything: the case checks nothing"


def test_traffic_counts(paper_inputs):
    assert len(read_traffic(paper_inputs / "traffic_case4.csv")) == 7430
    assert len(read_traffic(paper_inputs / "traffic_case1.csv")) == 52413


# case4 (7430 bundles, ~5 s) runs in the default suite; case1 (52413 bundles, ~45 s) is `slow` and
# fails the targets under every send order and routing tried, oracles included (strict
# priority: 90.7 % delivered, mean 1.65x the bound; the deadline queue: 100 %, 3.11x; README "The DTN
# alone on the study's own inputs"): a strict xfail, so the day it passes it turns red and gets updated.
_CASE1_TARGETS_MISSED = pytest.mark.xfail(
    strict=True, raises=AssertionError,
    reason="case1 at 1 kb/s with unicast forwarding misses >= 99 % delivered with a mean <= 1.25x the bound (README)")


def _study_run(paper_inputs, case: str, config=None):
    """The study's plan at 1 kb/s and one of its traffic sets: (plan, traffic, report with the bound)."""
    plan = read_contact_plan(paper_inputs / "contact_plan_3p_8s.csv", rate_bps=1000)
    traffic = read_traffic(paper_inputs / f"traffic_{case}.csv")
    run = run_dtn(plan, traffic, config=config)
    return plan, traffic, run.report(latency_lower_bounds(plan, traffic, 2000, run.created_ids))


@pytest.mark.parametrize("case", ["case4", pytest.param("case1", marks=[pytest.mark.slow, _CASE1_TARGETS_MISSED])])
def test_study_inputs_targets(paper_inputs, case):
    _plan, _traffic, rep = _study_run(paper_inputs, case)
    assert rep["dtn.conservation_ok"]
    assert rep["dtn.delivery_ratio"] >= 0.99
    for p in (1, 2, 3):
        assert rep[f"dtn.latency_s_by_priority.{p}.count"] == rep[f"dtn.latency_s_by_priority.{p}.created"]
    assert rep["dtn.latency_s.mean"] <= 1.25 * rep["dtn.latency_s.lower_bound_mean"]
    # latency rises with priority number (by classes: the study's TTL bands)
    med = [rep[f"dtn.latency_s_by_priority.{p}.median"] for p in range(1, 16)]
    bands = [[m for m in med[a - 1:b] if m is not None] for a, b in ((1, 1), (2, 3), (4, 7), (8, 15))]
    means = [sum(x) / len(x) for x in bands if x]
    assert means == sorted(means), means


@pytest.mark.slow
@pytest.mark.parametrize("order", ["priority", "deadline"])
def test_case1_trade_off_between_send_orders(paper_inputs, order):
    """What case1 at 1 kb/s does give (README table; the figures have been the same since the
    bundle agent's last change of policy): strict priority delivers every priority 1-3 bundle and
    >= 90 % of all; earliest-expiry-first delivers every bundle within its TTL, at a higher mean.
    Both means sit above the store-and-forward bound, which no policy beats when all is delivered."""
    from sat_node.dtn.agent import AgentConfig

    cfg = AgentConfig.for_policy(order, key=TEST_BPSEC_KEY)
    plan, traffic, rep = _study_run(paper_inputs, "case1", cfg)
    sf = store_forward_bound_mean(plan, traffic, 2000, cfg.ttl_s_by_priority)
    assert rep["dtn.conservation_ok"] and rep["dtn.dropped.integrity"] == 0
    bound = rep["dtn.latency_s.lower_bound_mean"]
    if order == "priority":
        assert 0.90 <= rep["dtn.delivery_ratio"] < 0.99
        for p in (1, 2, 3):
            assert rep[f"dtn.latency_s_by_priority.{p}.count"] == rep[f"dtn.latency_s_by_priority.{p}.created"]
        assert 1.25 * bound < rep["dtn.latency_s.mean"] < 1.8 * bound
    else:
        assert rep["dtn.delivery_ratio"] == 1.0 and rep["dtn.delivered_within_ttl_ratio"] == 1.0
        assert sf <= rep["dtn.latency_s.mean"] and rep["dtn.latency_s.mean"] > 2.5 * bound


def test_cli_deadline_queue_changes_the_order(tmp_path, capsys):
    """`constellation dtn --queue deadline` on the drawn chain: sat_11 holds a P9 for sat_13 while a
    stream of P1s arrives; with strict priority the P9 goes last, with the deadline queue (earliest
    expiry first; equal TTLs here) it goes before every P1 created after it."""
    import json

    from bringup.cli.main import main
    from orbit_clock.contact_plan_io import write_contact_plan
    with open(tmp_path / "plan.csv", "w") as fh:
        write_contact_plan(PLAN, "csv", fh)
    head = "source,time_s,packet_id,region," + ",".join(f"Sat{p}{s}" for p in (1,) for s in (1, 2, 3))
    # a P1 takes the radio at 10 s (to 12 s); the P9 created then waits; P1s keep coming every second
    rows = ["Sat11,10,1,r,0,-1,1", "Sat11,10,2,r,0,-1,9"] + [f"Sat11,{t},{k},r,0,-1,1" for k, t in
                                                              enumerate(range(11, 31), start=3)]
    (tmp_path / "traffic.csv").write_text("\n".join([head] + rows) + "\n")
    med = {}
    for q in ("priority", "deadline"):
        assert main(["dtn", "--contact-plan", str(tmp_path / "plan.csv"), "--traffic", str(tmp_path / "traffic.csv"),
                     "--ttl-s", "1:100,15:100", "--queue", q, "--json"]) == 0
        rep = json.loads(capsys.readouterr().out)
        assert rep["dtn.delivery_ratio"] == 1.0 and rep["dtn.conservation_ok"]
        assert 0 < rep["dtn.latency_s.store_forward_bound_mean"] <= rep["dtn.latency_s.mean"]
        med[q] = rep["dtn.latency_s_by_priority.9.median"]
    # strict: the P9 waits for all 20 P1s (~40 s on air); deadline: equal TTLs, so it goes first by age
    assert med["priority"] > 40 and med["deadline"] < 10, med
    # the P9 living three times as long as the P1s: earliest expiry sends it after every P1 (its
    # deadline 310 s, theirs 110-130 s); fifo ignores priority and TTL: the oldest goes first
    for q in ("deadline", "fifo"):
        assert main(["dtn", "--contact-plan", str(tmp_path / "plan.csv"), "--traffic", str(tmp_path / "traffic.csv"),
                     "--ttl-s", "1:100,15:300", "--queue", q, "--json"]) == 0
        rep = json.loads(capsys.readouterr().out)
        assert rep["dtn.delivery_ratio"] == 1.0 and rep["dtn.conservation_ok"]
        med[q] = rep["dtn.latency_s_by_priority.9.median"]
    assert med["deadline"] > 40 and med["fifo"] < 10, med


def test_policy_config_names_what_is_wrong():
    from sat_node.dtn.agent import AgentConfig, deadline_delays

    cfg = AgentConfig.for_policy("deadline", 12.5, ttl_s_by_priority={1: 100.0, 15: 300.0}, bundle_bits=800,
                                 key=TEST_BPSEC_KEY)
    assert cfg.priority_delay_s == deadline_delays({1: 100.0, 15: 300.0}) == (100.0,) + (300.0,) * 14
    assert cfg.hop_tolerance_s == 12.5 and cfg.bundle_bits == 800
    assert AgentConfig.for_policy(key=TEST_BPSEC_KEY).priority_delay_s is None
    assert AgentConfig.for_policy("fifo", key=TEST_BPSEC_KEY).priority_delay_s == (0.0,) * 15
    with pytest.raises(ValueError, match="send order 'lifo'"):
        AgentConfig.for_policy("lifo", key=TEST_BPSEC_KEY)
    for bad in (-1.0, float("nan")):
        with pytest.raises(ValueError, match="hop tolerance"):
            AgentConfig.for_policy("priority", bad, key=TEST_BPSEC_KEY)


def test_cli_hop_tolerance_takes_the_direct_contact(tmp_path, capsys):
    """`constellation dtn --hop-tolerance-s`: a bundle created at 10 s at sat_11 for sat_13 reaches it
    over the chain at 15 s (10-12 on air, +0.5, 12.5-14.5, +0.5: 5 s, two transmissions) or over a
    direct contact opening at 50 s (50-52, +0.5: 42.5 s, one), which arrives 37.5 s after the chain:
    a 40 s tolerance takes it, 30 s keeps the chain. A negative tolerance is one clear error line."""
    import json

    from bringup.cli.main import main
    from orbit_clock.contact_plan_io import write_contact_plan
    plan = ContactPlan(PLAN.contacts + [Contact(50.0, 1000.0, "sat_11", "sat_13", 1000.0, 0.5)])
    with open(tmp_path / "plan.csv", "w") as fh:
        write_contact_plan(plan, "csv", fh)
    head = "source,time_s,packet_id,region,Sat11,Sat12,Sat13"
    (tmp_path / "traffic.csv").write_text(f"{head}\nSat11,10,1,r,0,-1,4\n")
    argv = ["dtn", "--contact-plan", str(tmp_path / "plan.csv"), "--traffic", str(tmp_path / "traffic.csv"), "--json"]
    got = {}
    for tol in (0.0, 30.0, 40.0):
        assert main(argv + ["--hop-tolerance-s", str(tol)]) == 0
        rep = json.loads(capsys.readouterr().out)
        assert rep["dtn.delivery_ratio"] == 1.0 and rep["dtn.conservation_ok"]
        got[tol] = rep["dtn.latency_s.mean"]
    assert got == pytest.approx({0.0: 5.0, 30.0: 5.0, 40.0: 42.5}), got
    assert main(argv + ["--hop-tolerance-s", "-5"]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--hop-tolerance-s" in err[0] and "must be >= 0" in err[0], err


def test_route_memo_equals_fresh_queries(paper_inputs, monkeypatch):
    """The agent's route memos (per bundle, and shared by bundles that route alike at one instant,
    sat_node/dtn/agent.py _route) hand out exactly what a fresh CGR query with the bundle's own
    deadline returns: checked on every route of the first 1500 bundles of case4."""
    import numpy as np

    from sat_node.dtn.agent import BundleAgent

    plan = read_contact_plan(paper_inputs / "contact_plan_3p_8s.csv", rate_bps=1000)
    traffic = read_traffic(paper_inputs / "traffic_case4.csv")[:1500]
    orig = BundleAgent._route
    n = {"calls": 0, "shared": 0}

    def checked(self, h, t_ns):
        before = self.graph._qid
        r = orig(self, h, t_ns)
        n["calls"] += 1
        n["shared"] += self.graph._qid == before and h.route_memo is not None
        fb = None
        if self._parked:
            fb = self.graph._no_backlog.copy()
            for c, byp in self._parked.items():
                if sum(byp[: h.priority + 1]) > 0:
                    fb[c] = sum(byp[: h.priority + 1])
        excluded = None
        if h.excluded:
            excluded = np.zeros(len(self.graph.contacts), dtype=np.bool_)
            excluded[list(h.excluded)] = True
        fresh = self.graph.route(self.node, h.dest, t_ns / 1e9, h.bits, deadline_s=h.expiry_ns / 1e9,
                                 excluded=excluded, excluded_nodes=(h.excluded_node,) if h.excluded_node else (),
                                 first_backlog_bits=fb)
        assert r == fresh, (self.node, h.bundle.bundle_id, t_ns)
        return r

    monkeypatch.setattr(BundleAgent, "_route", checked)
    run = run_dtn(plan, traffic)
    assert run.report(None)["dtn.conservation_ok"]
    assert n["calls"] > 3000 and n["shared"] > 100, n


def test_cli_forwarding_multicast_on_the_chain(tmp_path, capsys):
    """`constellation dtn --forwarding multicast`: one observation of sat_11 for sat_12 (P1) and sat_13
    (P2) on the chain: one bundle, one transmission to sat_12 (the next hop of both), which delivers
    its own copy and relays sat_13's: 2 transmissions where unicast takes 3 (sat_13's bundle is sent
    twice). Latencies: the recipient list makes the first copy longer than 2 s."""
    import json

    from bringup.cli.main import main
    from orbit_clock.contact_plan_io import write_contact_plan
    with open(tmp_path / "plan.csv", "w") as fh:
        write_contact_plan(PLAN, "csv", fh)
    (tmp_path / "traffic.csv").write_text("source,time_s,packet_id,region,Sat11,Sat12,Sat13\nSat11,10,1,r,0,1,2\n")
    argv = ["dtn", "--contact-plan", str(tmp_path / "plan.csv"), "--traffic", str(tmp_path / "traffic.csv"), "--json"]
    rep = {}
    for fwd in ("unicast", "multicast"):
        assert main(argv + ["--forwarding", fwd]) == 0
        rep[fwd] = json.loads(capsys.readouterr().out)
        r = rep[fwd]
        assert r["dtn.forwarding"] == fwd and r["dtn.conservation_ok"] and r["dtn.delivered_within_ttl_ratio"] == 1.0
        assert r["dtn.bundles_created"] == 2 and r["dtn.observations"] == 1
        assert r["dtn.latency_s.floor_mean"] == pytest.approx((2.5 + 5.0) / 2)
        assert r["dtn.latency_s.floor_mean"] <= r["dtn.latency_s.store_forward_bound_mean"] <= r["dtn.latency_s.mean"]
    u, m = rep["unicast"], rep["multicast"]
    assert (u["dtn.transmissions"], m["dtn.transmissions"]) == (3, 2)
    assert (u["dtn.bundles_originated"], m["dtn.bundles_originated"]) == (2, 1)
    assert u["dtn.latency_s_by_priority.1.median"] == pytest.approx(2.5)
    assert 2.5 < m["dtn.latency_s_by_priority.1.median"] < 2.8  # + the list of two recipients on air
    assert m["dtn.latency_s_by_priority.2.median"] < u["dtn.latency_s_by_priority.2.median"]  # 7 s unicast
    assert m["dtn.bits_on_air"] > 2 * 2000 and u["dtn.bits_on_air"] == 3 * 2000


@pytest.mark.parametrize("case, pairs, observations", [
    ("case4", 7430, 1228), pytest.param("case1", 52413, 7632, marks=pytest.mark.slow)])
def test_study_inputs_multicast_targets(paper_inputs, case, pairs, observations):
    """The issue's targets on the study's inputs at 1 kb/s with multicast forwarding: >= 99.5 % of the
    pairs within their TTL, mean <= 10 s (and above the any-policy floor), priority 1 p95 <= 10 s, no
    priority 1-6 pair lost, every pair accounted for."""
    from bringup.analysis.dtn_bounds import floor_mean
    from sat_node.dtn.agent import AgentConfig

    plan = read_contact_plan(paper_inputs / "contact_plan_3p_8s.csv", rate_bps=1000)
    traffic = read_traffic(paper_inputs / f"traffic_{case}.csv")
    cfg = AgentConfig(key=TEST_BPSEC_KEY, forwarding="multicast")
    run = run_dtn(plan, traffic, config=cfg)
    rep = run.report()
    assert rep["dtn.conservation_ok"] and rep["dtn.bundles_created"] == pairs and rep["dtn.dropped.integrity"] == 0
    assert rep["dtn.bundles_originated"] == rep["dtn.observations"] == observations
    assert rep["dtn.delivered_within_ttl_ratio"] >= 0.995
    assert floor_mean(plan, traffic, 2000, cfg.ttl_s_by_priority) <= rep["dtn.latency_s.mean"] <= 10.0
    assert rep["dtn.latency_s_by_priority.1.p95"] <= 10.0
    for p in range(1, 7):
        assert rep[f"dtn.latency_s_by_priority.{p}.count"] == rep[f"dtn.latency_s_by_priority.{p}.created"]
    assert rep["dtn.transmissions_per_observation"] < 7  # unicast: 14.3 (case4), 15.8 (case1)


def test_report_does_not_depend_on_event_order():
    """Two engines interleave same-time events differently; the dtn.* figures must not follow: a
    thousand deliveries with latencies chosen so that the order of a float sum shows (1e6 s beside
    fractions of a second), the events shuffled ten times - the same report, bit for bit. The first
    shuffle's plain numpy mean in event order differs from the sorted one (the oracle that order
    matters here)."""
    import numpy as np

    from sat_node.dtn.agent import BundleEvent
    from sat_node.dtn.stats import dtn_report

    rng = random.Random(3)
    events = []
    for i in range(1000):
        created = rng.randrange(0, 10**12)
        lat_ns = rng.choice([10**15, 1, 123456789, 7 * 10**9 + 1])
        dest = f"sat_{rng.randrange(11, 99)}"
        events.append(BundleEvent(created, "created", "sat_11", f"b{i}", 1 + i % 15, dest, created))
        events.append(BundleEvent(created + lat_ns, "delivered", dest, f"b{i}", 1 + i % 15, dest, created))
    ref = dtn_report(events)
    orders_differ = False
    for _ in range(10):
        rng.shuffle(events)
        assert dtn_report(events) == ref
        lat = [(e.t_ns - e.created_ns) / 1e9 for e in events if e.kind == "delivered"]
        orders_differ |= float(np.mean(lat)) != ref["dtn.latency_s.mean"]
    assert orders_differ


def test_cli_epoch_sets_bundle_creation_times(tmp_path, capsys):
    """`constellation dtn --epoch`: the bundles' creation times are DTN time (ms since
    2000-01-01T00:00:00Z, RFC 9171 4.2.6) of the scenario clock; the default is the study's epoch."""
    import json
    from datetime import UTC, datetime

    from bringup.cli.main import main
    from orbit_clock.contact_plan_io import write_contact_plan
    from sat_node.dtn.bpv7 import PAPER_EPOCH_DTN_MS, decode_bundle
    with open(tmp_path / "plan.csv", "w") as fh:
        write_contact_plan(PLAN, "csv", fh)
    head = "source,time_s,packet_id,region,Sat11,Sat12,Sat13"
    (tmp_path / "traffic.csv").write_text(f"{head}\nSat11,10,1,r,0,-1,1\nSat11,20.5,2,r,0,-1,1\n")
    epoch_ms = int((datetime(2026, 11, 27, 12, tzinfo=UTC) - datetime(2000, 1, 1, tzinfo=UTC)).total_seconds()) * 1000
    created = {}
    for name, extra, zero in (("default", [], PAPER_EPOCH_DTN_MS), ("later", ["--epoch", "2026-11-27T12:00:00Z"],
                                                                  epoch_ms)):
        dump = tmp_path / name
        assert main(["dtn", "--contact-plan", str(tmp_path / "plan.csv"), "--traffic", str(tmp_path / "traffic.csv"),
                     "--json", "--dump-bundles", str(dump), *extra]) == 0
        assert json.loads(capsys.readouterr().out)["dtn.delivery_ratio"] == 1.0
        created[name] = sorted(decode_bundle(f.read_bytes()).creation_ms - zero for f in dump.glob("*.bpv7"))
    assert created["default"] == created["later"] == [10_000, 20_500]


@pytest.mark.parametrize("seed", range(6))
def test_hops_within_ttl_and_earliest_arrivals_against_plain_searches(seed):
    """The bounds' inputs on random plans (sparse, short contacts: many nodes unreachable within a
    TTL) and unsorted traffic, against searches written plainly: each item's fewest hops from a
    breadth-first search over the contacts open within its window, looked at one by one (no window or
    source shared), and the one-to-all earliest arrival against one CGR route query per destination
    (full volumes, no backlog: the same earliest arrival)."""
    from bringup.analysis.dtn_bounds import hops_within_ttl
    from sat_node.dtn.agent import ttl_s_for_priority
    from sat_node.dtn.cgr import ContactGraph
    rng = random.Random(100 + seed)
    nodes = [f"sat_{p}{s}" for p in (1, 2, 3) for s in (1, 2, 3)]
    contacts = []
    for _ in range(40):
        a, b = rng.sample(nodes, 2)
        t0 = rng.uniform(0, 3000)
        contacts.append(Contact(t0, t0 + rng.uniform(5, 400), a, b, 1000.0, rng.uniform(0.01, 0.2)))
    plan = ContactPlan(contacts)
    times = [round(rng.uniform(0, 3000), 1) for _ in range(6)]
    traffic = [TrafficItem(rng.choice(times), src, dst, rng.randint(1, 15), f"p{k}", "r", k)
               for k in range(120) for src, dst in [rng.sample(nodes, 2)]]
    ttl = {1: 300.0, 3: 900.0, 15: 2000.0}

    def plain_hops(item):
        w = ttl_s_for_priority(item.priority, ttl)
        open_ = [c for c in plan.contacts if c.start_s < item.t_s + w and c.end_s > item.t_s]
        hops, level = {item.source: 0}, 0
        while True:
            nxt = {c.dst for c in open_ if hops.get(c.src) == level and c.dst not in hops}
            if not nxt:
                return hops.get(item.dest, -1)
            level += 1
            hops.update(dict.fromkeys(nxt, level))

    got = hops_within_ttl(plan, traffic, ttl)
    assert got == [plain_hops(it) for it in traffic]
    assert any(h < 0 for h in got) and any(h > 1 for h in got)  # both cases occur
    g = ContactGraph(plan)
    for src in nodes:
        for t in times:
            ea = g.earliest_arrivals(src, t, 2000)
            for d in nodes:
                r = None if d == src else g.route(src, d, t, 2000)
                assert ea.get(d) == (None if r is None else r.arrival_s), (src, t, d)


def test_cyclic_collector_off_during_the_run_only():
    """run_dtn turns the cyclic garbage collector off for the run (bringup/analysis/dtn_alone.py) and
    leaves it as it found it: on after the run when it was on, off when it was off."""
    import gc

    from sat_node.dtn.agent import AgentConfig
    seen = []
    traffic = [TrafficItem(10.0, "sat_11", "sat_13", 1, "p1", "r", 2)]
    assert gc.isenabled()
    run = run_dtn(PLAN, traffic, config=AgentConfig(key=TEST_BPSEC_KEY), sink=lambda env: seen.append(gc.isenabled()))
    assert seen and not any(seen)
    assert gc.isenabled()
    assert run.report()["dtn.bundles_delivered"] == 1
    gc.disable()
    try:
        run_dtn(PLAN, traffic, config=AgentConfig(key=TEST_BPSEC_KEY))
        assert not gc.isenabled()
    finally:
        gc.enable()
