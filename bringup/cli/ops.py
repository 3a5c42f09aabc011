"""`constellation ops`: the operations dictionary and a run's event log.

* ``constellation ops dictionary [--out FILE]`` - the command and telemetry dictionary generated from
  the code (sat_node/operations/catalogue.py), one JSON file (stdout without ``--out``).
* ``constellation ops events BAG [--json]`` - the run's operations events (mode changes, command
  receipt / execution / rejection) in time order, each with its catalogue ID and severity.
* ``constellation ops packets BAG [--out FILE]`` - the run's housekeeping (``operations.hk_period_s``)
  as CCSDS space packets (sat_node/operations/packets.py), by default ``telemetry.ccsds`` beside the bag.

Checked by tests/unit/test_operations_catalogue.py (the dictionary file) and
tests/system/test_operations_commands_run.py (the event log of a commanded run's bag).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from bringup.cli.run_folder import write_text_atomic
from bringup.errors import UserError
from bringup.recording.bag import BagReader
from msgs_json import codec
from sat_node.operations.catalogue import dictionary, event_of
from sat_node.operations.packets import encode_hk_packet, hk_apid


def add_arguments(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="what", metavar="WHAT", required=True,
                           help="dictionary: write the command and telemetry dictionary; events: a run's event log")
    d = sub.add_parser("dictionary", help="write the command and telemetry dictionary (JSON)")
    d.add_argument("--out", type=Path, default=None, help="write it here instead of stdout")
    e = sub.add_parser("events", help="print a run's operations event log from its bag")
    e.add_argument("bag", type=Path, help="bag folder (runs/<name>/bag) or its .mcap file")
    e.add_argument("--json", action="store_true", help="one JSON object per line")
    k = sub.add_parser("packets", help="write a run's housekeeping as CCSDS space packets")
    k.add_argument("bag", type=Path, help="bag folder (runs/<name>/bag) or its .mcap file")
    k.add_argument("--out", type=Path, default=None, help="packet file (default: telemetry.ccsds beside the bag)")


def events_from_bag(bag: Path) -> list[dict]:
    """The operations events of a bag, in (time, satellite) order."""
    out = []
    with BagReader(bag) as b:
        topics = [t.topic for t in b.topics() if t.topic.endswith(("/ops/mode", "/ops/command"))]
        for env in (b.envelopes(topics) if topics else ()):
            m = codec.decode(env.topic, env.data)
            eid, sev, text = event_of(m)
            out.append({"t_s": m.t_ns / 1e9, "sat": m.sat, "id": eid, "severity": sev, "text": text})
    return sorted(out, key=lambda e: (e["t_s"], e["sat"], e["id"]))


def packets_from_bag(bag: Path) -> tuple[bytes, int]:
    """(the packets, how many) of a bag's Housekeeping messages, in (time, satellite) order; the APID
    by the satellite's index in the run's constellation (sat_PS names sort in that order)."""
    with BagReader(bag) as b:
        topics = [t.topic for t in b.topics() if t.topic.endswith("/ops/hk")]
        msgs = [codec.decode(env.topic, env.data) for env in (b.envelopes(topics) if topics else ())]
    if not msgs:
        raise UserError(f"bag {bag}: no housekeeping (/sat_XX/ops/hk): run with operations.hk_period_s > 0")
    sats = sorted({m.sat for m in msgs})  # (names sort in plane, slot order)
    seq: dict[str, int] = {}
    out = bytearray()
    for m in sorted(msgs, key=lambda m: (m.t_ns, m.sat)):
        n = seq[m.sat] = seq.get(m.sat, -1) + 1
        out += encode_hk_packet(m, hk_apid(sats.index(m.sat)), n)
    return bytes(out), len(msgs)


def run(args: argparse.Namespace) -> int:
    if args.what == "packets":
        data, n = packets_from_bag(args.bag)
        bag = Path(args.bag)
        out = args.out or ((bag.parent if bag.suffix == ".mcap" else bag).parent / "telemetry.ccsds")
        tmp = out.with_name(out.name + ".tmp")
        tmp.write_bytes(data)
        tmp.replace(out)
        print(f"constellation ops packets: {n} packets -> {out}")
        return 0
    if args.what == "dictionary":
        text = json.dumps(dictionary(), indent=2) + "\n"
        if args.out:
            write_text_atomic(args.out, text)
        else:
            print(text, end="")
        return 0
    for e in events_from_bag(args.bag):
        print(json.dumps(e) if args.json else f"{e['t_s']:10.3f} {e['sat']:<14} {e['id']:5d} {e['severity']:<11} "
              f"{e['text']}")
    return 0
