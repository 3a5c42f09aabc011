"""`constellation constellation`: each satellite's orbital elements at the scenario epoch.

Checked by tests/unit/test_orbit_cli.py.
"""

from __future__ import annotations

import csv
import json

from bringup.cli.common import add_out_arg, add_scenario_args, output_stream, scenario_from_args
from orbit_clock.propagation import build_constellation

_COLUMNS = ["name", "plane", "slot", "sma_km", "inc_deg", "raan_deg", "arglat_deg", "epoch_utc"]


def add_arguments(p) -> None:
    add_scenario_args(p)
    p.add_argument("--format", choices=["json", "csv"], default="json", help="output format (default json)")
    add_out_arg(p)


def run(args) -> int:
    sc = scenario_from_args(args)
    cons = build_constellation(sc)
    rows = [{k: getattr(e, k) for k in _COLUMNS} for e in cons.elements]
    c = sc.constellation
    with output_stream(args.out) as out:
        if args.format == "json":
            doc = {"scenario": sc.name, "epoch_utc": sc.scenario.epoch_utc, "pattern": c.pattern,
                   "walker": f"{c.inclination_deg}:{c.total_sats}/{c.planes}/{c.phasing_f}",
                   "altitude_km": c.altitude_km, "propagator": "SGP4 (WGS-84, sgp4init, no drag)",
                   "satellites": rows}
            json.dump(doc, out, indent=1)
            out.write("\n")
        else:
            w = csv.DictWriter(out, fieldnames=_COLUMNS, lineterminator="\n")
            w.writeheader()
            w.writerows(rows)
    return 0
