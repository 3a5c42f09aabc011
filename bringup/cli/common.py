"""Argument helpers shared by subcommands.

Checked through the commands that use them (tests/unit/test_orbit_cli.py,
tests/faults/test_faults_scenario_cli.py: bad scenario arguments are one line).
"""

from __future__ import annotations

import argparse
import sys
from contextlib import contextmanager
from datetime import UTC, datetime
from pathlib import Path

from bringup.engine.keys import ENV_BPSEC_KEY, ENV_BPSEC_KEY_FILE, RunKeys
from bringup.errors import UserError
from bringup.scenario.config import KNOWLEDGE_MODELS, RENAMED_KNOWLEDGE, Scenario, load_scenario
from bringup.scenario.overrides import OPTION_KEYS, apply_sets, check_conflicts
from bringup.scenario.regions_geojson import regions_arg
from msgs_json.names import MAX_PLANES, MAX_SATS

_OVERRIDES = ("sats", "planes", "hours", "seed", "knowledge", "transiency_min", "gp_spacing_km", "joint_planning",
              "joint_max_partners", "forwarding", "epoch_utc")
from bringup.scenario.limits import check_run_size


def transiency_arg(text: str) -> float:
    """``--transiency-min``: minutes, or ``slow`` (0: the slow storm-cell field)."""
    if text.strip().lower() == "slow":
        return 0.0
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected minutes (e.g. 15, 60) or 'slow'") from None
    if v < 0:
        raise argparse.ArgumentTypeError(f"{text!r}: must be >= 0 minutes")
    return v


def knowledge_arg(text: str) -> str:
    """``--knowledge``: a model of sat_node/knowledge.py; a former name is refused naming the models."""
    if text in KNOWLEDGE_MODELS:
        return text
    if text in RENAMED_KNOWLEDGE:
        from sat_node.knowledge import check_model  # here: the flight software's one message for it

        try:
            check_model(text)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None
    raise argparse.ArgumentTypeError(f"{text!r}: unknown knowledge model (models: {', '.join(KNOWLEDGE_MODELS)})")


def max_partners_arg(text: str) -> int:
    """``--joint-max-partners``: an integer >= 0 (0: unbounded, the study's joint planning)."""
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected a whole number of partners (0: unbounded)") from None
    if not 0 <= v <= MAX_SATS:
        raise argparse.ArgumentTypeError(f"{text!r}: must be 0..{MAX_SATS} (0: unbounded)")
    return v


def add_scenario_args(p: argparse.ArgumentParser, *, overrides: bool = True, knowledge: bool = False,
                      sets: bool = True) -> None:
    p.add_argument("--scenario", default="paper", help="scenario name or TOML path (default: paper)")
    if sets:
        add_set_arg(p)
    p.add_argument("--tle", action="append", default=None, metavar="FILE",
                   help="fly the satellites of this TLE / 3LE file instead of the scenario's constellation "
                        "(repeatable; named sat_n<NORAD>; the epoch is the elements')")
    p.add_argument("--omm", action="append", default=None, metavar="FILE",
                   help="fly the satellites of this CCSDS OMM file (XML, KVN or JSON; repeatable), as --tle")
    if overrides:
        p.add_argument("--sats", type=int, default=None,
                       help=f"number of satellites, 1..{MAX_SATS}; named sat_PS up to 9 planes x 9, "
                            f"sat_PPPP_SSSS beyond (default: scenario)")
        p.add_argument("--planes", type=int, default=None,
                       help=f"orbital planes, 1..{MAX_PLANES}, dividing the satellites evenly (default: the "
                            f"scenario's, or the largest below it that divides --sats)")
        p.add_argument("--hours", type=float, default=None, help="horizon [h] (default: scenario)")
        p.add_argument("--seed", type=int, default=None, help="seed (default: scenario)")
        add_regions_arg(p)
        add_epoch_arg(p, "epoch_utc")
    if knowledge:
        add_knowledge_args(p)


def add_regions_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument("--regions", default=None, metavar="FILE.geojson|W,S,E,N",
                   help="regions instead of the scenario's: the Polygon / MultiPolygon features of a GeoJSON file "
                        "(named by their 'name' property), or one bounding box in degrees (write --regions=W,S,E,N "
                        "when W is negative) (docs/guide/regions-and-fields.md)")


def add_set_arg(p: argparse.ArgumentParser) -> None:
    """``--set KEY=VALUE`` (repeatable): any scenario key, validated like the file
    (bringup/scenario/overrides.py); applied after the named options, in the order given."""
    p.add_argument("--set", dest="set", action="append", default=[], metavar="KEY=VALUE",
                   help="set any scenario key, as a TOML value: e.g. --set isl.rate_bps=250 --set "
                        "value.knowledge=observed (repeatable; validated like the scenario file)")


def epoch_arg(text: str) -> str:
    """``--epoch``: ``now`` (this second, UTC) or a UTC instant ``YYYY-MM-DDTHH:MM:SS[.fff]Z``; returned
    in the scenario's ``epoch_utc`` form."""
    t = text.strip()
    if t.lower() == "now":
        return datetime.now(UTC).replace(microsecond=0).strftime("%Y-%m-%dT%H:%M:%SZ")
    if not t.endswith("Z"):
        raise argparse.ArgumentTypeError(f"{text!r}: expected 'now' or a UTC instant like 2026-11-27T12:00:00Z")
    try:
        d = datetime.fromisoformat(t[:-1])
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected 'now' or a UTC instant like 2026-11-27T12:00:00Z") \
            from None
    if d.tzinfo is not None:
        raise argparse.ArgumentTypeError(f"{text!r}: give the instant in UTC with a trailing Z, no offset")
    if d.year < 2000:
        raise argparse.ArgumentTypeError(f"{text!r}: before the DTN epoch 2000-01-01T00:00:00Z (RFC 9171 4.2.6)")
    return t


def add_epoch_arg(p: argparse.ArgumentParser, dest: str) -> None:
    p.add_argument("--epoch", dest=dest, type=epoch_arg, default=None, metavar="now|UTC",
                   help="the scenario's start instant: 'now' or e.g. 2026-11-27T12:00:00Z; bundle creation times are "
                        "DTN time of this clock (default: the scenario's, the study's 2000-01-01T11:59:28Z)")


def add_knowledge_args(p: argparse.ArgumentParser) -> None:
    """What the planners know and of which field (scenario keys value.knowledge, value.transiency_min,
    regions.gp_spacing_km, scheduler.joint_planning, scheduler.joint_max_partners), and how the news
    travels (isl.forwarding)."""
    p.add_argument("--knowledge", type=knowledge_arg, default=None, metavar="|".join(KNOWLEDGE_MODELS),
                   help="what a planner knows: observed (the a-priori forecast updated by what reached it; "
                        "the paper scenario's), region-truth (the OSSE truth delayed to the region's "
                        "information time: an upper bound on what a perfect onboard hydrologic model could "
                        "infer), oracle (the truth at planning time; comparison only) (default: scenario)")
    p.add_argument("--transiency-min", type=transiency_arg, default=None, metavar="MIN|slow",
                   help="decorrelation of the synthetic field [min]: the lag at which the GP values' rank "
                        "correlation falls to 0.5 (not the study's 'transiency', which is the OSSE's time "
                        "resolution, value.osse_resolution_min), or 'slow' for the storm-cell field "
                        "(default: scenario)")
    p.add_argument("--gp-spacing-km", type=float, default=None,
                   help="GP spacing [km] (default: scenario; the paper's: footprint / 2)")
    p.add_argument("--planning", choices=("joint", "alone"), default=None,
                   help="plan satellites with overlapping fields of regard jointly (the study's) or each alone "
                        "(default: scenario)")
    p.add_argument("--joint-max-partners", type=max_partners_arg, default=None, metavar="K",
                   help="joint planning with at most K partners: those that may first see one of the planned "
                        "satellite's GPs earliest, ties by name; 0 = every overlapping satellite, the study's "
                        "(scenario key scheduler.joint_max_partners; default: scenario)")
    p.add_argument("--forwarding", choices=("multicast", "unicast"), default=None,
                   help="DTN forwarding (scenario key isl.forwarding): one bundle per observation to its recipient "
                        "list (multicast) or one per recipient (unicast, the study simulator's) (default: scenario)")


def overrides_of(args: argparse.Namespace) -> dict:
    """The scenario overrides given on the command line, as ``Scenario.with_overrides`` keywords
    (None: not given), and ``tle`` / ``omm``: the element files of ``--tle`` / ``--omm`` (absolute
    paths, ``Scenario.with_catalogue``)."""
    kw = {k: getattr(args, k, None) for k in _OVERRIDES if k != "joint_planning"}
    planning = getattr(args, "planning", None)
    kw["joint_planning"] = None if planning is None else planning == "joint"
    regions = getattr(args, "regions", None)
    kw["regions"] = None if regions is None else regions_arg(regions)
    for k in ("tle", "omm"):
        files = getattr(args, k, None)
        kw[k] = [str(Path(f).expanduser().resolve()) for f in files] if files else None
    return kw


def scenario_from_args(args: argparse.Namespace) -> Scenario:
    """The scenario with the command line's overrides, refused when it would not fit in memory
    (bringup/scenario/limits.py: the estimate is named)."""
    kw = overrides_of(args)
    sc = load_scenario(args.scenario).with_catalogue(kw.pop("tle") or (), kw.pop("omm") or ())
    if kw["gp_spacing_km"] is not None and not kw["gp_spacing_km"] > 0:
        raise UserError(f"--gp-spacing-km {kw['gp_spacing_km']}: must be > 0")
    if any(v is not None for v in kw.values()):
        sc = sc.with_overrides(**kw)
    sets = getattr(args, "set", None) or []
    check_conflicts(sets, explicit_options(args))
    sc = apply_sets(sc, sets)
    check_run_size(sc)
    return sc


def explicit_options(args: argparse.Namespace) -> list[str]:
    """The named scenario options given on the command line (argparse dests of OPTION_KEYS)."""
    return [k for k in OPTION_KEYS if getattr(args, k, None) is not None]


def add_key_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--bpsec-key-file", type=Path, default=None, metavar="FILE",
                   help="the constellation's BPSec (BIB) key, hex on one line, mode 600 (default: "
                        f"${ENV_BPSEC_KEY_FILE}, else ${ENV_BPSEC_KEY} in hex, else a key generated for the run)")


def keys_from_args(args: argparse.Namespace) -> RunKeys:
    """The run's keys: a new run key and the BPSec key from ``--bpsec-key-file`` or the environment
    (bringup/engine/keys.py)."""
    return RunKeys.generate(getattr(args, "bpsec_key_file", None))


def add_out_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", type=Path, default=None, help="write to FILE instead of stdout")


@contextmanager
def output_stream(path: Path | None):
    """stdout, or a file opened for writing (its folder created)."""
    if path is None:
        yield sys.stdout
        return
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", encoding="utf-8", newline="") as fh:
        yield fh
