"""Plots of a parameter sweep: one figure per metric, its mean over seeds against the first axis's
values, with the 95 % confidence band of the mean (bringup/analysis/stats.py), one line per mode and
combination of the other axes, the seeds' own values as dots.

A numeric first axis is plotted at its values (log scale when they span more than a factor of 20),
any other at evenly spaced positions labelled with the values.

How we know it is right: tests/unit/test_grid.py draws a sweep's figure and reads back the line's
points (the means) and the band's vertices (the intervals) from the matplotlib artists.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from bringup.analysis.figures import PlotError, save_figure

__all__ = ["figure_metric", "plot_sweep"]


def _num(v) -> float | None:
    return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else None


def figure_metric(res: dict, metric: str, axes: list[str], title: str = "") -> Figure:
    """``res``: sweep.json's object (``cells`` with ``params``, ``mean``, ``ci95``, ``per_seed``)."""
    if not axes:
        raise PlotError("sweep: no axis to plot against")
    x_axis, others = axes[0], axes[1:]
    labels = []
    for c in res["cells"]:
        v = c["params"].get(x_axis)
        if v is not None and repr(v) not in [repr(w) for w in labels]:
            labels.append(v)
    numeric = all(_num(v) is not None for v in labels)
    pos = {repr(v): (_num(v) if numeric else float(i)) for i, v in enumerate(labels)}
    groups: dict[tuple, list] = {}
    for c in res["cells"]:
        if x_axis not in c["params"] or c["mean"].get(metric) is None:
            continue
        key = (c["mode"], *(repr(c["params"].get(a)) for a in others))
        groups.setdefault(key, []).append(c)
    if not groups:
        raise PlotError(f"sweep: no cell has {metric}")
    fig = Figure(figsize=(6.4, 4.0))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    for i, (key, cells) in enumerate(sorted(groups.items())):
        cells = sorted(cells, key=lambda c: pos[repr(c["params"][x_axis])])
        x = np.array([pos[repr(c["params"][x_axis])] for c in cells])
        m = np.array([c["mean"][metric] for c in cells], dtype=float)
        name = key[0] + "".join(f", {a}={v}" for a, v in zip(others, key[1:]))
        color = f"C{i % 10}"
        ax.plot(x, m, "o-", color=color, label=name)
        ci = [c["ci95"].get(metric) for c in cells]
        if all(b is not None for b in ci):
            ax.fill_between(x, [b[0] for b in ci], [b[1] for b in ci], color=color, alpha=0.2, lw=0)
        for xc, c in zip(x, cells):
            v = [p for p in c["per_seed"].get(metric, []) if p is not None]
            ax.plot([xc] * len(v), v, ".", color=color, alpha=0.4)
    if numeric and len(labels) > 1 and min(pos.values()) > 0 and max(pos.values()) / min(pos.values()) > 20:
        ax.set_xscale("log")
    ax.set_xticks(sorted(pos.values()))
    ax.set_xticklabels([str(v) for v in sorted(labels, key=lambda v: pos[repr(v)])])
    ax.set_xlabel(x_axis)
    ax.set_ylabel(f"{metric} (mean, 95 % CI band, seeds as dots)")
    ax.set_title(title or metric, fontsize=9)
    ax.legend(loc="best", fontsize=7)
    fig.tight_layout()
    return fig


def plot_sweep(folder: Path, res: dict, axes: list[str], title: str = "") -> list[Path]:
    """``folder/<metric>.png`` for each metric some cell has; the paths written."""
    made = []
    for metric in res["metrics"]:
        try:
            fig = figure_metric(res, metric, axes, title=title)
        except PlotError:
            continue
        made.append(save_figure(fig, Path(folder) / f"{metric.replace('.', '_')}.png"))
    return made
