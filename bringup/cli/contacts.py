"""`constellation contacts`: the contact plan (ISL line of sight and/or ground-station passes).

``--format ion`` starts with the scenario epoch as ionadmin's ``@`` reference time; ``ion`` and
``hdtn-json`` hold whole seconds, rounded as orbit_clock/contact_plan_io.py says (windows inward,
rates down, light times up); contacts left with no whole second are counted on stderr.
``--unix-time`` writes HDTN times as Unix seconds (HDTN's ``--use-unix-timestamp``);
``--ion-times absolute`` writes ION times as ``yyyy/mm/dd-hh:mm:ss`` UTC on every line. With
``--epoch now`` (or any UTC instant) the plan's instants are those of a live run started then.

Checked by tests/unit/test_orbit_cli.py and tests/unit/test_contact_plan_io.py.
"""

from __future__ import annotations

import sys

from bringup.cli.common import add_out_arg, add_scenario_args, output_stream, scenario_from_args
from bringup.errors import UserError
from orbit_clock.contact_plan import ContactPlan
from orbit_clock.contact_plan_io import ContactPlanError, write_contact_plan
from orbit_clock.ground_passes import ground_contact_plan, station_names
from orbit_clock.isl import isl_contact_plan
from orbit_clock.propagation import build_constellation


def add_arguments(p) -> None:
    add_scenario_args(p)
    p.add_argument("--format", choices=["csv", "ion", "hdtn-json"], default="csv", help="output format (default csv)")
    p.add_argument("--links", choices=["all", "isl", "ground"], default="all",
                   help="which contacts: ISL, ground-station passes or both (default all)")
    p.add_argument("--unix-time", action="store_true",
                   help="hdtn-json: times as Unix seconds (for HDTN's --use-unix-timestamp) instead of seconds "
                        "since the scenario epoch")
    p.add_argument("--ion-times", choices=["relative", "absolute"], default="relative",
                   help="ion: contact times as +N seconds after the '@' epoch line (default) or as absolute "
                        "yyyy/mm/dd-hh:mm:ss UTC on every line")
    add_out_arg(p)


def run(args) -> int:
    if args.ion_times != "relative" and args.format != "ion":
        raise UserError("--ion-times applies to --format ion only")
    if args.unix_time and args.format != "hdtn-json":
        raise UserError("--unix-time applies to --format hdtn-json only (ION plans carry the epoch in their '@' line)")
    sc = scenario_from_args(args)
    cons = build_constellation(sc)
    contacts = []
    if args.links in ("all", "isl"):
        contacts += isl_contact_plan(sc, cons).contacts
    if args.links in ("all", "ground"):
        contacts += ground_contact_plan(sc, cons).contacts
    try:
        with output_stream(args.out) as out:
            w = write_contact_plan(ContactPlan(contacts), args.format, out, ground_stations=station_names(sc),
                                   epoch_utc=sc.epoch, unix_time=args.unix_time, ion_times=args.ion_times)
    except ContactPlanError as exc:
        raise UserError(str(exc)) from None
    if w.dropped:
        print(f"contacts: {len(w.dropped)} of {len(contacts)} contacts left out: no whole second inside their "
              f"window (shortest {min(c.duration_s for c in w.dropped):.3f} s)", file=sys.stderr)
    return 0
