"""The plots of one run (PNG, bringup/analysis/figures.py), from its bag and world: written to OUT/plots/.

Ground tracks, OSSE snapshot, contact plan, observation Gantt chart, value over time, and for a
distributed run with bundles the study's Figure 5 (bringup/analysis/figure5.py).

Checked by tests/unit/test_cli_exit.py (a whole local run writes its plots) and, figure by
figure, tests/unit/test_plots.py.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image

from bringup.analysis import figures as plots
from bringup.analysis.figure5 import bundle_rows_from_bag, figure5_data, plot_figure5
from bringup.analysis.report import true_values
from bringup.recording.bag import BagReader
from msgs_json import codec
from orbit_clock import ecef_to_geodetic

__all__ = ["run_plots", "shrink_png"]

_NS = 1_000_000_000


def run_plots(out: Path, bag_dir: Path, world, rep: dict) -> list[Path]:
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
    made.append(plots.plot_ground_tracks(d / "ground_tracks.png", tracks, regions=sc.regions.list,
                                         stations=sc.ground.stations))
    made.append(plots.plot_osse_snapshot(d / "osse_snapshot.png", world.osse, slot=world.osse.n_slots // 2))
    if len(world.isl_plan):
        made.append(plots.plot_contact_timeline(d / "contact_plan.png", world.isl_plan, max_rows=60))
    with BagReader(bag_dir) as bag:
        topics = [x.topic for x in bag.topics() if x.topic.endswith("/observations")]
        obs = [codec.decode(e.topic, e.data) for e in bag.envelopes(topics)]
    if obs:
        rows = [{"sat": o.sat, "t_ns": o.t_ns, "region": world.region_of_gp(o.gp)} for o in obs]
        made.append(plots.plot_observation_gantt(d / "observations_gantt.png", rows, sat_names=world.sat_names,
                                                 region_names=[r.name for r in sc.regions.list]))
        tv = true_values(obs, sc.value.revisit_zero_s)
        made.append(plots.plot_value_over_time(
            d / "value_over_time.png", {rep["mode"]: ([o.t_ns / _NS for o, _, _ in tv], [v for _, v, _ in tv])},
            horizon_s=sc.scenario.horizon_s))
    if rep.get("mode") == "distributed" and (rep.get("dtn") or {}).get("bundles_created"):
        # the study's Fig. 5: bundle latency vs access gaps by priority (bringup/analysis/figure5.py)

        rows = bundle_rows_from_bag(bag_dir)
        if rows:
            data = figure5_data(rows, world.access, world.ctx.gps.region_index,
                                replan_period_s=sc.scheduler.replan_period_s)
            made.append(plot_figure5(d / "figure5.png", data))
    for p in made:
        shrink_png(p)
    return made


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
