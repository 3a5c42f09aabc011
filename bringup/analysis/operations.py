"""report.json ``operations``: time in each mode per satellite and the value lost to faults.

Only in a run where some satellite changed mode (sat_node/operations/modes.py) or handled an operator
command (a run without faults or commands has no such message and so no such section - its report is
unchanged):

* ``commands.{received, executed, rejected.<reason>, latency_s.{mean, max}}`` - from the satellites'
  CommandEvent messages (sat_node/operations/commands.py); the latency runs from the command's issue
  time to its execution on the named satellite;

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
tests/system/test_operations_faults.py.
"""

from __future__ import annotations

from collections import defaultdict

import numpy as np

from msgs_json import schemas as S

__all__ = ["OPS", "operations_figures"]

OPS = ("/ops/mode", "/ops/command")  # the topics (suffixes) report.json's operations section reads

_NS = 1_000_000_000


def operations_figures(changes, horizon_s: float) -> dict:
    """``{"operations": ...}`` for report.json (module docstring) from ModeChange messages: time in each
    mode per satellite that changed mode, over [0, horizon_s], starting NOMINAL; {} without any."""
    commands = [m for m in changes if isinstance(m, S.CommandEvent)]
    changes = [m for m in changes if isinstance(m, S.ModeChange)]
    out = {"commands": command_figures(commands)} if commands else {}
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


def command_figures(events) -> dict:
    """``operations.commands`` from CommandEvent messages: how many were received and executed, the
    rejections by reason, and the latency from issue to execution [s] (mean, max; uplink wait, relay
    over the ISLs and the step it waited for)."""
    rej: dict[str, int] = defaultdict(int)
    for e in events:
        if e.stage == "rejected":
            rej[e.reason or "other"] += 1
    done = [e.latency_s for e in events if e.stage == "executed"]
    return {"received": sum(e.stage == "received" for e in events), "executed": len(done),
            "rejected": dict(sorted(rej.items())),
            "latency_s": {"mean": float(np.mean(done)), "max": float(np.max(done))} if done else {}}
