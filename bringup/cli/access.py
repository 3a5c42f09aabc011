"""`constellation access`: ground-point access windows of every satellite within the field of regard.

Checked by tests/unit/test_orbit_cli.py.
"""

from __future__ import annotations

import csv
import json

from bringup.cli.common import add_out_arg, add_scenario_args, output_stream, scenario_from_args
from bringup.scenario.world import for_deg_per_sat
from orbit_clock.access import access_windows
from orbit_clock.ground_points import ground_points
from orbit_clock.propagation import build_constellation

_COLUMNS = ["sat", "region", "gp", "lat_deg", "lon_deg", "start_s", "end_s", "min_off_nadir_deg"]


def add_arguments(p) -> None:
    add_scenario_args(p)
    p.add_argument("--format", choices=["csv", "json"], default="csv", help="output format (default csv)")
    add_out_arg(p)


def run(args) -> int:
    sc = scenario_from_args(args)
    cons = build_constellation(sc)
    gps = ground_points(sc)
    win = access_windows(cons, gps, 0.0, float(sc.scenario.horizon_s), for_deg_per_sat(sc))
    rows = list(win.rows(gps))
    with output_stream(args.out) as out:
        if args.format == "csv":
            w = csv.writer(out, lineterminator="\n")
            w.writerow(_COLUMNS)
            for r in rows:
                w.writerow([r["sat"], r["region"], r["gp"], f"{r['lat_deg']:.6f}", f"{r['lon_deg']:.6f}",
                            f"{r['start_s']:.3f}", f"{r['end_s']:.3f}", f"{r['min_off_nadir_deg']:.4f}"])
        else:
            json.dump({"scenario": sc.name, "epoch_utc": sc.epoch_iso,
                       "max_off_nadir_deg": win.max_off_nadir_deg, "windows": rows}, out, indent=1)
            out.write("\n")
    return 0
