"""Argument helpers shared by subcommands.

Checked through the commands that use them (tests/unit/test_orbit_cli.py,
tests/faults/test_faults_scenario_cli.py: bad scenario arguments are one line).
"""

from __future__ import annotations

import argparse
import sys
from contextlib import contextmanager
from pathlib import Path

from bringup.scenario.config import Scenario, load_scenario


def add_scenario_args(p: argparse.ArgumentParser, *, overrides: bool = True) -> None:
    p.add_argument("--scenario", default="paper", help="scenario name or TOML path (default: paper)")
    if overrides:
        p.add_argument("--sats", type=int, default=None, help="number of satellites (default: scenario)")
        p.add_argument("--hours", type=float, default=None, help="horizon [h] (default: scenario)")
        p.add_argument("--seed", type=int, default=None, help="seed (default: scenario)")


def scenario_from_args(args: argparse.Namespace) -> Scenario:
    sc = load_scenario(args.scenario)
    sats, hours, seed = (getattr(args, k, None) for k in ("sats", "hours", "seed"))
    if sats is not None or hours is not None or seed is not None:
        sc = sc.with_overrides(sats=sats, hours=hours, seed=seed)
    return sc


def add_out_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", type=Path, default=None, help="write to FILE instead of stdout")


@contextmanager
def output_stream(path: Path | None):
    """stdout, or a file opened for writing (its folder created)."""
    if path is None:
        yield sys.stdout
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", encoding="utf-8", newline="") as fh:
        yield fh
