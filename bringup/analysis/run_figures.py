"""The plots of one run (PNG, bringup/analysis/figures.py), from its bag and world: written to OUT/plots/.

Ground tracks, OSSE snapshot, contact plan, observation Gantt chart, value over time, and for a
distributed run with bundles the study's Figure 5 (bringup/analysis/figure5.py).

The bag is opened and read once for all of them (:func:`plot_inputs`): one pass over the
``/observations`` topics and, when Figure 5 is drawn, the ``/dtn/events`` topics, each decoded
into its own list in the bag's log-time order - what reading each set of topics alone gives (a
240-satellite hour's bag read twice cost ~3 s more: two metadata checks, every chunk decompressed
twice).

Checked by tests/unit/test_cli_exit.py (a whole local run writes its plots), figure by figure
tests/unit/test_plots.py, and test_plots.py's test_plot_inputs_equal_separate_reads (the one pass
gives what a read of each topic set gives).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image

from bringup.analysis import figures as plots
from bringup.analysis.figure5 import bundle_rows, figure5_data, plot_figure5
from bringup.analysis.report import true_values
from bringup.recording.bag import BagReader
from msgs_json import codec
from orbit_clock import ecef_to_geodetic

__all__ = ["plot_inputs", "run_plots", "shrink_png"]

_NS = 1_000_000_000


def run_plots(out: Path, bag_dir: Path, world, rep: dict, formats=("png",)) -> list[Path]:
    """The run's figures as PNG in ``out/plots`` (and in the vector ``formats`` beside them); the
    PNGs' paths."""
    with plots.also_as(formats):
        return _run_plots(out, bag_dir, world, rep)


def _run_plots(out: Path, bag_dir: Path, world, rep: dict) -> list[Path]:
    d = Path(out) / "plots"
    d.mkdir(parents=True, exist_ok=True)
    sc = world.scenario
    made: list[Path] = []
    t = np.arange(0.0, sc.scenario.horizon_s + 1, 60.0)
    pos = world.constellation.positions_ecef_km(t)

    tracks = {}
    for i, name in enumerate(world.sat_names):
        lat, lon, _ = ecef_to_geodetic(pos[i])
        tracks[name] = (np.asarray(lat), np.asarray(lon))
    g = world.gps
    regions = [r if r.shape_deg is None else  # a drawn shape: its outline, labelled at its GPs' centre
               {"name": r.name, "lat_deg": float(g.region_center_lat_deg[i]),
                "lon_deg": float(g.region_center_lon_deg[i]), "outline_deg": r.shape_deg}
               for i, r in enumerate(sc.regions.list)]
    made.append(plots.plot_ground_tracks(d / "ground_tracks.png", tracks, regions=regions,
                                         stations=sc.ground.stations))
    made.append(plots.plot_osse_snapshot(d / "osse_snapshot.png", world.osse, slot=world.osse.n_slots // 2))
    if len(world.isl_plan) or len(world.ground_plan):  # ISL and ground passes: the plan of `contacts`
        made.append(plots.plot_contact_timeline(d / "contact_plan.png", [*world.isl_plan, *world.ground_plan],
                                                max_rows=120))
    # the study's Fig. 5 (bundle latency vs access gaps by priority) for a distributed run with bundles
    fig5 = rep.get("mode") == "distributed" and bool((rep.get("dtn") or {}).get("bundles_created"))
    obs, events = plot_inputs(bag_dir, bundle_events=fig5)
    if obs:
        rows = [{"sat": o.sat, "t_ns": o.t_ns, "region": world.region_of_gp(o.gp)} for o in obs]
        made.append(plots.plot_observation_gantt(d / "observations_gantt.png", rows, sat_names=world.sat_names,
                                                 region_names=[r.name for r in sc.regions.list]))
        tv = true_values(obs, sc.value.revisit_zero_s)
        made.append(plots.plot_value_over_time(
            d / "value_over_time.png", {rep["mode"]: ([o.t_ns / _NS for o, _, _ in tv], [v for _, v, _ in tv])},
            horizon_s=sc.scenario.horizon_s))
    if fig5:
        rows = bundle_rows(events)  # (bringup/analysis/figure5.py)
        if rows:
            data = figure5_data(rows, world.access, world.ctx.gps.region_index,
                                replan_period_s=sc.scheduler.replan_period_s)
            made.append(plot_figure5(d / "figure5.png", data))
    for p in made:
        shrink_png(p)
    return made


def plot_inputs(bag_dir: Path, *, bundle_events: bool) -> tuple[list, list]:
    """(observations, bundle events): the decoded messages of the bag's ``/observations`` topics and,
    with ``bundle_events``, of its ``/dtn/events`` topics (else []), each list in log-time order,
    from one BagReader and one pass over the messages."""
    obs: list = []
    events: list = []
    with BagReader(bag_dir) as bag:
        names = [x.topic for x in bag.topics()]
        obs_topics = {t for t in names if t.endswith("/observations")}
        event_topics = {t for t in names if t.endswith("/dtn/events")} if bundle_events else set()
        if obs_topics or event_topics:
            for e in bag.envelopes(obs_topics | event_topics):
                (obs if e.topic in obs_topics else events).append(codec.decode(e.topic, e.data))
    return obs, events


def shrink_png(path: Path, max_bytes: int = 300_000, colors: int = 128) -> Path:
    """Re-save a PNG larger than ``max_bytes`` with a ``colors``-entry palette (ground tracks with
    24 anti-aliased colours come out near 1 MB; the palette version looks the same at a third)."""
    path = Path(path)
    if path.stat().st_size <= max_bytes:
        return path
    with Image.open(path) as im:
        q = im.convert("RGB").quantize(colors=colors, method=Image.Quantize.MEDIANCUT)
    q.save(path, format="PNG", optimize=True)
    return path
