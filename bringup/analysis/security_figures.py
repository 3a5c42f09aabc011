"""report.json ``security``: what a run's processes rejected, from the run's /run/meta ``security`` record.

The ROS clock writes the record (bringup/engine/ros/clock_node.py): per process, per topic, per reason,
the messages it rejected before acting on them. The record comes from a bag, so it is checked here
like any untrusted input. Checked by tests/faults/test_faults_hostile_ros.py (counts per forged
message) and tests/faults/test_hostile_inputs.py (malformed records: one line).
"""

from __future__ import annotations

from collections import defaultdict

__all__ = ["security_figures"]


def security_figures(record: dict | None) -> dict:
    """report.json ``security`` from the run's /run/meta ``security`` record: ``rejected`` - messages
    the run's processes rejected (not authenticated under the run key, malformed, from no host of
    the run), by reason, summed over processes and topics; ``rejected_by_process`` - the record
    itself, ``{process: {topic: {reason: n}}}`` (the clock, the router, each satellite...). Both
    empty when nothing was rejected (and always under the local engine: one process, no network).
    ValueError naming the first malformed entry (the record comes from a bag: untrusted)."""
    if record is not None and not isinstance(record, dict):
        raise ValueError(f"'security' is {type(record).__name__}, not an object")
    by = (record or {}).get("rejected_by_process") or {}
    if not isinstance(by, dict):
        raise ValueError(f"security.rejected_by_process is {type(by).__name__}, not an object")
    total: dict[str, int] = defaultdict(int)
    for proc, topics in by.items():
        if not isinstance(topics, dict):
            raise ValueError(f"security.rejected_by_process.{str(proc)[:40]} is not an object")
        for topic, reasons in topics.items():
            if not isinstance(reasons, dict) or not all(type(n) is int and n >= 0 for n in reasons.values()):
                raise ValueError(f"security.rejected_by_process.{str(proc)[:40]}.{str(topic)[:80]}: "
                                 "not an object of counts")
            for reason, n in reasons.items():
                total[reason] += n
    return {"rejected": dict(sorted(total.items())), "rejected_by_process": dict(by)}
