"""report.json ``operations``: time in each mode per satellite and the value lost to faults.

Only in a run where some satellite changed mode (sat_node/operations/modes.py) or handled an operator
command (a run without faults or commands has no such message and so no such section - its report is
unchanged):

* ``commands.{received, executed, rejected.<reason>, latency_s.{mean, max}}`` - from the satellites'
  CommandEvent messages (sat_node/operations/commands.py); the latency runs from the command's issue
  time to its execution on the named satellite; ``uplink_latency_s`` to its receipt there;
  ``acks`` the acknowledgements that reached the ground (CommandAck, downlinked at the satellite's
  ground contacts) and their latency from the execution; ``by_command.<id>`` each command's
  uplink, execution and ack latency;
* ``tasks.<id>`` - each executed tasking request (sat_node/operations/tasking.py): its ground point
  and deadline, and the first observation of that GP after its execution (by whom, when, in time,
  whether the observer was a tasked satellite);

* ``time_in_mode_s.{sat}.{NOMINAL,DEGRADED,SAFE}`` - for every satellite that changed mode (the
  others were NOMINAL over the whole run), from its ModeChange messages over [0, horizon_s],
  starting NOMINAL;
* ``transitions`` - the number of mode changes;
* ``value_lost_estimate`` - a documented estimate, not a counterfactual run: the planner's assumed
  value of the looks the satellites dropped from their plans when they stopped imaging
  (ModeChange.plan_value_dropped summed). The looks they would have planned in later replans while
  down are not in it, nor what their neighbours took instead: compare with the same scenario run
  without the fault (``constellation compare``) for the realised difference.

Oracle: a hand-worked pair of changes in tests/unit/test_operations_modes.py; whole runs in
tests/system/test_operations_faults.py and tests/system/test_operations_tasking_run.py (the
latencies against the CommandEvent and CommandAck times in the bag, the task's observation against
the bag's observations).
"""

from __future__ import annotations

from collections import defaultdict

import numpy as np

from msgs_json import schemas as S

__all__ = ["ACKS", "OPS", "command_figures", "operations_figures", "task_figures"]

OPS = ("/ops/mode", "/ops/command")  # the topics (suffixes) report.json's operations section reads
ACKS = "/ground/acks"  # and the acknowledgements that reached the ground (CommandAck)

_NS = 1_000_000_000


def operations_figures(changes, horizon_s: float, observations=(), acks=()) -> dict:
    """``{"operations": ...}`` for report.json (module docstring) from ModeChange messages: time in each
    mode per satellite that changed mode, over [0, horizon_s], starting NOMINAL; {} without any.
    ``observations`` (Observation) and ``acks`` (CommandAck): for the commands' tasks and acknowledgements."""
    commands = [m for m in changes if isinstance(m, S.CommandEvent)]
    changes = [m for m in changes if isinstance(m, S.ModeChange)]
    out = {"commands": command_figures(commands, acks)} if commands else {}
    tasks = task_figures(commands, observations)
    if tasks:
        out["tasks"] = tasks
    if not changes:
        return {"operations": out} if out else {}
    by_sat: dict[str, list] = defaultdict(list)
    for m in changes:
        by_sat[m.sat].append(m)
    end_ns = int(round(horizon_s * _NS))
    tim: dict[str, dict[str, float]] = {}
    for sat in sorted(by_sat):
        ms = sorted(by_sat[sat], key=lambda m: m.t_ns)
        acc = {"NOMINAL": 0, "DEGRADED": 0, "SAFE": 0}
        mode, since = "NOMINAL", 0
        for m in ms:
            t = min(m.t_ns, end_ns)
            acc[mode] += max(0, t - since)
            mode, since = m.mode, t
        acc[mode] += max(0, end_ns - since)
        tim[sat] = {k: v / _NS for k, v in acc.items()}
    return {"operations": out | {"transitions": len(changes), "time_in_mode_s": tim,
            "value_lost_estimate": float(sum(m.plan_value_dropped for m in changes)),
            "value_lost_method": "plan_value_dropped (the planner's assumed value of the looks dropped "
                                 "on stopping imaging)"}}


def _stats(xs) -> dict:
    return {"mean": float(np.mean(xs)), "max": float(np.max(xs))} if xs else {}


def command_figures(events, acks=()) -> dict:
    """``operations.commands`` from CommandEvent messages: how many were received and executed, the
    rejections by reason, and the latency from issue to execution [s] (mean, max; uplink wait, relay
    over the ISLs and the step it waited for); with the CommandAck messages that reached the ground,
    per command (``by_command``): its satellite and kind, the uplink latency (issue to receipt on
    its satellite), the execution latency (issue to execution) and the ack latency (execution, or
    rejection, to its acknowledgement on the ground) [s]."""
    rej: dict[str, int] = defaultdict(int)
    for e in events:
        if e.stage == "rejected":
            rej[e.reason or "other"] += 1
    done = [e.latency_s for e in events if e.stage == "executed"]
    acked = {(a.sat, a.command_id, a.stage, a.event_ns): a for a in acks}
    per: dict[str, dict] = {}
    for e in sorted(events, key=lambda e: (e.t_ns, e.sat, e.command_id, e.stage)):
        if e.command_id == "?":
            continue
        d = per.setdefault(e.command_id, {"sat": e.sat, "kind": e.kind, "issued_s": e.issued_ns / _NS})
        if e.stage == "received":
            d.setdefault("uplink_latency_s", e.latency_s)
        elif e.stage == "executed":
            d.setdefault("execution_latency_s", e.latency_s)
        else:
            d.setdefault("rejected", e.reason)
        a = acked.get((e.sat, e.command_id, e.stage, e.t_ns))
        if e.stage != "received" and a is not None and "ack_latency_s" not in d:
            d["ack_latency_s"], d["acked_s"], d["acked_at"] = a.latency_s, a.t_ns / _NS, a.station
    ack_ex = [a.latency_s for a in acks if a.stage == "executed"]
    return {"received": sum(e.stage == "received" for e in events), "executed": len(done),
            "rejected": dict(sorted(rej.items())),
            "latency_s": _stats(done),
            "uplink_latency_s": _stats([e.latency_s for e in events if e.stage == "received"]),
            "acks": {"received_on_ground": len(acks), "latency_s": _stats(ack_ex)},
            "by_command": per}


def task_figures(events, observations) -> dict:
    """``operations.tasks``: per executed tasking request (CommandEvent with a GP), its satellite,
    ground point, deadline and execution time [s], and the first observation of that GP at or after
    the execution by any satellite (``observed_by``, ``observed_s``; null when none), whether it came
    before the deadline, and whether its observer is a satellite that executed a task for that GP."""
    tasks = [e for e in events if e.stage == "executed" and e.kind == "task" and e.gp >= 0]
    if not tasks:
        return {}
    tasked = {(e.sat, e.gp) for e in tasks}
    by_gp: dict[int, list] = defaultdict(list)
    for o in observations:
        by_gp[o.gp].append(o)
    out = {}
    for e in sorted(tasks, key=lambda e: (e.command_id, e.sat)):
        seen = sorted((o for o in by_gp.get(e.gp, ()) if o.t_ns >= e.t_ns), key=lambda o: (o.t_ns, o.sat))
        first = seen[0] if seen else None
        out[e.command_id] = {
            "sat": e.sat, "gp": e.gp, "by_s": e.by_ns / _NS, "executed_s": e.t_ns / _NS,
            "observed_by": first.sat if first else None, "observed_s": first.t_ns / _NS if first else None,
            "in_time": bool(first is not None and first.t_ns <= e.by_ns),
            "observer_was_tasked": bool(first is not None and (first.sat, e.gp) in tasked)}
    return out
