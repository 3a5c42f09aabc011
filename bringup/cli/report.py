"""`constellation report BAG`: rebuild report.json from a run's bag alone.

The bag's ``.mcap`` is read as far as it goes (a cut one too: bringup/recording/bag_reader.py); what
the reader read past (metadata.yaml disagreeing with the file, a cut file, payloads not counted) is
printed as ``warning:`` lines on stderr, and a run that did not reach its horizon gives a report
with ``partial: true``. ``--out`` is written whole or not at all (a temporary file renamed).

The bag's seal is checked first (bringup/recording/bag_seal.py; report.json ``integrity``): a seal
that does not match refuses the bag in one line naming integrity (exit 2) unless ``--unverified``
is given, and then the report, and a warning line, say ``unverified``.

Checked by tests/faults/test_bag_seal.py, tests/system/test_engines_equal.py and tests/unit/test_cli_exit.py (the report
rebuilt from the bag equals the run's report.json), tests/unit/test_bag_recovery.py (partial and
foreign-metadata bags) and tests/faults/test_hostile_inputs.py.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from bringup.analysis.report import report_from_bag
from bringup.cli.run_folder import write_text_atomic


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("bag", type=Path, help="bag folder (runs/<name>/bag) or its .mcap file")
    p.add_argument("--out", type=Path, default=None, help="write report.json here instead of stdout")
    p.add_argument("--unverified", action="store_true",
                   help="read a bag whose seal does not match (the report says unverified)")


def run(args: argparse.Namespace) -> int:
    rep = report_from_bag(args.bag, warn=lambda line: print(f"constellation report: warning: {line}",
                                                            file=sys.stderr),
                          unverified_ok=args.unverified)
    text = json.dumps(rep, indent=2, sort_keys=True, allow_nan=False) + "\n"
    if args.out:
        write_text_atomic(args.out, text)
    else:
        print(text, end="")
    return 0
