"""scheduler.replan_trigger: "periodic" replans only every replan_period_s (the study's scheme),
"news" also as soon as delivered news makes a planned look worthless (sat_node/satellite.py).

Oracle: the planning times of every schedule a satellite publishes in a distributed local-engine run
(24 satellites, 2 h, each planning alone so that their plans overlap and news matters; the paper
scenario otherwise). Periodic: every one on the period's grid from
the start. News: the same periodic ones, and some between them - each shortly after a bundle was delivered
to that satellite.
"""

from __future__ import annotations

import msgspec
import pytest

from bringup.engine.local import run_local
from bringup.scenario.participants import all_participants
from bringup.scenario.world import World
from msgs_json import codec
from msgs_json import schemas as S
from tests.keys import TEST_BPSEC_KEY

_NS = 1_000_000_000


def _run(sc, trigger: str):
    sc = msgspec.structs.replace(sc, scheduler=msgspec.structs.replace(sc.scheduler, replan_trigger=trigger))
    world = World.build(sc)
    res = run_local(all_participants(world, "distributed", bpsec_key=TEST_BPSEC_KEY), horizon_ns=sc.horizon_ns,
                    max_step_ns=int(sc.scenario.lockstep_max_step_s * 1e9))
    planned, delivered = [], set()
    for e in res.envelopes:
        if e.topic.endswith("/schedule"):
            m = codec.decode(e.topic, e.data)
            planned.append((m.sat, m.planned_ns))
        elif e.topic.endswith("/dtn/events"):
            m = codec.decode(e.topic, e.data)
            if isinstance(m, S.BundleDelivered):
                delivered.add((m.sat, m.t_ns))
    return planned, delivered


@pytest.fixture(scope="module")
def runs(paper_scenario):
    sc = paper_scenario.with_overrides(sats=24, hours=2, joint_planning=False)
    assert sc.scheduler.replan_trigger == "news"  # the paper scenario's
    return {t: _run(sc, t) for t in ("periodic", "news")}, round(sc.scheduler.replan_period_s * _NS)


def test_periodic_replans_only_on_the_period(runs):
    by, period = runs
    planned, delivered = by["periodic"]
    assert delivered  # news did arrive
    assert len(planned) == 24 * 12  # 0, 600, ..., 6600 s for each satellite
    assert all(t % period == 0 for _sat, t in planned)


def test_news_replans_between_periods_when_a_bundle_arrives(runs):
    by, period = runs
    planned, delivered = by["news"]
    on_grid = [(s, t) for s, t in planned if t % period == 0]
    off = [(s, t) for s, t in planned if t % period]
    assert len(on_grid) == 24 * 12
    assert off, "no replan for news in 24 satellites x 2 h"
    # a satellite replans for news only shortly after something was delivered to it (the delivery
    # is stamped with its time on the link; the satellite reads it at a later lockstep step)
    for s, t in off:
        assert any(d == s and t - 60 * _NS <= dt <= t for d, dt in delivered), (s, t)
