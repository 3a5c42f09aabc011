"""`constellation constellation`: each satellite's orbital elements, source and payload.

A Walker satellite lists its circular elements at the scenario epoch (plane, slot, sma_km,
inc_deg, raan_deg, arglat_deg); a catalogue satellite (``--tle`` / ``--omm`` or the scenario's
element files, bringup/scenario/fleet.py) its NORAD number, catalogue name, where its element set
came from and the set's own mean elements and epoch. Every row carries the satellite's field of
regard, footprint and ISL radio.

Checked by tests/unit/test_orbit_cli.py (Walker) and tests/unit/test_fleet.py (catalogue and mixed).
"""

from __future__ import annotations

import csv
import json

from bringup.cli.common import add_out_arg, add_scenario_args, output_stream, scenario_from_args
from bringup.scenario import fleet
from orbit_clock.elements import ElementSet

_WALKER = ["name", "plane", "slot", "sma_km", "inc_deg", "raan_deg", "arglat_deg", "epoch_utc"]
_CATALOGUE = ["norad", "label", "source", "ecc", "mean_motion_rev_day", "arg_perigee_deg", "mean_anomaly_deg",
              "bstar"]
_PAYLOAD = ["for_off_nadir_deg", "footprint_km", "isl_rate_bps", "isl_max_range_km"]


def add_arguments(p) -> None:
    add_scenario_args(p)
    p.add_argument("--format", choices=["json", "csv"], default="json", help="output format (default json)")
    add_out_arg(p)


def _row(e, p: fleet.SatParams, catalogue: bool) -> dict:
    if isinstance(e, ElementSet):
        f = dict(e.fields)
        row = {"name": e.name, "plane": "", "slot": "", "sma_km": "", "inc_deg": float(f["INCLINATION"]),
               "raan_deg": float(f["RA_OF_ASC_NODE"]), "arglat_deg": "", "epoch_utc": e.epoch_utc,
               "norad": e.norad, "label": e.label, "source": e.where, "ecc": float(f["ECCENTRICITY"]),
               "mean_motion_rev_day": float(f["MEAN_MOTION"]), "arg_perigee_deg": float(f["ARG_OF_PERICENTER"]),
               "mean_anomaly_deg": float(f["MEAN_ANOMALY"]), "bstar": float(f["BSTAR"])}
    else:
        row = {k: getattr(e, k) for k in _WALKER}
        if catalogue:
            row.update({k: "" for k in _CATALOGUE})
    if catalogue:
        row.update({"for_off_nadir_deg": p.for_off_nadir_deg, "footprint_km": p.footprint_km,
                    "isl_rate_bps": p.isl_rate_bps, "isl_max_range_km": p.isl_max_range_km})
    return row


def run(args) -> int:
    sc = scenario_from_args(args)
    fl = fleet.resolve(sc)
    w = sc.walker
    catalogue = w is None or len(sc.groups) > 1  # a mixed or catalogue fleet: the wider table
    rows = [_row(e, p, catalogue) for e, p in zip(fl.elements, fl.params)]
    columns = _WALKER + (_CATALOGUE + _PAYLOAD if catalogue else [])
    with output_stream(args.out) as out:
        if args.format == "json":
            doc = {"scenario": sc.name, "epoch_utc": sc.epoch_iso}
            if w is not None:
                doc.update({"pattern": w.pattern, "walker": f"{w.inclination_deg}:{w.total_sats}/{w.planes}/{w.phasing_f}",
                            "altitude_km": w.altitude_km})
            doc["propagator"] = ("SGP4 (WGS-84, sgp4init, no drag)" if not catalogue else
                                 "SGP4 (Walker: WGS-84, sgp4init, no drag; catalogue: WGS-72, the element sets' own)")
            doc["satellites"] = [{k: r[k] for k in columns if r[k] != ""} for r in rows]
            json.dump(doc, out, indent=1)
            out.write("\n")
        else:
            wr = csv.DictWriter(out, fieldnames=columns, lineterminator="\n")
            wr.writeheader()
            wr.writerows(rows)
    return 0
