"""What the operations system tests read from a run folder: the decoded messages of chosen bag topics,
and report.json less the fields that differ between runs of the same scenario (run time, provenance,
engine, security)."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path


def bag_messages(bag: Path, pred: Callable[[str], bool]) -> list:
    """Every message on the bag's topics for which ``pred(topic)`` holds, decoded, in bag order."""
    from bringup.recording.bag import BagReader
    from msgs_json import codec

    with BagReader(bag) as b:
        topics = [t.topic for t in b.topics() if pred(t.topic)]
        return [codec.decode(env.topic, env.data) for env in b.envelopes(topics)] if topics else []


def comparable_report(run_dir: Path) -> dict:
    """report.json without runtime, provenance, engine and security (equal runs compare equal)."""
    rep = json.loads((run_dir / "report.json").read_text())
    for k in ("runtime", "provenance", "engine", "security"):
        rep.pop(k, None)
    return rep
