"""Running a sweep's cells x seeds, each finished run stored, so a sweep that was stopped resumes.

Each run is named by what it runs: its mode and the hash of its whole scenario (bringup/scenario/
world.py ``scenario_key``: every key, the seed and the cell's overrides included), under
``OUT/runs/<engine>/``:

* ``--engine local``: the run goes in this process (bringup/analysis/compare.py ``run_in_process``:
  the local engine, the report built from its envelopes, no bag); its report and provenance are
  written whole (a temporary file renamed) to ``<mode>-<key>.json``;
* ``--engine ros``: ``constellation run --engine ros`` in a subprocess on the cell's resolved
  scenario (``<mode>-<key>.toml``, bringup/scenario/provenance.py ``scenario_toml``) into the run
  folder ``<mode>-<key>/`` (bag, report.json); done when its report.json is there and not partial.

A run whose file is there is not run again: a sweep killed midway and started again (same scenario,
grid, options) runs only the missing ones; a changed scenario or cell has another key, so nothing
stale is reused. Runs go one after the other, in cell order.

How we know it is right: tests/system/test_sweep_grid.py (a sweep killed after its first stored
runs, rerun: the stored files untouched, only the missing runs made, the figures complete).
"""

from __future__ import annotations

import json
import time
from pathlib import Path

from bringup.analysis.compare import run_in_process, run_one
from bringup.analysis.grid import Cell, get_path
from bringup.scenario.config import Scenario
from bringup.scenario.overrides import apply_sets
from bringup.scenario.provenance import provenance, scenario_toml
from bringup.scenario.world import scenario_key

__all__ = ["GridRun", "plan_runs", "run_all"]


class GridRun:
    """One cell x seed: its scenario, where its result is stored, and whether it is there."""

    def __init__(self, cell: Cell, seed: int, sc: Scenario, root: Path, engine: str):
        self.cell, self.seed, self.scenario, self.engine = cell, seed, sc, engine
        self.key = f"{cell.mode}-{scenario_key(sc)}"
        self.dir = Path(root) / "runs" / engine
        self.path = self.dir / (f"{self.key}.json" if engine == "local" else f"{self.key}/report.json")

    def load(self) -> dict | None:
        """The stored report, or None when the run is not done (missing, unreadable, partial)."""
        try:
            d = json.loads(self.path.read_text())
        except (OSError, ValueError):
            return None
        rep = d.get("report") if self.engine == "local" else d
        if not isinstance(rep, dict) or rep.get("partial"):
            return None
        return rep

    def run(self, write_text, to_json) -> dict:
        """Run it and store it: ``write_text(path, text)`` writes a file whole, ``to_json(obj)`` is
        its JSON text (bringup/cli/run_folder.py write_text_atomic, json_text)."""
        self.dir.mkdir(parents=True, exist_ok=True)
        if self.engine == "local":
            rep = run_in_process(self.scenario, self.cell.mode)
            rep["provenance"] = provenance(self.scenario)
            write_text(self.path, to_json({"mode": self.cell.mode, "seed": self.seed, "params": self.cell.params,
                                           "report": rep}) + "\n")
            return rep
        toml = self.dir / f"{self.key}.toml"
        write_text(toml, scenario_toml(self.scenario))
        return run_one(scenario=str(toml), mode=self.cell.mode, seed=None, out=self.path.parent, engine="ros")


def plan_runs(base: Scenario, cells: list[Cell], seeds: list[int], root: Path, engine: str) -> list[GridRun]:
    """Every cell x seed with its scenario, validated before anything runs (one line naming the
    cell's override that is wrong)."""
    runs = []
    for c in cells:
        sc = apply_sets(base, list(c.sets), what=f"--grid cell {c.id}:")
        for s in seeds:
            runs.append(GridRun(c, s, apply_sets(sc, [("scenario.seed", s)]), root, engine))
    return runs


def run_all(runs: list[GridRun], write_text, to_json, say=lambda *a: None) -> dict[tuple[str, int], dict]:
    """Run what is missing (stored with ``write_text`` / ``to_json``: :meth:`GridRun.run`), reuse
    what is stored; ``{(cell id, seed): report}``."""
    reports: dict[tuple[str, int], dict] = {}
    todo = []
    for r in runs:
        rep = r.load()
        if rep is None:
            todo.append(r)
        else:
            reports[(r.cell.id, r.seed)] = rep
    say(f"sweep: {len(runs)} run{'s' if len(runs) != 1 else ''}, {len(reports)} already done (reused), "
        f"{len(todo)} to run")
    for i, r in enumerate(todo, 1):
        t0 = time.perf_counter()
        rep = r.run(write_text, to_json)
        reports[(r.cell.id, r.seed)] = rep
        params = " ".join(f"{k}={v!r}" for k, v in r.cell.params.items())
        say(f"sweep: [{i}/{len(todo)}] {r.cell.id} {r.cell.mode} {params} seed {r.seed}: value "
            f"{get_path(rep, 'value.cumulative') or 0:.0f} ({time.perf_counter() - t0:.1f} s)")
    return reports
