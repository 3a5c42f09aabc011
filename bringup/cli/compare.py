"""`constellation compare`: distributed vs centralized vs non-agile on the same scenario and seeds
(the study's Table 2, Nag et al. 2019 section 5); the logic is bringup/analysis/compare.py.

Writes ``OUT/<mode>-s<seed>/`` (each a whole run: bag, report.json, report.md; the first seed's
runs also their plots), ``OUT/compare.json`` (the ``--json`` object), ``OUT/compare.md`` (tables),
``OUT/plots/value_over_time.png`` (the three modes, first seed), ``OUT/plots/figure5.png``
(bundle latency vs access gaps by priority, distributed, first seed; bringup/analysis/figure5.py) and
``OUT/plots/info_age.png`` (the age of the information each look was planned with, distributed and
centralized, first seed). ``--knowledge``, ``--transiency-min``, ``--gp-spacing-km`` and
``--planning`` go to every run.
With K seeds each mode's entry holds the means over the seeds, report-shaped, plus each Table-2
figure's mean, sample standard deviation, Student-t 95 % interval, n and per-seed list under
``"seeds"`` (bringup/analysis/compare.py combine); ``"table2"`` sets the study's Table 2 beside ours
(the coverage ratio against its 11.3x; the value ratio is not in the study).
``compare.json`` also holds ``provenance`` (bringup/scenario/provenance.py; ``--set KEY=VALUE`` goes
to every run).

Checked by tests/system/test_compare_modes.py (a reduced real compare) and
tests/unit/test_compare.py.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from bringup.analysis import compare as C
from bringup.analysis.figure5 import bundle_rows_from_bag, figure5_data, figure5_summary, plot_figure5
from bringup.analysis.report import true_values
from bringup.cli.common import add_knowledge_args, add_regions_arg, add_set_arg, scenario_from_args
from bringup.cli.run_folder import RunFolder, json_text, write_text_atomic
from bringup.errors import UserError
from bringup.recording.bag import BagReader
from bringup.scenario.provenance import provenance
from bringup.scenario.world import World
from msgs_json import codec


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scenario", default="paper", help="scenario name or TOML path (default: paper)")
    add_set_arg(p)
    p.add_argument("--engine", choices=("local", "ros"), default="local",
                   help="local: every run in one process (fast); ros: every run as real rclpy processes (default: local)")
    p.add_argument("--seeds", type=int, default=1, help="number of seeds K: the scenario seed, +1, ... (default 1)")
    p.add_argument("--sats", type=int, default=None, help="number of satellites (default: scenario)")
    p.add_argument("--hours", type=float, default=None, help="horizon [h] (default: scenario)")
    p.add_argument("--jobs", type=int, default=1, help="runs at once (default 1; each run is one process)")
    p.add_argument("--json", action="store_true", help="print exactly one JSON object on stdout")
    p.add_argument("--out", type=Path, default=None, help="folder (default runs/compare-<scenario>)")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    add_knowledge_args(p)
    add_regions_arg(p)


def run(args: argparse.Namespace) -> int:
    if args.seeds < 1:
        raise UserError(f"--seeds {args.seeds}: must be >= 1")
    if args.jobs < 1:
        raise UserError(f"--jobs {args.jobs}: must be >= 1")
    args.seed = None
    sc = scenario_from_args(args)  # validates scenario and overrides before any run starts
    seeds = [sc.scenario.seed + k for k in range(args.seeds)]
    # (each run's folder <mode>-s<seed> is a run folder of its own: its run clears it, keeping its cache)
    with RunFolder(args.out or Path("runs") / f"compare-{sc.name}",
                   outputs=("compare.json", "compare.md", "plots")) as folder:
        _compare(args, sc, seeds, folder.path)
        folder.done()
    return 0


def _compare(args, sc, seeds: list[int], out: Path) -> None:
    def say(*a) -> None:
        print(*a, file=sys.stderr)

    say(f"compare: {sc.name}, {sc.n_sats} satellites, {sc.scenario.horizon_s / 3600:g} h, "
        f"seeds {seeds}, engine {args.engine} -> {out}")
    extra = []
    if args.knowledge is not None:
        extra += ["--knowledge", args.knowledge]
    if args.transiency_min is not None:
        extra += ["--transiency-min", repr(args.transiency_min)]
    if args.gp_spacing_km is not None:
        extra += ["--gp-spacing-km", repr(args.gp_spacing_km)]
    if args.planning is not None:
        extra += ["--planning", args.planning]
    if getattr(args, "joint_max_partners", None) is not None:
        extra += ["--joint-max-partners", str(args.joint_max_partners)]
    if getattr(args, "forwarding", None) is not None:
        extra += ["--forwarding", args.forwarding]
    if getattr(args, "regions", None) is not None:
        box = args.regions.split(",")
        extra += [f"--regions={args.regions if len(box) == 4 else Path(args.regions).resolve()}"]
    for item in args.set:  # (each run applies them after its named options, as here; its seed is
        # given by --seed, the first of them from a --set scenario.seed)
        if item.partition("=")[0].strip() != "scenario.seed":
            extra += ["--set", item]
    say(f"compare: knowledge {sc.value.knowledge}, transiency {sc.value.transiency_min:g} min "
        f"(0: slow), {sc.gp_spacing_km:g} km GPs, planning {_planning(sc)}")
    by_mode = C.run_matrix(scenario=args.scenario, seeds=seeds, out=out, engine=args.engine, sats=args.sats,
                           hours=args.hours, jobs=args.jobs, say=say, extra=extra)
    res = C.compare_result(by_mode, seeds)
    # what the comparison was made from (each run's own report.json holds its run's)
    res["provenance"] = provenance(sc, getattr(args, "_argv", None))
    extra_plots = []
    if not args.no_plots:
        extra_plots = _plots(out, seeds[0], res, sc, args)
    write_text_atomic(out / "compare.json", json_text(res, indent=2, sort_keys=True) + "\n")
    title = (f"# Compare: {sc.name}, {sc.n_sats} satellites, {sc.scenario.horizon_s / 3600:g} h, "
             f"seeds {seeds}, engine {args.engine}, knowledge {sc.value.knowledge}, transiency "
             f"{sc.value.transiency_min:g} min (0: slow)")
    md = [title, "",
          C.table_markdown(res), "", C.ratios_markdown(res), "", C.table2_markdown(res), ""]
    md += [f"![{p.stem}](plots/{p.name})" for p in extra_plots]
    write_text_atomic(out / "compare.md", "\n".join(md) + "\n")
    if args.json:
        print(json.dumps(res, sort_keys=True))
    else:
        print(C.table_markdown(res))
        print()
        print(C.ratios_markdown(res))
        print()
        print(C.table2_markdown(res))
        print(f"\n-> {out / 'compare.json'}, {out / 'compare.md'}")


def _plots(out: Path, seed: int, res: dict, sc, args) -> list[Path]:
    """Value over time per mode and Figure 5 (first seed), from the runs' bags."""
    # here, not at the top: matplotlib costs ~0.27 s to import (python -X importtime), paid only
    # when plots are made (not with --no-plots)
    from bringup.analysis import figures as plots

    d = out / "plots"
    d.mkdir(parents=True, exist_ok=True)
    series = {}
    ages = {}
    for m in ("distributed", "centralized", "nonagile"):
        bag = out / f"{m}-s{seed}" / "bag"
        with BagReader(bag) as b:
            topics = [x.topic for x in b.topics() if x.topic.endswith("/observations")]
            obs = [codec.decode(e.topic, e.data) for e in b.envelopes(topics)] if topics else []
        tv = true_values(obs, sc.value.revisit_zero_s)
        series[m] = ([o.t_ns / 1e9 for o, _, _ in tv], [v for _, v, _ in tv])
        if m != "nonagile":
            ages[m] = [(o.t_ns - o.info_ns) / 1e9 for o in obs if o.info_ns is not None]
    made = [plots.plot_value_over_time(d / "value_over_time.png", series, horizon_s=sc.scenario.horizon_s)]
    if any(ages.values()):
        made.append(plots.plot_info_age(d / "info_age.png", ages,
                                        title=f"Information age, {sc.value.knowledge} knowledge, seed {seed}"))
    run_sc = sc.with_overrides(seed=seed)
    world = World.cached(run_sc, out / f"distributed-s{seed}" / "cache")
    rows = bundle_rows_from_bag(out / f"distributed-s{seed}" / "bag")
    if rows:
        data = figure5_data(rows, world.access, world.ctx.gps.region_index,
                            replan_period_s=run_sc.scheduler.replan_period_s)
        res["distributed"]["figure5"] = figure5_summary(data)
        made.append(plot_figure5(d / "figure5.png", data))
    return made


def _planning(sc) -> str:
    """``joint``, ``joint, at most K partners`` or ``alone`` (scheduler.joint_planning, joint_max_partners)."""
    if not sc.scheduler.joint_planning:
        return "alone"
    k = sc.scheduler.joint_max_partners
    return f"joint, at most {k} partner{'s' if k > 1 else ''}" if k else "joint"
