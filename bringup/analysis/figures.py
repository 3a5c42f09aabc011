"""Plots of a run: PNG figures from plain data, for report.md and the README.

Each figure comes as a pair: ``figure_<name>(...) -> matplotlib.figure.Figure`` builds it (tests
inspect the artists and plotted arrays) and ``plot_<name>(path, ...) -> Path`` writes the PNG and
returns its path. No pyplot and no global backend switch: figures are ``Figure`` objects drawn by
the Agg canvas, so importing this module never changes another module's matplotlib state.

Figures (in kind, after Nag et al., ICAPS SPARK 2019, Figs. 3-5 and Table 2):

* ground tracks and regions on an equirectangular lat/lon map (no coastlines);
* one OSSE value snapshot per region (GP squares coloured by value 1..256);
* Gantt chart of observations per satellite (rows satellites, marks coloured by region);
* contact-plan timeline (rows node pairs, bars for windows; ISL and ground coloured apart);
* value accumulated over time per mode (distributed / centralized / non-agile ...);
* bundle latency by priority against access gaps by priority, box plots (the study's Fig. 5);
* the distributed / centralized value ratio against the field's transiency, mean and 95 % confidence
  interval over seeds (the transiency sweep, bringup/cli/sweep.py);
* the age of the information each look was planned with, one histogram per mode or knowledge model.

How we know it is right: ``tests/unit/test_plots.py`` draws each from small generated data, checks
a non-empty PNG is written and that the data went in (plotted arrays, number of bars/boxes/patches).
Input mistakes (empty series, unknown region) raise :class:`PlotError` with one line.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from contextvars import ContextVar
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import PolyCollection
from matplotlib.figure import Figure
from matplotlib.patches import Patch, Rectangle

from msgs_json.names import is_catalogue_name, is_sat_name, sat_plane_slot

__all__ = [
    "PlotError",
    "also_as",
    "figure_contact_timeline",
    "figure_ground_tracks",
    "figure_info_age",
    "figure_latency_vs_gaps",
    "figure_observation_gantt",
    "figure_transiency_sweep",
    "figure_value_over_time",
    "figure_value_snapshot",
    "plot_contact_timeline",
    "plot_ground_tracks",
    "plot_info_age",
    "plot_latency_vs_gaps",
    "plot_observation_gantt",
    "plot_osse_snapshot",
    "plot_transiency_sweep",
    "plot_value_over_time",
    "plot_value_snapshot",
    "save_figure",
]

_KM_PER_DEG = 111.32
_DPI = 120


class PlotError(ValueError):
    """Data a plot cannot draw; the message is one line naming the plot and the problem."""


#: the vector formats a figure can also be written in, beside its PNG
VECTOR_FORMATS = ("svg", "pdf")
_EXTRA_FORMATS: ContextVar[tuple[str, ...]] = ContextVar("figure_formats", default=())


@contextmanager
def also_as(formats) -> Iterator[None]:
    """Within the block, :func:`save_figure` also writes each figure in ``formats`` (of
    VECTOR_FORMATS), beside the PNG with the format's suffix (``--plot-formats svg,pdf``)."""
    extra = tuple(dict.fromkeys(f for f in formats if f != "png"))
    bad = [f for f in extra if f not in VECTOR_FORMATS]
    if bad:
        raise PlotError(f"figure formats {', '.join(bad)}: not one of png, {', '.join(VECTOR_FORMATS)}")
    token = _EXTRA_FORMATS.set(extra)
    try:
        yield
    finally:
        _EXTRA_FORMATS.reset(token)


def save_figure(fig: Figure, path: str | Path) -> Path:
    """Write a figure as PNG (folders created), and in the formats of an enclosing :func:`also_as`
    beside it; return the PNG's path."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    FigureCanvasAgg(fig)
    fig.savefig(p, dpi=_DPI, format="png")
    for fmt in _EXTRA_FORMATS.get():
        fig.savefig(p.with_suffix(f".{fmt}"), format=fmt)
    return p


def _get(obj: Any, key: str, default: Any = None) -> Any:
    if isinstance(obj, Mapping):
        return obj.get(key, default)
    return getattr(obj, key, default)


def _plane_of(name: str) -> str:
    """A Walker satellite's plane number; a catalogue satellite (sat_n<NORAD>) is its own group."""
    return str(sat_plane_slot(name)[0]) if is_sat_name(name) and not is_catalogue_name(name) else name


def _colors(n: int) -> list:
    cmap = colormaps["tab10" if n <= 10 else "tab20"]
    return [cmap(i % cmap.N) for i in range(n)]


# --------------------------------------------------------------------------------------------
# Ground tracks
# --------------------------------------------------------------------------------------------
def figure_ground_tracks(tracks: Mapping[str, tuple[Sequence[float], Sequence[float]]],
                         regions: Sequence[Any] = (), stations: Sequence[Any] = (),
                         title: str = "Ground tracks and regions") -> Figure:
    """Sub-satellite points per satellite and region squares on a plain lat/lon map.

    tracks: sat name -> (lat_deg[], lon_deg[]). Satellites (``sat_PS``, ``sat_PPPP_SSSS``) share
    a colour per plane P. regions / stations: dicts or objects with name, lat_deg, lon_deg (and size_km for
    square regions, or outline_deg, GeoJSON MultiPolygon coordinates, for drawn shapes). Tracks are broken
    where they cross the dateline.
    """
    if not tracks:
        raise PlotError("ground tracks: no satellite tracks given")
    fig = Figure(figsize=(12, 6.2), layout="constrained")
    ax = fig.add_subplot()
    from bringup.analysis.coastlines import land_polygons

    for xy in land_polygons():  # GSHHS crude shorelines (bringup/analysis/coastlines.py)
        ax.plot(xy[:, 0], xy[:, 1], lw=0.4, color="0.55", zorder=0, gid="coastline")
    planes = sorted({_plane_of(n) for n in tracks}, key=lambda p: (not p.isdigit(), int(p) if p.isdigit() else 0, p))
    pcol = dict(zip(planes, _colors(len(planes)), strict=True))
    labelled = set()
    for name in sorted(tracks):
        lat, lon = (np.asarray(a, dtype=float) for a in tracks[name])
        if lat.shape != lon.shape:
            raise PlotError(f"ground tracks: '{name}' has {lat.size} latitudes but {lon.size} longitudes")
        lon = (lon + 180.0) % 360.0 - 180.0
        jump = np.flatnonzero(np.abs(np.diff(lon)) > 180.0) + 1
        lat_b, lon_b = np.insert(lat, jump, np.nan), np.insert(lon, jump, np.nan)
        pl = _plane_of(name)
        label = f"plane {pl}" if pl not in labelled and pl != name else (name if pl == name else None)
        labelled.add(pl)
        ax.plot(lon_b, lat_b, lw=0.7, alpha=0.75, color=pcol[pl], label=label, gid=f"track:{name}")
        ax.plot(lon[:1], lat[:1], "o", ms=3, color=pcol[pl])
    for r in regions:
        lat0, lon0 = float(_get(r, "lat_deg")), float(_get(r, "lon_deg"))
        outline = _get(r, "outline_deg", None)
        if outline is not None:  # a drawn shape: its rings ([[[lon, lat], ...], ...] per polygon)
            for poly in outline:
                for ring in poly:
                    xy = np.asarray(ring, dtype=float)
                    ax.plot((xy[:, 0] + 180.0) % 360.0 - 180.0, xy[:, 1], color="crimson", lw=1.5,
                            gid=f"region:{_get(r, 'name')}")
        else:
            h = float(_get(r, "size_km", 80.0)) / _KM_PER_DEG
            w = h / max(math.cos(math.radians(lat0)), 0.05)
            ax.add_patch(Rectangle((lon0 - w / 2, lat0 - h / 2), w, h, fill=False, ec="crimson", lw=1.5,
                                   gid=f"region:{_get(r, 'name')}"))
        ax.plot([lon0], [lat0], marker="s", ms=9, mfc="none", mec="crimson", mew=1.8)
        ax.annotate(str(_get(r, "name")), (lon0, lat0), xytext=(6, 6), textcoords="offset points",
                    color="crimson", fontsize=10, fontweight="bold",
                    bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.7})
    for s in stations:
        ax.plot([float(_get(s, "lon_deg"))], [float(_get(s, "lat_deg"))], "^", ms=9, color="black",
                gid=f"station:{_get(s, 'name')}")
        ax.annotate(str(_get(s, "name")), (float(_get(s, "lon_deg")), float(_get(s, "lat_deg"))),
                    xytext=(6, -12), textcoords="offset points", fontsize=9)
    ax.set_xlim(-180, 180)
    ax.set_ylim(-90, 90)
    ax.set_aspect("equal")
    ax.set_xticks(range(-180, 181, 30))
    ax.set_yticks(range(-90, 91, 30))
    ax.grid(True, lw=0.4, alpha=0.5)
    ax.set_xlabel("longitude [deg]")
    ax.set_ylabel("latitude [deg]")
    ax.set_title(title)
    extra = [Patch(fc="none", ec="crimson", label="region")]
    handles, _ = ax.get_legend_handles_labels()
    ax.legend(handles=handles + extra, loc="lower left", fontsize=8, ncol=min(6, len(handles) + 1),
              framealpha=0.85)
    return fig


def plot_ground_tracks(path: str | Path, tracks, regions=(), stations=(), **kw) -> Path:
    """PNG of :func:`figure_ground_tracks`; returns the path."""
    return save_figure(figure_ground_tracks(tracks, regions, stations, **kw), path)


# --------------------------------------------------------------------------------------------
# OSSE value snapshot per region
# --------------------------------------------------------------------------------------------
def _spacing_km(x: np.ndarray, y: np.ndarray) -> float:
    if x.size < 2:
        return 8.0
    d = np.hypot(x[:, None] - x[None, :], y[:, None] - y[None, :])
    np.fill_diagonal(d, np.inf)
    return float(np.median(d.min(axis=1)))


def figure_value_snapshot(lat_deg: Sequence[float], lon_deg: Sequence[float], region_index: Sequence[int],
                          values: Sequence[float], region_names: Sequence[str], title: str = "",
                          vmin: float = 1, vmax: float = 256) -> Figure:
    """One panel per region: each GP a square (side = GP spacing) coloured by its value.

    Axes are east/north offsets [km] from the region's mean GP position.
    """
    lat, lon = np.asarray(lat_deg, float), np.asarray(lon_deg, float)
    reg, val = np.asarray(region_index, int), np.asarray(values, float)
    if not (lat.shape == lon.shape == reg.shape == val.shape) or lat.ndim != 1:
        raise PlotError(f"value snapshot: lat {lat.shape}, lon {lon.shape}, region {reg.shape}, value "
                        f"{val.shape} must be equal-length 1-D arrays")
    present = [r for r in range(len(region_names)) if np.any(reg == r)]
    if not present:
        raise PlotError("value snapshot: no GP belongs to any of the named regions")
    n = len(present)
    ncol = min(n, 3)
    nrow = math.ceil(n / ncol)
    fig = Figure(figsize=(3.1 * ncol + 0.9, 3.2 * nrow + 0.5), layout="constrained")
    axes = fig.subplots(nrow, ncol, squeeze=False)
    coll = None
    for k, r in enumerate(present):
        ax = axes[k // ncol][k % ncol]
        idx = np.flatnonzero(reg == r)
        lat0, lon0 = lat[idx].mean(), lon[idx].mean()
        x = ((lon[idx] - lon0 + 180) % 360 - 180) * _KM_PER_DEG * math.cos(math.radians(lat0))
        y = (lat[idx] - lat0) * _KM_PER_DEG
        h = 0.51 * _spacing_km(x, y)            # a hair over half: no hairline gaps between squares
        sq = np.stack([np.column_stack([x - h, y - h]), np.column_stack([x + h, y - h]),
                       np.column_stack([x + h, y + h]), np.column_stack([x - h, y + h])], axis=1)
        coll = PolyCollection(sq, array=val[idx], cmap="viridis", clim=(vmin, vmax), edgecolors="face", linewidths=0.3,
                              gid=f"snapshot:{region_names[r]}")
        ax.add_collection(coll)
        ax.set_xlim(x.min() - 2 * h, x.max() + 2 * h)
        ax.set_ylim(y.min() - 2 * h, y.max() + 2 * h)
        ax.set_aspect("equal")
        ax.set_title(f"{region_names[r]}  (max {int(val[idx].max())})", fontsize=10)
        ax.set_xlabel("east [km]", fontsize=8)
        ax.set_ylabel("north [km]", fontsize=8)
        ax.tick_params(labelsize=7)
    for k in range(n, nrow * ncol):
        axes[k // ncol][k % ncol].set_visible(False)
    fig.colorbar(coll, ax=axes, label="flood value (1..256)", shrink=0.9)
    if title:
        fig.suptitle(title)
    return fig


def plot_value_snapshot(path: str | Path, lat_deg, lon_deg, region_index, values, region_names, **kw) -> Path:
    """PNG of :func:`figure_value_snapshot`; returns the path."""
    return save_figure(figure_value_snapshot(lat_deg, lon_deg, region_index, values, region_names, **kw), path)


def plot_osse_snapshot(path: str | Path, field: Any, slot: int = 0) -> Path:
    """PNG of one slot of an OSSE field (``ground_station.OsseField``), one panel per region."""
    if not 0 <= int(slot) < field.n_slots:
        raise PlotError(f"OSSE snapshot: slot {slot} outside 0..{field.n_slots - 1}")
    t_h = int(slot) * field.slot_s / 3600.0
    title = f"OSSE value ({field.source}), slot {int(slot)}: t = {t_h:.2f} h after epoch"
    return plot_value_snapshot(path, field.lat_deg, field.lon_deg, field.region_index, field.snapshot(slot),
                               field.region_names, title=title)


# --------------------------------------------------------------------------------------------
# Observation Gantt chart
# --------------------------------------------------------------------------------------------
def _t_s(o: Any) -> float:
    t = _get(o, "t_s")
    if t is None and _get(o, "t_ns") is not None:
        t = int(_get(o, "t_ns")) / 1e9
    if t is None:
        raise PlotError(f"observation {o!r}: needs 't_s' or 't_ns'")
    return float(t)


def figure_observation_gantt(observations: Sequence[Any], sat_names: Sequence[str] | None = None,
                             region_names: Sequence[str] | None = None,
                             title: str = "Observations per satellite") -> Figure:
    """Rows satellites, a mark at each observation time [h], coloured by region.

    observations: dicts/objects with ``sat``, ``t_s`` (or ``t_ns``) and ``region`` (name or index
    into region_names).
    """
    if not observations:
        raise PlotError("observation Gantt: no observations given")
    sats = list(sat_names) if sat_names else sorted({str(_get(o, "sat")) for o in observations})
    row = {s: i for i, s in enumerate(sats)}
    regs_seen = []
    for o in observations:
        r = _get(o, "region")
        if isinstance(r, (int, np.integer)) and region_names is not None:
            r = region_names[int(r)]
        if r not in regs_seen:
            regs_seen.append(r)
    regs = list(region_names) if region_names else sorted(regs_seen, key=str)
    rcol = dict(zip(regs, _colors(len(regs)), strict=True))
    pts: dict[Any, tuple[list, list]] = {r: ([], []) for r in regs}
    for o in observations:
        s, r = str(_get(o, "sat")), _get(o, "region")
        if isinstance(r, (int, np.integer)) and region_names is not None:
            r = region_names[int(r)]
        if s not in row:
            raise PlotError(f"observation Gantt: satellite '{s}' is not in sat_names")
        if r not in pts:
            raise PlotError(f"observation Gantt: region '{r}' is not in region_names")
        pts[r][0].append(_t_s(o) / 3600.0)
        pts[r][1].append(row[s])
    fig = Figure(figsize=(12, 1.2 + 0.28 * len(sats)), layout="constrained")
    ax = fig.add_subplot()
    for r in regs:
        t_h, y = pts[r]
        if t_h:
            ax.scatter(t_h, y, marker="|", s=140, linewidths=1.2, color=rcol[r], label=f"{r} ({len(t_h)})",
                       gid=f"gantt:{r}")
    ax.set_yticks(range(len(sats)), sats, fontsize=8)
    ax.set_ylim(len(sats) - 0.5, -0.5)
    ax.set_xlabel("time since epoch [h]")
    ax.grid(True, axis="x", lw=0.4, alpha=0.5)
    ax.set_title(f"{title} ({len(observations)} observations)")
    ax.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8, title="region")
    return fig


def plot_observation_gantt(path: str | Path, observations, sat_names=None, region_names=None, **kw) -> Path:
    """PNG of :func:`figure_observation_gantt`; returns the path."""
    return save_figure(figure_observation_gantt(observations, sat_names, region_names, **kw), path)


# --------------------------------------------------------------------------------------------
# Contact plan timeline
# --------------------------------------------------------------------------------------------
def _merge(windows: list[tuple[float, float]]) -> list[tuple[float, float]]:
    out: list[list[float]] = []
    for a, b in sorted(windows):
        if out and a <= out[-1][1]:
            out[-1][1] = max(out[-1][1], b)
        else:
            out.append([a, b])
    return [(a, b) for a, b in out]


def figure_contact_timeline(plan: Any, title: str = "Contact plan", max_rows: int | None = None) -> Figure:
    """Rows unordered node pairs, one bar per window (both directions merged) [h].

    plan: an ``orbit_clock.contact_plan.ContactPlan`` (or any iterable of objects with start_s,
    end_s, src, dst). Satellite-satellite pairs come first (blue), pairs with a ground node after
    (orange). ``max_rows`` draws only the pairs with the most contact time; the title always counts
    the whole plan, and says how many rows are drawn when not all are.
    """
    by_pair: dict[tuple[str, str], list[tuple[float, float]]] = {}
    for c in plan:
        key = tuple(sorted((str(c.src), str(c.dst))))
        by_pair.setdefault(key, []).append((float(c.start_s), float(c.end_s)))
    if not by_pair:
        raise PlotError("contact timeline: the plan has no contacts")
    merged = {k: _merge(v) for k, v in by_pair.items()}
    pairs = list(merged)
    n_pairs, n_windows = len(pairs), sum(len(w) for w in merged.values())
    if max_rows is not None and len(pairs) > max_rows:
        pairs = sorted(pairs, key=lambda k: -sum(b - a for a, b in merged[k]))[:max_rows]

    def is_ground(k):
        return not (k[0].startswith("sat_") and k[1].startswith("sat_"))

    pairs.sort(key=lambda k: (is_ground(k), k))
    fig = Figure(figsize=(12, 1.4 + 0.16 * len(pairs)), layout="constrained")
    ax = fig.add_subplot()
    for i, k in enumerate(pairs):
        bars = [(a / 3600.0, (b - a) / 3600.0) for a, b in merged[k]]
        ax.broken_barh(bars, (i - 0.4, 0.8), facecolors="tab:orange" if is_ground(k) else "tab:blue",
                       gid=f"pair:{k[0]}-{k[1]}")
    ax.set_yticks(range(len(pairs)), [f"{a} - {b}" for a, b in pairs], fontsize=6 if len(pairs) > 40 else 8)
    ax.set_ylim(len(pairs) - 0.5, -0.5)
    ax.set_xlabel("time since epoch [h]")
    ax.grid(True, axis="x", lw=0.4, alpha=0.5)
    shown = "" if len(pairs) == n_pairs else f" ({len(pairs)} pairs with the most contact time drawn)"
    ax.set_title(f"{title}: {n_pairs} node pairs, {n_windows} windows{shown}")
    kinds = [Patch(fc="tab:blue", label="inter-satellite")] if not all(map(is_ground, pairs)) else []
    kinds += [Patch(fc="tab:orange", label="ground")] if any(map(is_ground, pairs)) else []
    ax.legend(handles=kinds, loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8)
    return fig


def plot_contact_timeline(path: str | Path, plan, **kw) -> Path:
    """PNG of :func:`figure_contact_timeline`; returns the path."""
    return save_figure(figure_contact_timeline(plan, **kw), path)


# --------------------------------------------------------------------------------------------
# Value accumulated over time per mode
# --------------------------------------------------------------------------------------------
def figure_value_over_time(series: Mapping[str, tuple[Sequence[float], Sequence[float]]],
                           cumulative_input: bool = False, horizon_s: float | None = None,
                           title: str = "Value accumulated over time") -> Figure:
    """One step line per mode: cumulative value against time [h].

    series: mode -> (t_s[], value[]). By default value[] holds the value of each observation (it is
    sorted by time and summed); with ``cumulative_input=True`` it is already the running total.
    """
    if not series:
        raise PlotError("value over time: no series given")
    fig = Figure(figsize=(9, 5), layout="constrained")
    ax = fig.add_subplot()
    for (mode, (t_s, v)), color in zip(series.items(), _colors(len(series)), strict=True):
        t, val = np.asarray(t_s, float), np.asarray(v, float)
        if t.shape != val.shape or t.ndim != 1:
            raise PlotError(f"value over time: '{mode}' has {t.size} times but {val.size} values")
        order = np.argsort(t, kind="stable")
        t, val = t[order], val[order]
        cum = val if cumulative_input else np.cumsum(val)
        t_h = np.concatenate([[0.0], t / 3600.0])
        cum = np.concatenate([[0.0], cum])
        if horizon_s is not None:
            t_h, cum = np.append(t_h, horizon_s / 3600.0), np.append(cum, cum[-1])
        ax.step(t_h, cum, where="post", lw=1.8, color=color, label=f"{mode} ({cum[-1]:.0f})", gid=f"mode:{mode}")
    ax.set_xlabel("time since epoch [h]")
    ax.set_ylabel("cumulative value")
    ax.grid(True, lw=0.4, alpha=0.5)
    ax.set_title(title)
    ax.legend(loc="upper left")
    return fig


def plot_value_over_time(path: str | Path, series, **kw) -> Path:
    """PNG of :func:`figure_value_over_time`; returns the path."""
    return save_figure(figure_value_over_time(series, **kw), path)


# --------------------------------------------------------------------------------------------
# Latency vs access gaps by priority (the study's Fig. 5)
# --------------------------------------------------------------------------------------------
def figure_latency_vs_gaps(latency_s_by_priority: Mapping[int, Sequence[float]],
                           gap_s_by_priority: Mapping[int, Sequence[float]],
                           before_fraction_by_priority: Mapping[int, float] | None = None,
                           title: str = "Bundle latency vs access gaps by priority") -> Figure:
    """Side-by-side box plots per priority: bundle latency [s] and the gap [s] between successive
    satellite accesses to a region, on a log axis. Optional: per priority, the fraction of bundles
    that arrive before the destination reaches the region (printed above the boxes).
    """
    prios = sorted({int(p) for p in latency_s_by_priority} | {int(p) for p in gap_s_by_priority})
    lat = {int(k): np.asarray(v, float) for k, v in latency_s_by_priority.items()}
    gap = {int(k): np.asarray(v, float) for k, v in gap_s_by_priority.items()}
    if not any(a.size for a in lat.values()) and not any(a.size for a in gap.values()):
        raise PlotError("latency vs gaps: every priority is empty")
    fig = Figure(figsize=(max(8, 0.75 * len(prios) + 3), 5.2), layout="constrained")
    ax = fig.add_subplot()
    boxes = {"latency": 0, "gap": 0}
    for kind, data, off, color in (("latency", lat, -0.2, "tab:blue"), ("gap", gap, 0.2, "tab:orange")):
        pos, vals = [], []
        for i, p in enumerate(prios):
            a = data.get(p, np.empty(0))
            a = a[np.isfinite(a) & (a > 0)]
            if a.size:
                pos.append(i + off)
                vals.append(a)
        if vals:
            bp = ax.boxplot(vals, positions=pos, widths=0.34, patch_artist=True, manage_ticks=False,
                            flierprops={"marker": ".", "ms": 3, "alpha": 0.5})
            for b in bp["boxes"]:
                b.set(facecolor=color, alpha=0.6, gid=f"box:{kind}")
            boxes[kind] = len(vals)
    if before_fraction_by_priority:
        top = ax.secondary_xaxis("top")
        ticks = [i for i, p in enumerate(prios) if p in before_fraction_by_priority]
        top.set_xticks(ticks, [f"{100 * before_fraction_by_priority[prios[i]]:.0f}%" for i in ticks], fontsize=8)
        top.set_xlabel("bundles arrived before the destination reached the region", fontsize=9)
    ax.set_yscale("log")
    ax.set_xticks(range(len(prios)), [str(p) for p in prios])
    ax.set_xlim(-0.6, len(prios) - 0.4)
    ax.set_xlabel("bundle priority (1 = next satellite to reach the region)")
    ax.set_ylabel("seconds (log)")
    ax.grid(True, axis="y", which="both", lw=0.3, alpha=0.5)
    ax.set_title(title)
    ax.legend(handles=[Patch(fc="tab:blue", alpha=0.6, label=f"bundle latency ({boxes['latency']} priorities)"),
                       Patch(fc="tab:orange", alpha=0.6, label=f"access gap ({boxes['gap']} priorities)")],
              loc="upper left")
    fig._box_counts = boxes  # for tests: how many boxes of each kind were drawn
    return fig


def plot_latency_vs_gaps(path: str | Path, latency_s_by_priority, gap_s_by_priority, **kw) -> Path:
    """PNG of :func:`figure_latency_vs_gaps`; returns the path."""
    return save_figure(figure_latency_vs_gaps(latency_s_by_priority, gap_s_by_priority, **kw), path)


def figure_transiency_sweep(rows: Sequence[Mapping[str, Any]], title: str = "",
                            study: tuple[float, float] | None = (15.0, 26347 / 21820)) -> Figure:
    """Rows ``{"transiency_min", "measured_min", "mean", "ci95", "values"}``: the ratio's mean with
    its 95 % interval per transiency (log axis), the seeds' values as dots, 1 as a line, and the
    study's point (15 min, +21 %)."""
    rows = [r for r in rows if r.get("mean") is not None]
    if not rows:
        raise PlotError("transiency sweep: no row with a value")
    fig = Figure(figsize=(6.4, 4.0))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    x = np.array([float(r["transiency_min"]) for r in rows])
    m = np.array([float(r["mean"]) for r in rows])
    e = np.array([float(r["ci95"] or 0.0) for r in rows])
    ax.errorbar(x, m, yerr=e, fmt="o-", color="C0", capsize=4, label="distributed / centralized (mean, 95 % CI)")
    for r in rows:
        v = r.get("values") or []
        ax.plot([float(r["transiency_min"])] * len(v), v, ".", color="C0", alpha=0.35)
    ax.axhline(1.0, color="0.5", lw=0.8)
    if study is not None:
        ax.plot([study[0]], [study[1]], "*", ms=12, color="C3", label="the study (15 min, +21 %)")
    ax.set_xscale("log")
    ax.set_xticks(x)
    ax.set_xticklabels([f"{v:g}" for v in x])
    ax.set_xlabel("field transiency [min] (lag at which the rank correlation falls to 0.5)")
    ax.set_ylabel("cumulative value, distributed / centralized")
    ax.set_title(title or "Reactive imaging against the field's time scale")
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    return fig


def plot_transiency_sweep(path: str | Path, rows, **kw) -> Path:
    return save_figure(figure_transiency_sweep(rows, **kw), path)


def figure_info_age(ages_s: Mapping[str, Sequence[float]], title: str = "") -> Figure:
    """One histogram per label (mode or knowledge model) of the information age [min] of its looks."""
    ages = {k: np.asarray(v, dtype=float) / 60.0 for k, v in ages_s.items() if len(v)}
    if not ages:
        raise PlotError("information age: no looks")
    fig = Figure(figsize=(6.4, 4.0))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    top = max(float(np.percentile(a, 99)) for a in ages.values())
    bins = np.linspace(0.0, max(top, 1.0), 40)
    for i, (k, a) in enumerate(ages.items()):
        ax.hist(np.clip(a, 0, bins[-1]), bins=bins, histtype="step", lw=1.5, color=f"C{i}",
                label=f"{k} (median {np.median(a):.0f} min)")
    ax.set_xlabel("age of the information a look was planned with [min]")
    ax.set_ylabel("looks")
    ax.set_title(title or "Information age")
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    return fig


def plot_info_age(path: str | Path, ages_s, **kw) -> Path:
    return save_figure(figure_info_age(ages_s, **kw), path)
