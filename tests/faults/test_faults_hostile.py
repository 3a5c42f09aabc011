"""Hostile input (issue 7): fuzzed JSON, mutated BPv7 bytes and wrong-key BPSec bundles on every
input topic of every participant, injected by a rogue participant on the local engine's bus (which,
unlike DDS under the lockstep host, delivers any source's envelopes to the logic, so every message
reaches the code under test).

Seeded fuzzer (random.Random(7)): per step, on each input topic (/sat_XX/dtn/in, /sat_XX/dtn/status,
/sat_XX/dtn/out read by the router): random bytes, random text, mutated golden JSON (byte flips,
truncation, wrong types), mutated real bundles (bit flips, truncation), and wrong-key BPSec bundles
(RFC 9173 BIB-HMAC-SHA2 with another key) addressed to the satellite as destination and next hop,
carrying a forged observation.
Oracles: the run completes (a participant exception would be an EngineError); the observations are
identical to the clean run (no forged news changed a plan); no forged bundle is delivered, queued or
forwarded; no forged observation is in any satellite's knowledge; every injected message is counted
as a rejection with a reason somewhere (satellite rejected_by_reason, agent dropped.integrity /
dropped.malformed-like counters, router rejected_by_reason) - injected == counted.
"""

from __future__ import annotations

import random

import pytest

from msgs_json import codec, schemas as S, topics as T
from msgs_json.envelope import Emit, StepResult
from tests.keys import TEST_BPSEC_KEY

pytestmark = [pytest.mark.faults, pytest.mark.system]

SATS, HOURS = 12, 1.0
FORGED_T_NS = 123_456_789  # the forged observations' time: no real observation has it


@pytest.fixture(scope="module")
def world():
    from bringup.scenario.config import load_scenario
    from bringup.scenario.world import World

    return World.cached(load_scenario("paper").with_overrides(sats=SATS, hours=HOURS, seed=1))


def _forged_bundle(target: str, claimed_src: str, gp: int, t_ns: int, seq: int) -> bytes:
    """A well-formed BPv7 bundle for ``target`` (destination and next hop), built as the agent builds
    one, with a BIB made with the wrong key and a forged observation as payload."""
    from orbit_clock.contact_plan import node_number
    from sat_node.dtn.agent import AgentConfig
    from sat_node.dtn.bpsec import add_bib
    from sat_node.dtn.bpv7 import Bundle, encode_bundle, ipn
    from sat_node.dtn.routing_blocks import set_routing
    from sat_node.inference import Inference, encode_inference

    cfg = AgentConfig(key=TEST_BPSEC_KEY)
    b = Bundle(dest=ipn(node_number(target), 1), src=ipn(node_number(claimed_src), 1),
               creation_ms=cfg.epoch_dtn_ms + t_ns // 1_000_000, seq=10_000 + seq, lifetime_ms=900_000,
               payload=encode_inference(Inference(claimed_src, gp, FORGED_T_NS, 99.0, 0)))
    set_routing(b, [(node_number(target), 1, 900_000)], {node_number(target): (node_number(target),)})
    b.hop_count = (cfg.hop_limit, 0)
    add_bib(b, b"not-the-constellation-key-000000", ipn(node_number(claimed_src), 0))
    return encode_bundle(b)


class Rogue:
    """A participant that only emits hostile envelopes (and counts what it sent, by kind)."""

    name = "rogue"

    def __init__(self, world, good_bundles: list[bytes], seed: int = 7, per_step: int = 3):
        self.sats = list(world.sat_names)
        self.horizon_ns = world.scenario.horizon_ns
        self.rng = random.Random(seed)
        self.good = good_bundles
        self.per_step = per_step
        self.sent: dict[str, int] = {}
        self.forged_ids: set[str] = set()
        self.goldens = [codec.encode(m) for m in (
            S.TransmissionFailed(sat="sat_11", t_ns=5, bundle_id="ipn:11.0/1/0", next_hop="sat_12", start_ns=1,
                                 reason="contact_ended"),
            S.DtnCounters(sat="sat_11", t_ns=1, counters={"a": 1}))]

    def subscriptions(self):
        return []

    def start(self, t0_ns):
        return StepResult([], None)

    def finish(self, t_ns):
        return []

    def _mutate(self, data: bytes) -> bytes:
        r = self.rng
        b = bytearray(data)
        kind = r.randrange(3)
        if kind == 0 and b:
            for _ in range(r.randint(1, 4)):
                i = r.randrange(len(b))
                b[i] ^= 1 << r.randrange(8)
        elif kind == 1 and b:
            b = b[: r.randrange(len(b))]
        else:
            b += bytes(r.randrange(256) for _ in range(r.randint(1, 8)))
        return bytes(b)

    def _one(self, t_ns: int) -> Emit:
        from sat_node.dtn.bpv7 import decode_bundle

        r = self.rng
        sat = r.choice(self.sats)
        kind = r.choice(["bytes", "text", "json", "bundle_mut", "forged", "forged", "status"])
        self.sent[kind] = self.sent.get(kind, 0) + 1
        if kind == "bytes":
            return Emit(r.choice([T.dtn_in_topic(sat), T.dtn_out_topic(sat)]), r.randbytes(r.randint(0, 64)), t_ns)
        if kind == "text":
            return Emit(r.choice([T.dtn_in_topic(sat), T.dtn_status_topic(sat)]),
                        "".join(chr(r.randrange(32, 0x2FF)) for _ in range(r.randint(0, 40))), t_ns)
        if kind == "json":
            g = r.choice(self.goldens).encode()
            return Emit(T.dtn_status_topic(sat), self._mutate(g).decode("utf-8", "replace"), t_ns)
        if kind == "status":  # well-formed status naming a transmission that never was
            m = S.TransmissionFailed(sat=sat, t_ns=t_ns, bundle_id=f"ipn:{r.randint(1, 99)}.0/{t_ns}/0",
                                     next_hop=r.choice(self.sats), start_ns=t_ns, reason="contact_ended")
            return Emit(T.dtn_status_topic(sat), codec.encode(m), t_ns)
        if kind == "bundle_mut":
            return Emit(r.choice([T.dtn_in_topic(sat), T.dtn_out_topic(sat)]), self._mutate(r.choice(self.good)), t_ns)
        src = r.choice([s for s in self.sats if s != sat])
        data = _forged_bundle(sat, src, r.randrange(100), t_ns, len(self.forged_ids))
        self.forged_ids.add(decode_bundle(data).bundle_id)
        return Emit(r.choice([T.dtn_in_topic(sat), T.dtn_out_topic(src)]), data, t_ns)

    def step(self, t_ns, inbox):
        if t_ns >= self.horizon_ns:  # emits of the last step are delivered to no one: send nothing
            return StepResult([], None)
        return StepResult([self._one(t_ns) for _ in range(self.per_step)], None)


def _run(world, rogue=None):
    from bringup.engine.local import run_local
    from bringup.scenario.participants import all_participants

    sc = world.scenario
    parts = all_participants(world, "distributed", bpsec_key=TEST_BPSEC_KEY)
    if rogue is not None:
        parts.append(rogue)
    res = run_local(parts, horizon_ns=sc.horizon_ns, max_step_ns=int(round(sc.scenario.lockstep_max_step_s * 1e9)))
    return parts, res.envelopes


def _obs(envs):
    return sorted((e.source, e.data) for e in envs if e.topic.endswith("/observations"))


def test_hostile_input_is_counted_and_never_acted_on(world):
    clean_parts, clean = _run(world)
    good = [e.data for e in clean if e.topic.endswith("/dtn/out")][:50]
    assert good, "the clean run must carry bundles to mutate"
    rogue = Rogue(world, good)
    parts, envs = _run(world, rogue)
    injected = sum(rogue.sent.values())
    assert injected > 500 and rogue.forged_ids
    # every node stayed up (run_local would have raised) and decided exactly as in the clean run
    assert _obs(envs) == _obs(clean)
    sats = [p for p in parts if p.name in world.sat_names]
    router = next(p for p in parts if p.name == "dtn_router")
    # no forged bundle acted on: never delivered, forwarded or held; no forged observation known
    for e in envs:
        if e.topic.endswith("/dtn/events"):
            m = codec.decode(e.topic, e.data)
            if m.bundle_id in rogue.forged_ids:
                assert isinstance(m, (S.BundleDropped, S.CopyDiscarded)), m
                if isinstance(m, S.BundleDropped):
                    assert m.reason == "integrity"
    for p in sats:
        assert not any(k.t_s * 1e9 == pytest.approx(FORGED_T_NS) for k in p.known)
        assert not (set(p.agent._held) & rogue.forged_ids)
    # the router forwarded nothing that did not come from a real satellite on its own topic:
    # every /dtn/in copy carries bytes some real satellite sent on /dtn/out
    sent_by_sats = {e.data for e in envs if e.topic.endswith("/dtn/out") and e.source != "rogue"}
    assert all(e.data in sent_by_sats for e in envs if e.topic.endswith("/dtn/in") and e.source == "dtn_router")
    # every injected message rejected with a reason, counted once
    sat_rej = sum(sum(p.rejected_by_reason.values()) for p in sats)
    agent_rej = sum(v for p in sats for k, v in p.agent.counters.items()
                    if k.startswith("dropped.") and k not in ("dropped.ttl", "dropped.no_route"))
    agent_disc = sum(p.agent.counters.get("discarded.not_next_hop", 0) - cp.agent.counters.get("discarded.not_next_hop", 0)
                     for p, cp in zip(sats, [q for q in clean_parts if q.name in world.sat_names]))
    router_rej = sum(router.rejected_by_reason.values())
    counted = sat_rej + agent_rej + agent_disc + router_rej
    print(f"injected {injected} {rogue.sent}; rejected: sats {sat_rej} agents {agent_rej} "
          f"(+{agent_disc} not-next-hop) router {router_rej} {router.rejected_by_reason}; forged {len(rogue.forged_ids)}")
    assert counted == injected
