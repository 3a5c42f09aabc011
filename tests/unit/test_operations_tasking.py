"""Tasking requests (sat_node/operations/tasking.py): the target as a new GP of interest of the planner.

Oracles: the nearest ground point against a brute-force scan with another distance formula (the
chord between unit vectors, turned into an arc); the overlay on a hand-built value matrix; the
fulfilment rule on hand-made observations; and the peek test - two identical satellites of one
world, only one of which executed the signed task command, plan differently: the one that received
it plans the target, the other never does.
"""

from __future__ import annotations

import math

import msgspec
import numpy as np
import pytest

from bringup.scenario.config import _validate, load_scenario
from msgs_json import codec
from msgs_json import schemas as S
from msgs_json import topics as T
from msgs_json.envelope import Envelope
from sat_node.operations.commands import (
    Command,
    CommandRejected,
    check_args,
    encode_command,
    satellite_command_key,
)
from sat_node.operations.tasking import TASK_VALUE, Task, TaskBook, nearest_gp
from tests.keys import TEST_BPSEC_KEY

_NS = 1_000_000_000
GROUND_KEY = bytes(range(100, 132))


def test_nearest_gp_against_a_chord_scan():
    rng = np.random.default_rng(7)
    lat = rng.uniform(-60, 60, 500)
    lon = rng.uniform(-180, 180, 500)
    for _ in range(50):
        p, q = float(rng.uniform(-60, 60)), float(rng.uniform(-180, 180))
        i, d = nearest_gp(lat, lon, p, q)

        def unit(a, b):
            a, b = np.radians(a), np.radians(b)
            return np.stack([np.cos(a) * np.cos(b), np.cos(a) * np.sin(b), np.sin(a)], axis=-1)

        chord = np.linalg.norm(unit(lat, lon) - unit(p, q), axis=-1)
        arc = 2 * 6371.0088 * np.arcsin(chord / 2)
        assert i == int(np.argmin(arc)) and d == pytest.approx(float(arc.min()), rel=1e-9, abs=1e-6)


def test_overlay_floors_the_owners_value_and_reserves_it_from_partners():
    book = TaskBook()
    book.add(Task("c1", gp=7, priority=2, by_ns=30 * _NS, issued_ns=0, executed_ns=5 * _NS))
    book.add(Task("c2", gp=9, priority=1, by_ns=100 * _NS, issued_ns=0, executed_ns=5 * _NS))
    ov = book.overlay("sat_11", 10 * _NS)
    ids = np.array([3, 7, 9])
    times = np.array([10.0, 20.0, 30.0, 40.0])
    base = np.array([[5.0, 600.0, 1.0]] * 4)
    got = ov.apply("sat_11", ids, times, base)
    want = base.copy()
    want[:3, 1] = 600.0  # already worth more than priority 2's 512: kept
    want[:, 2] = TASK_VALUE[1]  # priority 1 to 100 s
    assert np.array_equal(got, want)
    got = ov.apply("sat_11", ids, times, np.array([5.0, 1.0, 1.0]))  # (G,): spread over the window
    assert got.shape == (4, 3) and list(got[:, 1]) == [512.0, 512.0, 512.0, 1.0]
    partner = ov.apply("sat_12", ids, times, base)
    assert list(partner[:, 1]) == [0.0, 0.0, 0.0, 600.0] and list(partner[:, 2]) == [0.0] * 4
    assert np.array_equal(partner[:, 0], base[:, 0])
    same = base[:, :2]
    assert ov.apply("sat_11", np.array([1, 2]), times, same) is same  # no tasked GP: untouched
    assert book.overlay("sat_11", 101 * _NS) is None  # past every deadline


def test_a_task_is_fulfilled_by_a_look_after_its_issue_only():
    book = TaskBook()
    book.add(Task("c1", gp=7, priority=1, by_ns=100 * _NS, issued_ns=20 * _NS, executed_ns=30 * _NS))
    book.observed(7, 10 * _NS, "sat_12")  # before the issue: not for this task
    book.observed(8, 40 * _NS, "sat_12")  # another GP
    assert book.open_at(40 * _NS)
    book.observed(7, 50 * _NS, "sat_12")
    assert book.tasks[0].done_ns == 50 * _NS and book.tasks[0].done_by == "sat_12"
    assert book.open_at(50 * _NS) == [] and book.overlay("sat_11", 50 * _NS) is None


def _task_cmd(cid="t1", sat="sat_24", **args):
    a = {"lat_deg": 10.0, "lon_deg": 20.0, "priority": 1, "by_ns": 100} | args
    return Command(cid, 1, sat, "task", a, 10, 1000)


@pytest.mark.parametrize("args", [{"priority": 0}, {"priority": True}, {"lat_deg": 95.0}, {"lon_deg": "x"},
                                  {"by_ns": 5}, {"by_ns": 1.5}, {"extra": 1}])
def test_bad_task_args_are_malformed(args):
    with pytest.raises(CommandRejected, match="malformed"):
        check_args(_task_cmd(**args))


@pytest.fixture(scope="module")
def world():
    from bringup.scenario.world import World

    raw = msgspec.to_builtins(load_scenario("paper").with_overrides(sats=12, hours=0.5))
    raw.pop("source_path", None)
    raw["commands"] = [{"sat": "sat_24", "kind": "mode", "mode": "nominal", "at_s": 1.0}]  # a guard in each
    return World.build(_validate(raw, "<test>"))


def _sat(world, name="sat_24"):
    from sat_node.satellite import SatelliteLogic

    return SatelliteLogic(world, name, "distributed", bpsec_key=TEST_BPSEC_KEY,
                          command_key=satellite_command_key(GROUND_KEY, name))


def _planned(sat) -> set[int]:
    return {it.gp for it in sat.plan}


def test_only_the_satellite_that_received_the_task_plans_the_target(world):
    """The peek test: the same satellite twice; only ``told`` gets the signed task (as the ground
    gateway uplinks it, GroundCommand on /ground/commands). The target is a GP the satellite can see
    in its first window but does not plan on its own."""
    told, blind = _sat(world), _sat(world)
    told.start(0)
    blind.start(0)
    planned = _planned(blind)
    assert _planned(told) == planned  # the same satellite, the same plan
    p = world.planner
    inst = p.instance("sat_24", 0.0, blind.kstate.knowledge(
        world.osse, world.gps.region_index, world.gps.ecef_km, 0.0, blind.known, blind.belief),
        window_s=world.scenario.scheduler.plan_lookahead_s)
    seen = inst.in_for.sum(axis=0)
    cands = [(int(n), int(g)) for g, n in zip(inst.gp_ids, seen) if int(g) not in planned and n >= 5]
    assert cands, "no visible GP left unplanned in the first window"
    _n, gp = max(cands)
    lat, lon = float(world.gps.lat_deg[gp]), float(world.gps.lon_deg[gp])
    t = 30 * _NS
    cmd = Command("t1", 1, "sat_24", "task", {"lat_deg": lat, "lon_deg": lon, "priority": 1, "by_ns": 1800 * _NS},
                  20 * _NS, 3600 * _NS)
    text = encode_command(cmd, satellite_command_key(GROUND_KEY, "sat_24")).decode()
    up = S.GroundCommand(relay="sat_24", station="gs_svalbard", t_ns=t, payload=text)
    env = Envelope(t, "commander", 1, T.GROUND_COMMANDS, codec.encode(up))
    r_told = told.step(t, [env])
    blind.step(t, [])
    events = [codec.decode(e.topic, e.data) for e in r_told.emits if e.topic == T.ops_command_topic("sat_24")]
    assert [(e.stage, e.command_id) for e in events] == [("received", "t1"), ("executed", "t1")]
    assert told.tasks.tasks[0].gp == gp
    assert gp in _planned(told)  # replanned at once with the target in
    assert gp not in _planned(blind)
    blind._replan(t)  # replanned at the same time, without the command: still not
    assert gp not in _planned(blind)
    # a task signed under the BPSec key (which every satellite holds) is forged: no task, no target
    third = _sat(world)
    third.start(0)
    bad = encode_command(cmd, TEST_BPSEC_KEY).decode()
    env = Envelope(t, "commander", 1, T.GROUND_COMMANDS,
                   codec.encode(S.GroundCommand(relay="sat_24", station="gs_svalbard", t_ns=t, payload=bad)))
    third.step(t, [env])
    assert third.tasks.tasks == [] and third.guard.rejected == {"forged": 1} and gp not in _planned(third)
    assert math.isfinite(told.plan[0].value)
