"""Parameter grids: the cells of a sweep over any scenario keys, and their figures over seeds.

A grid is written ``"isl.rate_bps=250,1000,8000 scheduler.replan_period_s=300,600"``: axes separated
by spaces, each a scenario key (the dotted path of bringup/scenario/overrides.py) and its values
separated by commas (a comma inside ``[...]``, ``{...}`` or quotes belongs to the value); every value
is a TOML literal, as with ``--set``. The cells are the cartesian product of the axes (the first axis
varies slowest), times the chosen modes. An axis may also be a *preset* whose one value sets several
keys (the four named sweeps of ``constellation sweep``: :func:`preset_axis`).

The figures of one run are dotted report.json keys (:data:`METRICS`, more with ``--metric``). Over
the seeds of a cell each figure is summarised by bringup/analysis/stats.py ``summarize`` (mean,
sample sd, Student-t 95 % CI); a figure a run's report does not have (missing or null) is left out
of that cell's figure, and has no row in the CSV.

The tidy CSV (:func:`csv_text`) has one row per cell x seed x metric, columns ``cell, mode, <one
column per axis>, seed, metric, value``; the JSON (:func:`summary`) has per cell ``mean``, ``sd``,
``ci95`` and ``n`` by metric at the cell's top level, and the per-seed values.

How we know it is right: tests/unit/test_grid.py (parsing, the product, one-line errors, the
summary against statistics.stdev and scipy's t.interval) and tests/system/test_sweep_grid.py (a
real 2 x 2 x 3 seeds sweep whose CSV, grouped by cell and metric with the csv module, gives the
JSON's means and intervals; a sweep killed midway and rerun runs only the missing runs).
"""

from __future__ import annotations

import csv
import io
import itertools
from dataclasses import dataclass, field

from bringup.analysis.stats import CI_LEVEL, summarize
from bringup.errors import UserError
from bringup.scenario.overrides import KEY_RE, parse_value

__all__ = ["METRICS", "STATISTICS", "Axis", "Cell", "cells_of", "csv_text", "get_path", "parse_grid",
           "split_values", "summary"]

#: the figures of a run a sweep reports by default (dotted report.json keys)
METRICS = ("value.cumulative", "coverage.gp_observed_fraction", "observations.count",
           "observations.duplicates_15min", "value.assumed_error_mean", "dtn.delivery_ratio",
           "knowledge.info_age_s.median")

#: what the summary's figures are (written into sweep.json beside them)
STATISTICS = {
    "mean": "arithmetic mean over the seeds",
    "sd": "sample standard deviation over the seeds (n - 1 in the denominator); null for one seed",
    "ci95": f"{CI_LEVEL:.0%} confidence interval of the mean, [low, high]: mean -+ t(0.975, n - 1) sd / sqrt(n) "
            "(Student's t); null for one seed",
    "n": "number of seeds whose report has the figure",
}


@dataclass(frozen=True)
class Axis:
    """One axis: its name (a scenario key, or a preset's name), the value labels, and for each
    label the (key, value) overrides it makes."""

    name: str
    labels: tuple
    sets: tuple  # per label: tuple of (key, value)


@dataclass(frozen=True)
class Cell:
    id: str
    mode: str
    params: dict = field(default_factory=dict)  # axis name -> label
    sets: tuple = ()  # (key, value) overrides, in axis order


def get_path(rep: dict, key: str):
    """``rep["a"]["b"]`` for ``key = "a.b"``; None when any part is missing."""
    d = rep
    for part in key.split("."):
        if not isinstance(d, dict) or part not in d:
            return None
        d = d[part]
    return d


def _split_top_level(text: str, is_sep) -> list[str]:
    """``text`` cut at the characters ``is_sep`` accepts outside brackets and quotes (pieces as they are)."""
    out, cur, depth, quote = [], [], 0, ""
    for ch in text:
        if quote:
            cur.append(ch)
            if ch == quote:
                quote = ""
            continue
        if ch in "\"'":
            quote = ch
        elif ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
        elif depth == 0 and is_sep(ch):
            out.append("".join(cur))
            cur = []
            continue
        cur.append(ch)
    out.append("".join(cur))
    return out


def split_values(text: str) -> list[str]:
    """``"1,[2, 3],'a,b'"`` -> ``["1", "[2, 3]", "'a,b'"]``: commas outside brackets and quotes."""
    return [v.strip() for v in _split_top_level(text, lambda ch: ch == ",")]


def _split_axes(text: str) -> list[str]:
    """Axes separated by whitespace outside brackets and quotes."""
    return [a for a in _split_top_level(text, str.isspace) if a]


def parse_grid(texts: list[str]) -> list[Axis]:
    """The axes of one or more ``--grid`` texts; UserError (one line) naming a malformed axis, an
    empty or repeated value, a key given twice, or the seed (``--seeds`` gives the seeds)."""
    axes: list[Axis] = []
    for text in texts:
        for part in _split_axes(text):
            key, eq, vals = part.partition("=")
            key = key.strip()
            if not eq or not key:
                raise UserError(f"--grid {part!r}: expected KEY=V1,V2,... (e.g. isl.rate_bps=250,1000)")
            if not KEY_RE.match(key):
                raise UserError(f"--grid {part!r}: {key!r} is not a dotted scenario key")
            if key == "scenario.seed":
                raise UserError(f"--grid {part!r}: the seeds are given by --seeds K (the scenario seed and the "
                                "K - 1 after it)")
            if any(a.name == key for a in axes):
                raise UserError(f"--grid: key {key!r} is given twice")
            raw = split_values(vals)
            if any(not v for v in raw):
                raise UserError(f"--grid {part!r}: an empty value")
            labels = []
            for v in raw:
                try:
                    labels.append(parse_value(v))
                except ValueError as exc:
                    raise UserError(f"--grid {part!r}: {exc}") from None
            if len({repr(v) for v in labels}) != len(labels):
                raise UserError(f"--grid {part!r}: a value is given twice")
            axes.append(Axis(key, tuple(labels), tuple(((key, v),) for v in labels)))
    if not axes:
        raise UserError("--grid: no axis (expected e.g. \"isl.rate_bps=250,1000 scheduler.replan_period_s=300,600\")")
    return axes


def cells_of(axes: list[Axis], modes: list[str], start: int = 1) -> list[Cell]:
    """Every mode x the cartesian product of the axes (first axis slowest), numbered from ``start``."""
    cells = []
    k = start
    for mode in modes:
        for combo in itertools.product(*(range(len(a.labels)) for a in axes)):
            params = {a.name: a.labels[i] for a, i in zip(axes, combo)}
            sets = tuple(kv for a, i in zip(axes, combo) for kv in a.sets[i])
            cells.append(Cell(id=f"c{k}", mode=mode, params=params, sets=sets))
            k += 1
    return cells


def _cell_figures(reports: dict[int, dict], metrics: list[str]) -> dict:
    per = {m: {s: get_path(rep, m) for s, rep in reports.items()} for m in metrics}
    st = {m: summarize(list(v.values())) for m, v in per.items()}
    return {"mean": {m: s["mean"] for m, s in st.items()}, "sd": {m: s["sd"] for m, s in st.items()},
            "ci95": {m: s["ci95"] for m, s in st.items()}, "n": {m: s["n"] for m, s in st.items()},
            "per_seed": {m: [v[s] for s in reports] for m, v in per.items()}}


def summary(cells: list[Cell], reports: dict[tuple[str, int], dict], seeds: list[int], metrics: list[str]) -> dict:
    """The JSON summary: per cell its parameters, overrides and figures (``reports[(cell id,
    seed)]``: that run's report)."""
    out = []
    for c in cells:
        reps = {s: reports[(c.id, s)] for s in seeds if (c.id, s) in reports}
        out.append({"cell": c.id, "mode": c.mode, "params": dict(c.params),
                    "sets": {k: v for k, v in c.sets}, "seeds": list(reps), **_cell_figures(reps, metrics)})
    return {"metrics": list(metrics), "seeds": list(seeds), "statistics": dict(STATISTICS), "cells": out}


def _csv_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, (int, str)):
        return str(v)
    return repr(v)


def csv_text(cells: list[Cell], reports: dict[tuple[str, int], dict], seeds: list[int], metrics: list[str],
             axes: list[str]) -> str:
    """The tidy long CSV: ``cell, mode, <axes...>, seed, metric, value``, one row per cell x seed x
    metric the run's report has (module docstring)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["cell", "mode", *axes, "seed", "metric", "value"])
    for c in cells:
        for s in seeds:
            rep = reports.get((c.id, s))
            if rep is None:
                continue
            for m in metrics:
                v = get_path(rep, m)
                if v is None or isinstance(v, (dict, list)):
                    continue
                w.writerow([c.id, c.mode, *(_csv_value(c.params[a]) if a in c.params else "" for a in axes),
                            s, m, _csv_value(v)])
    return buf.getvalue()
