"""`constellation contacts`: the contact plan (ISL line of sight and/or ground-station passes).

Checked by tests/unit/test_orbit_cli.py and tests/unit/test_contact_plan_io.py.
"""

from __future__ import annotations

from bringup.cli.common import add_out_arg, add_scenario_args, output_stream, scenario_from_args
from orbit_clock.contact_plan import ContactPlan, write_contact_plan
from orbit_clock.ground_passes import ground_contact_plan, station_names
from orbit_clock.isl import isl_contact_plan
from orbit_clock.propagation import build_constellation


def add_arguments(p) -> None:
    add_scenario_args(p)
    p.add_argument("--format", choices=["csv", "ion", "hdtn-json"], default="csv", help="output format (default csv)")
    p.add_argument("--links", choices=["all", "isl", "ground"], default="all",
                   help="which contacts: ISL, ground-station passes or both (default all)")
    add_out_arg(p)


def run(args) -> int:
    sc = scenario_from_args(args)
    cons = build_constellation(sc)
    contacts = []
    if args.links in ("all", "isl"):
        contacts += isl_contact_plan(sc, cons).contacts
    if args.links in ("all", "ground"):
        contacts += ground_contact_plan(sc, cons).contacts
    with output_stream(args.out) as out:
        write_contact_plan(ContactPlan(contacts), args.format, out, ground_stations=station_names(sc))
    return 0
