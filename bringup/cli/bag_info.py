"""`constellation bag-info BAG`: topics, types, message counts and time span of a recorded bag.

Reads the bag with bringup/recording/bag.py (rosbags; no rclpy). Times are sim time: ns since the
scenario epoch, also shown in seconds; the epoch (the bag's clock: its log times and /clock are
epoch + t, UTC) is shown with them. ``--json`` prints the same as one JSON object.

The numbers are the ``.mcap`` file's own (bringup/recording/bag_reader.py): a metadata.yaml that
disagrees is named in a ``warning:`` line on stderr, and a file its writer never closed is read as
far as it goes, with a ``complete: no`` line saying what was recovered and what was lost.

The bag's seal is checked first (bringup/recording/bag_seal.py): ``integrity: verified`` or
``integrity: unverified (why)``; a seal that does not match refuses the bag in one line (exit 2)
unless ``--unverified`` is given.

Checked by tests/faults/test_bag_seal.py, tests/unit/test_recording.py (test_bag_info_command) and tests/unit/test_bag_recovery.py.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from bringup.recording.bag import BagReader, epoch_custom_data
from bringup.recording.bag_seal import check_bag


def add_arguments(p) -> None:
    p.add_argument("bag", type=Path, help="bag directory (metadata.yaml + .mcap) or its .mcap file")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    p.add_argument("--unverified", action="store_true",
                   help="read a bag whose seal does not match (its outputs say unverified)")


def bag_summary(path: Path, *, unverified_ok: bool = False) -> dict:
    """{path, integrity, complete, recovery, warnings, messages, epoch_ns, epoch_utc, start_ns,
    end_ns, duration_s, topics: [{topic, type, count}]}."""
    integrity = check_bag(path, unverified_ok=unverified_ok)
    with BagReader(path) as r:
        topics = [{"topic": t.topic, "type": t.msgtype, "count": t.count} for t in r.topics()]
        return {
            "path": str(r.path),
            "integrity": integrity.as_dict(),
            "complete": r.complete,
            "recovery": r.recovery,
            "warnings": list(r.warnings),
            "messages": r.count,
            "epoch_ns": r.epoch_ns,
            "epoch_utc": epoch_custom_data(r.epoch_ns).get("epoch_utc", "1970-01-01T00:00:00Z"),
            "start_ns": r.start_ns,
            "end_ns": r.end_ns,
            "duration_s": (r.end_ns - r.start_ns) / 1e9,
            "topics": topics,
        }


def run(args) -> int:
    s = bag_summary(args.bag, unverified_ok=args.unverified)
    if s["integrity"]["status"] != "verified":
        print(f"constellation bag-info: warning: bag {s['path']}: unverified: {s['integrity']['detail']}",
              file=sys.stderr)
    for line in s["warnings"] + ([s["recovery"]] if s["recovery"] else []):
        print(f"constellation bag-info: warning: bag {s['path']}: {line}", file=sys.stderr)
    if args.json:
        print(json.dumps(s, indent=2))
        return 0
    print(f"bag:       {s['path']}")
    i = s["integrity"]
    print(f"integrity: {i['status']}" + ("" if i["status"] == "verified" else f" ({i['detail']})"))
    if not s["complete"]:
        print(f"complete:  no - {s['recovery']}")
    print(f"messages:  {s['messages']}")
    print(f"epoch:     {s['epoch_utc']} (log times and /clock: epoch + t, UTC)")
    print(f"start:     {s['start_ns'] / 1e9:.3f} s ({s['start_ns']} ns since epoch)")
    print(f"end:       {s['end_ns'] / 1e9:.3f} s ({s['end_ns']} ns since epoch)")
    print(f"duration:  {s['duration_s']:.3f} s")
    print(f"topics:    {len(s['topics'])}")
    if s["topics"]:
        wt = max(len(t["topic"]) for t in s["topics"])
        wy = max(len(t["type"]) for t in s["topics"])
        for t in s["topics"]:
            print(f"  {t['topic']:<{wt}}  {t['type']:<{wy}}  {t['count']:>9}")
    return 0
