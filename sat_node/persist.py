"""What a satellite knows, saved after every lockstep step and restored after a crash.

Pure module (no rclpy). A satellite process killed with SIGKILL and started again must go on as if
nothing happened: no observation executed twice, none lost, no accepted bundle lost. Two parts:

* the bundles it holds are rows of its persistent bundle store (sat_node/dtn/store.py, SQLite WAL);
* everything else (:func:`snapshot`): the scheduler's knowledge - known observations (own and
  delivered by DTN), the current plan and its version, the last executed observation time, the next
  replan time, the pointing target, counters - and the bundle agent's routing state (queues, parked
  groups, radio-free time, in-flight transmissions, duplicates seen) and its port's state
  (sat_node/dtn/port.py: the event cursor, events not yet turned into messages and what is known
  about them, transmissions not yet settled). It is one pickle, so objects
  shared between the satellite and its agent (a transmission and its held record) stay shared.
  The shared read-only inputs (world, scenario, belief noise, contact graph, store connection,
  agent config) and the agent's query buffers (all zero between queries) are rebuilt from the
  world pickle by the new process, not saved.

The host (bringup/engine/ros/host.py) writes the snapshot into the bundle store's own SQLite file in the
same transaction as the step's store writes (:func:`persistent_connection`; bringup/engine/checkpoint.py),
so bundles and knowledge never disagree. :func:`restore` checks that: the rows in the store must be
exactly the bundles the restored agent holds; a difference (which the single transaction should make
impossible) is repaired from the snapshot and counted in ``restore_report``.

How we know it is right: tests/faults/test_restart_unit.py (snapshot -> restore into a freshly
built satellite -> the next steps emit exactly what the uninterrupted satellite emits) and
tests/faults/test_restart_ros.py (kill -9 mid-run: the finished run equals the uninterrupted one).
"""

from __future__ import annotations

import pickle
import sqlite3

from sat_node.dtn.bpv7 import encode_bundle
from sat_node.dtn.store import StoredBundle
from sat_node.value import KnownLog

__all__ = ["persistent_connection", "restore", "snapshot"]

# _key: the BPSec key (centralized downlinks) never goes in a checkpoint
_SAT_SHARED = ("world", "sc", "belief", "agent", "port", "_key")
_AGENT_SHARED = ("graph", "store", "config", "on_event", "_out_starts", "_backlog_buf", "_excluded_buf")
_PORT_SHARED = ("agent",)


def persistent_connection(sat) -> sqlite3.Connection | None:
    """The satellite's bundle store connection when it is a file (else None)."""
    ag = getattr(sat, "agent", None)
    store = getattr(ag, "store", None)
    if store is None or getattr(store, "path", None) is None:
        return None
    return store._db  # the store's own connection: one transaction covers its rows and the snapshot


def snapshot(sat) -> bytes:
    state = {k: v for k, v in vars(sat).items() if k not in _SAT_SHARED}
    ag = sat.agent
    if ag is not None:
        state["__agent__"] = {k: v for k, v in vars(ag).items() if k not in _AGENT_SHARED}
    port = sat.port
    if port is not None:
        ps = {k: v for k, v in vars(port).items() if k not in _PORT_SHARED}
        # keyed by id(event): keep the events themselves (same pickle)
        by_id = {id(ev): ev for ev in (ag.events or ())}
        ps["_ev_info"] = [(by_id[i], info) for i, info in ps["_ev_info"].items() if i in by_id]
        state["__port__"] = ps
    return pickle.dumps(state, protocol=pickle.HIGHEST_PROTOCOL)


def restore(sat, blob: bytes) -> None:
    """Put ``blob`` (from :func:`snapshot`) into ``sat``, freshly built for the same world and name."""
    state = pickle.loads(blob)
    agent_state = state.pop("__agent__", None)
    port_state = state.pop("__port__", None)
    if port_state is not None:
        port_state["_ev_info"] = {id(ev): info for ev, info in port_state["_ev_info"]}
        vars(sat.port).update(port_state)
    fresh_guard = getattr(sat, "guard", None)  # operator commands: the key is not in the snapshot
    vars(sat).update(state)
    if fresh_guard is not None and getattr(sat, "guard", None) is not None:
        sat.guard.keep_key_of(fresh_guard)
    if not isinstance(sat.known, KnownLog):  # a snapshot from before KnownLog: a plain list
        sat.known = KnownLog(sat.known)
    report = {"store_rows_added": 0, "store_rows_removed": 0}
    ag = sat.agent
    if ag is not None and agent_state is not None:
        vars(ag).update(agent_state)
        if ag.store is not None:
            report = _reconcile_store(ag)
    sat.restore_report = report


def _reconcile_store(ag) -> dict:
    rows = {sb.bundle_id for sb in ag.store.load_all()}
    held = dict(ag._held)
    multicast = not hasattr(ag, "_in_flight")  # sat_node/dtn/multicast.py: in-flight recipients are in _held
    if not multicast:
        for bid, (_tx, h) in ag._in_flight.items():
            held[bid] = h
    added = removed = 0
    for bid, h in held.items():
        if bid not in rows:
            if multicast:
                ag._persist(h)  # the row of the recipients it is responsible for
            else:
                ag.store.put(StoredBundle(bid, encode_bundle(h.bundle), h.priority, h.dest, h.expiry_ns, h.ready_ns))
            added += 1
    for bid in rows - held.keys():
        ag.store.delete(bid)
        removed += 1
    return {"store_rows_added": added, "store_rows_removed": removed, "held": len(held)}
