"""`constellation report BAG`: rebuild report.json from a run's bag alone.

Checked by tests/system/test_engines_equal.py and tests/unit/test_cli_exit.py (the report
rebuilt from the bag equals the run's report.json).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from bringup.analysis.report import report_from_bag


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("bag", type=Path, help="bag folder (runs/<name>/bag) or its .mcap file")
    p.add_argument("--out", type=Path, default=None, help="write report.json here instead of stdout")


def run(args: argparse.Namespace) -> int:
    rep = report_from_bag(args.bag)
    text = json.dumps(rep, indent=2, sort_keys=True) + "\n"
    if args.out:
        args.out.write_text(text)
    else:
        print(text, end="")
    return 0
