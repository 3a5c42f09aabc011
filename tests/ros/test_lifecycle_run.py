"""Managed lifecycle on a live ROS run (bringup/engine/ros/lifecycle_manager.py, host.py).

Oracles written by others: rcl_lifecycle's state machine behind rclpy's LifecycleNode, read through
the standard lifecycle services by an independent rclpy client of the test (lifecycle_msgs
GetState / GetAvailableTransitions), and the local engine's envelopes for the same toy run.
- Every participant node of a launched run is ``active`` while the run goes on (get_state), its
  available transitions are the shared table's (bringup/engine/lifecycle.py ``available``), and the
  run's bag equals the local engine's envelopes (the life cycle changes nothing in the results).
- A node whose configure fails is named by the launcher with its process and the transition, the
  run stops, and no process of the run is left: a toy participant whose build raises, and a real
  satellite of the scenario factory whose bundle store cannot be opened (its path is a folder).
"""

from __future__ import annotations

import os
import threading
import time
from pathlib import Path

import pytest

from bringup.engine.lifecycle import ACTIVE, available
from bringup.engine.local import run_local
from bringup.engine.ros.launcher import launch, lease_domain_id
from bringup.engine.ros.run_spec import RunSpec
from bringup.recording.bag import BagReader
from tests.ros import toy_participants as toy

pytestmark = [pytest.mark.ros, pytest.mark.timeout(240)]
S = 10**9


def _alive(pids: list[int]) -> list[int]:
    out = []
    for pid in pids:
        try:
            st = Path(f"/proc/{pid}/stat").read_text().split()
        except OSError:
            continue
        if st[2] != "Z":
            out.append(pid)
    return out


def _pids(run_dir: Path) -> list[int]:
    return [int(p.read_text()) for p in (run_dir / "logs").glob("*.pid")]


def _client_states(domain_id: int, names: list[str], stop: threading.Event, out: dict) -> None:
    """An rclpy client of the test's own: each node's state (get_state) and available transitions
    while the run goes on, read once each node answers ``active``."""
    import rclpy
    from lifecycle_msgs.srv import GetAvailableTransitions, GetState
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    ctx = Context()
    rclpy.init(context=ctx, domain_id=domain_id, signal_handler_options=SignalHandlerOptions.NO)
    try:
        node = rclpy.create_node("test_lifecycle_client", context=ctx, start_parameter_services=False)
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(node)
        for name in names:
            get = node.create_client(GetState, f"/{name}/get_state")
            avail = node.create_client(GetAvailableTransitions, f"/{name}/get_available_transitions")
            while not stop.is_set():
                if get.service_is_ready() and avail.service_is_ready():
                    fut = get.call_async(GetState.Request())
                    ex.spin_until_future_complete(fut, timeout_sec=5.0)
                    if fut.done() and fut.result().current_state.label == ACTIVE:
                        tr = avail.call_async(GetAvailableTransitions.Request())
                        ex.spin_until_future_complete(tr, timeout_sec=5.0)
                        out[name] = (ACTIVE, [t.transition.label for t in tr.result().available_transitions])
                        break
                ex.spin_once(timeout_sec=0.05)
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=ctx)


def test_every_node_is_active_during_the_run_and_the_results_stand(tmp_path):
    n = 3
    extra = {"n_counters": n, "period_s": 5.0}
    roles = toy.roles(n, pingpong=False)
    spec = RunSpec(factory="tests.ros.toy_participants:make_deferred", roles=roles, horizon_ns=600 * S,
                   max_step_ns=10 * S, real_time_factor=60.0, bag_dir=str(tmp_path / "bag"), extra=extra)
    lease = lease_domain_id()
    states: dict = {}
    stop = threading.Event()
    reader = threading.Thread(target=_client_states, args=(lease.domain_id, roles, stop, states), daemon=True)
    reader.start()
    try:
        res = launch(spec, tmp_path / "run", domain_id=lease.domain_id)
    finally:
        stop.set()
        reader.join(timeout=30)
        lease.release()
    assert res.ok, res.message
    # an independent client saw every participant node active, with rcl_lifecycle's transitions
    assert set(states) == set(roles), states
    for name in roles:
        assert states[name] == (ACTIVE, available(ACTIVE)), (name, states[name])
    # the run's envelopes are the local engine's (the same toy participants, built eagerly)
    local = run_local([toy.make(spec, r, host=False)[0] for r in roles], horizon_ns=600 * S, max_step_ns=10 * S)
    with BagReader(tmp_path / "bag") as bag:
        got = [(e.t_ns, e.source, e.seq, e.topic, e.data)
               for e in bag.envelopes([t.topic for t in bag.topics() if t.topic.startswith("/toy/")])]
    want = [(e.t_ns, e.source, e.seq, e.topic, e.data) for e in local.envelopes]
    assert got and sorted(got) == sorted(want)
    # the nodes were shut down through deactivate -> cleanup -> shutdown (their hosts ended 0)
    assert not _alive(_pids(tmp_path / "run"))


def test_node_that_fails_configure_is_named_and_every_process_ends(tmp_path):
    roles = toy.roles(3, pingpong=False)
    spec = RunSpec(factory="tests.ros.toy_participants:make_deferred", roles=roles, horizon_ns=600 * S,
                   max_step_ns=10 * S, bag_dir=str(tmp_path / "bag"),
                   extra={"n_counters": 3, "fail_configure": "c1"})
    t0 = time.monotonic()
    res = launch(spec, tmp_path / "run")
    assert not res.ok
    assert "node /c1 (process c1) failed lifecycle transition 'configure' in state 'unconfigured'" in res.message
    assert "toy: c1 cannot open its store" in res.message  # the cause, from the process's log
    assert "\n" not in res.message
    assert "c1" in res.failed_roles
    assert time.monotonic() - t0 < 120
    assert not _alive(_pids(tmp_path / "run")), "a process of the run outlived it"
    assert not any(p.exists() for p in [tmp_path / "run" / "run.keys"])
    assert os.path.isdir(tmp_path / "run" / "logs")


def test_satellite_whose_store_cannot_open_fails_configure_named(tmp_path):
    """The scenario's own factory: a satellite builds its bundle store in on_configure; a store path
    that is a folder (SQLite cannot open it) fails that node's configure, and the run stops naming it."""
    from bringup.engine.ros.factory import FACTORY
    from bringup.scenario.config import load_scenario
    from bringup.scenario.participants import roles_for
    from bringup.scenario.world import World

    sc = load_scenario("paper").with_overrides(sats=3, hours=0.1)
    world = World.build(sc)
    world_path = world.save(tmp_path / "world.pkl")
    store = tmp_path / "store"
    victim = world.sat_names[1]
    (store / f"{victim}.sqlite").mkdir(parents=True)  # where its store file would be
    spec = RunSpec(factory=FACTORY, roles=roles_for(world, "distributed"), scenario=str(Path(sc.source_path).resolve()),
                   overrides={"sats": 3, "hours": 0.1}, mode="distributed", startup_timeout_s=None,
                   extra={"world": str(world_path.resolve()), "world_key": world.key, "store_dir": str(store)})
    res = launch(spec, tmp_path / "run")
    assert not res.ok
    assert res.message.startswith(f"node /{victim}/{victim} (process {victim}) failed lifecycle transition "
                                  "'configure' in state 'unconfigured'; the run stopped: "
                                  f"host {victim}: error: node {victim}: transition 'configure' failed: "), res.message
    assert victim in res.failed_roles and "\n" not in res.message
    assert not _alive(_pids(tmp_path / "run")), "a process of the run outlived it"
