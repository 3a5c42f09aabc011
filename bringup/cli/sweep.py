"""`constellation sweep`: the study's figures over a grid of any scenario keys, several seeds, either engine.

``--grid "isl.rate_bps=250,1000,8000 scheduler.replan_period_s=300,600" --seeds K [--mode M ...]
[--engine local|ros]`` runs every cell of the cartesian product of the axes (bringup/analysis/grid.py)
for each mode and each of K seeds (the scenario seed and the K - 1 after it). Every finished run is
stored under ``OUT/runs/`` (bringup/analysis/grid_runs.py), so a sweep that was stopped and is started
again runs only what is missing. ``OUT`` (``--out``, default ``runs/sweep-<scenario>``) gets
``sweep.csv`` (tidy, one row per cell x seed x metric), ``sweep.json`` (per cell: mean, sample sd,
Student-t 95 % CI and n of every metric, bringup/analysis/stats.py; the per-seed values; the
provenance), ``sweep.md`` and ``plots/<metric>.png`` (mean and 95 % band; bringup/analysis/grid_figures.py).

The four named sweeps of the study's design parameters are presets of the same machinery, one
axis each, with their own modes: replan period [s] (``--replan-s``; distributed; the plan lookahead
follows the period), ISL rate [bit/s] (``--isl-rate-bps``; distributed), satellites per plane
(``--sats-per-plane``; distributed and non-agile), ground-station count (``--stations``; the first N
of the scenario's; centralized); ``--only`` picks some. They honour ``--seeds``, ``--engine`` and
``--set``; the table marks the scenario's own value with ``*``. The scenario is reduced (``--sats``
12, ``--hours`` 2 unless given) so a sweep runs in minutes.

``--transiency 15,30,60,120 --seeds K`` sweeps the field's transiency instead (does reacting onboard
beat the ground when the field changes fast?): for each transiency and seed a distributed and a
centralized run, their value ratio per seed, and per transiency the mean with its 95 % confidence
interval (bringup/analysis/compare.py mean_ci95); ``--out`` also writes ``transiency.png``. It runs
the local engine in this process.

An option that does not apply to the chosen sweep is refused in one line, never ignored.

Checked by tests/unit/test_compare.py (the preset rows and the baseline mark, bad lists named; the
transiency sweep's rows, intervals and plot), tests/unit/test_grid.py (the presets equal the
variants they always made, refused options) and tests/system/test_sweep_grid.py (a real grid:
CSV against JSON, a killed sweep resumed).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import msgspec

from bringup.analysis.compare import get_path, mean_ci95, run_in_process, scenario_variant
from bringup.analysis.grid import METRICS, Cell, cells_of, csv_text, parse_grid, summary
from bringup.analysis.grid_runs import plan_runs, run_all
from bringup.analysis.stats import summarize
from bringup.cli.common import add_knowledge_args, add_set_arg, explicit_options, scenario_from_args
from bringup.cli.run_folder import RunFolder, json_text, write_text_atomic
from bringup.errors import UserError
from bringup.scenario.overrides import check_conflicts
from bringup.scenario.provenance import provenance

PARAMS = ("replan_period_s", "isl_rate_bps", "sats_per_plane", "n_stations")
# the presets' options (argparse dest) and their values when not given
PRESET_DEFAULTS = {"replan_s": "300,600,1200", "isl_rate_bps": "250,1000,4000", "sats_per_plane": "2,4,8",
                   "stations": "1,2"}
SATS, HOURS = 12, 2.0  # the reduced scenario a sweep runs unless --sats / --hours say otherwise
MODES = ("distributed", "centralized", "nonagile")


def _floats(text: str, what: str) -> list[float]:
    try:
        v = [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise UserError(f"--{what} {text!r}: expected comma-separated numbers") from None
    if not v or any(x <= 0 and what != "stations" for x in v):
        raise UserError(f"--{what} {text!r}: expected positive numbers")
    return v


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scenario", default="paper", help="scenario name or TOML path (default: paper)")
    add_set_arg(p)
    p.add_argument("--grid", action="append", default=[], metavar='"KEY=V1,V2 KEY2=V1,V2"',
                   help="sweep any scenario keys: the cartesian product of the axes (values are TOML literals; "
                        "repeatable)")
    p.add_argument("--mode", action="append", choices=MODES, default=None,
                   help="with --grid: the mode(s) each cell runs (repeatable; default distributed)")
    p.add_argument("--engine", choices=("local", "ros"), default="local",
                   help="local: each run in this process; ros: `constellation run --engine ros` per run "
                        "(default local)")
    p.add_argument("--metric", action="append", default=[], metavar="KEY",
                   help=f"one more report.json figure to summarise (dotted key; default: {', '.join(METRICS)})")
    p.add_argument("--sats", type=int, default=None, help=f"satellites of the baseline (default {SATS})")
    p.add_argument("--hours", type=float, default=None, help=f"horizon [h] (default {HOURS:g})")
    p.add_argument("--seed", type=int, default=None, help="first seed (default: scenario)")
    p.add_argument("--replan-s", default=None,
                   help=f"preset: replan periods [s] (distributed; default {PRESET_DEFAULTS['replan_s']})")
    p.add_argument("--isl-rate-bps", default=None,
                   help=f"preset: ISL rates [bit/s] (distributed; default {PRESET_DEFAULTS['isl_rate_bps']})")
    p.add_argument("--sats-per-plane", default=None,
                   help=f"preset: satellites per plane (distributed, non-agile; default {PRESET_DEFAULTS['sats_per_plane']})")
    p.add_argument("--stations", default=None,
                   help=f"preset: ground-station counts (centralized; default {PRESET_DEFAULTS['stations']})")
    p.add_argument("--only", choices=PARAMS, action="append", default=None, help="sweep only this preset")
    p.add_argument("--transiency", default=None, metavar="MIN,MIN,...",
                   help="sweep the field's transiency [min] instead (e.g. 15,30,60,120): distributed / "
                        "centralized value ratio per seed, mean and 95 %% CI")
    p.add_argument("--seeds", type=int, default=1, help="seeds per cell: the scenario seed, +1, ... (default 1)")
    p.add_argument("--json", action="store_true", help="print the result as one JSON object")
    p.add_argument("--out", type=Path, default=None,
                   help="folder for sweep.json, sweep.csv, sweep.md, plots/ and the stored runs "
                        "(default runs/sweep-<scenario>; the transiency sweep writes only when given)")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    add_knowledge_args(p)


def _preset_given(args) -> list[str]:
    return [f"--{d.replace('_', '-')}" for d in PRESET_DEFAULTS if getattr(args, d, None) is not None] + (
        ["--only"] if args.only else [])


def _check_options(args) -> None:
    """Refuse, in one line, an option the chosen sweep would not use."""
    if args.seeds < 1:
        raise UserError(f"--seeds {args.seeds}: must be >= 1")
    presets = _preset_given(args)
    if args.transiency is not None:
        extra = presets + (["--grid"] if args.grid else []) + (["--mode"] if args.mode else []) + (
            ["--metric"] if args.metric else []) + (["--engine ros"] if args.engine == "ros" else [])
        if extra:
            raise UserError(f"--transiency: {', '.join(extra)} do not apply to the transiency sweep (distributed "
                            "and centralized, local engine, in this process)")
        return
    if args.grid and presets:
        raise UserError(f"--grid with {', '.join(presets)}: the named sweeps are presets; put the key in the grid "
                        "instead (e.g. scheduler.replan_period_s=300,600)")
    if args.mode and not args.grid:
        raise UserError("--mode goes with --grid (each named sweep runs its own modes)")


def _base_scenario(args):
    """The scenario with --set and the named options; the sweep's reduced size unless given (or set)."""
    set_keys = {s.partition("=")[0].strip() for s in args.set}
    ns = argparse.Namespace(**vars(args))
    if ns.sats is None and not set_keys & {"constellation.total_sats", "constellation.planes"}:
        ns.sats = SATS
    if ns.hours is None and "scenario.horizon_s" not in set_keys:
        ns.hours = HOURS
    return scenario_from_args(ns)


def _rows_plan(sc, args) -> list[tuple[str, float, str, dict, bool]]:
    """The named sweeps' rows: (parameter, value, mode, compare.scenario_variant keywords, is the
    scenario's own value)."""
    s, i, c = sc.scheduler, sc.isl, sc.walker

    def opt(dest: str) -> str:
        v = getattr(args, dest, None)
        return PRESET_DEFAULTS[dest] if v is None else v

    only = set(args.only or PARAMS)
    plan = []
    if "replan_period_s" in only:
        plan += [("replan_period_s", v, "distributed", {"replan_period_s": v}) for v in _floats(opt("replan_s"), "replan-s")]
    if "isl_rate_bps" in only:
        plan += [("isl_rate_bps", v, "distributed", {"isl_rate_bps": v})
                 for v in _floats(opt("isl_rate_bps"), "isl-rate-bps")]
    if "sats_per_plane" in only:
        for v in _floats(opt("sats_per_plane"), "sats-per-plane"):
            for m in ("distributed", "nonagile"):
                plan.append(("sats_per_plane", int(v), m, {"sats_per_plane": int(v)}))
    if "n_stations" in only:
        plan += [("n_stations", int(v), "centralized", {"n_stations": int(v)}) for v in _floats(opt("stations"), "stations")]
    base = {"replan_period_s": s.replan_period_s, "isl_rate_bps": i.rate_bps, "sats_per_plane": c.sats_per_plane if c else None,
            "n_stations": len(sc.ground.stations)}
    return [(p, v, m, ch, base[p] == v) for p, v, m, ch in plan]


def preset_sets(sc, param: str, v) -> tuple:
    """The scenario overrides of one value of a named sweep (what compare.scenario_variant makes)."""
    if param == "replan_period_s":
        # a plan must cover the time to the next replan, else the satellite idles in between:
        # the lookahead follows the period (the study's 10 min / 10 min)
        return (("scheduler.replan_period_s", float(v)), ("scheduler.plan_lookahead_s", float(v)))
    if param == "isl_rate_bps":
        return (("isl.rate_bps", float(v)),)
    if param == "sats_per_plane":
        if sc.walker is None:
            raise UserError("the satellites-per-plane sweep needs a Walker shell (the scenario flies catalogue "
                            "satellites only)")
        return (("constellation.total_sats", int(v) * sc.walker.planes),)
    if param == "n_stations":
        st = msgspec.to_builtins(sc.ground.stations)
        if not 0 <= v <= len(st):
            raise UserError(f"ground-station count {v}: the scenario has {len(st)} stations")
        return (("ground.stations", st[:int(v)]),)
    raise UserError(f"no preset sweep {param!r} (presets: {', '.join(PARAMS)})")


def run(args: argparse.Namespace) -> int:
    _check_options(args)
    explicit = explicit_options(args)
    sc = _base_scenario(args)
    if args.transiency is not None:
        return _run_transiency(sc, args)
    plan = None
    if args.grid:
        axes = parse_grid(args.grid)
        for a in axes:  # a grid key an explicit option also sets: one of them would be ignored
            check_conflicts([(a.name, None)], explicit)
        cells = cells_of(axes, list(dict.fromkeys(args.mode or ["distributed"])))
        axis_names = [a.name for a in axes]
    else:
        plan = _rows_plan(sc, args)
        cells = [Cell(id=f"c{k}", mode=m, params={p: v}, sets=preset_sets(sc, p, v))
                 for k, (p, v, m, _, _) in enumerate(plan, 1)]
        axis_names = [p for p in PARAMS if any(r[0] == p for r in plan)]
    seeds = [sc.scenario.seed + k for k in range(args.seeds)]
    metrics = list(dict.fromkeys([*METRICS, *args.metric]))
    out = (args.out or Path("runs") / f"sweep-{sc.name}").absolute()
    runs = plan_runs(sc, cells, seeds, out, args.engine)  # every cell validated before anything runs

    def say(*a) -> None:
        print(*a, file=sys.stderr)

    with RunFolder(out, outputs=("sweep.json", "sweep.md", "sweep.csv", "plots")) as folder:
        say(f"sweep: {sc.name}, {sc.n_sats} satellites, {sc.scenario.horizon_s / 3600:g} h, "
            f"{len(cells)} cells x {len(seeds)} seeds {seeds}, engine {args.engine} -> {folder.path}")
        reports = run_all(runs, write_text_atomic, json_text, say=say)
        res = {"scenario": sc.name, "sats": sc.n_sats, "hours": sc.scenario.horizon_s / 3600,
               "seed": sc.scenario.seed, "engine": args.engine, "modes": list(dict.fromkeys(c.mode for c in cells)),
               "axes": axis_names, "csv": "sweep.csv",
               **summary(cells, reports, seeds, metrics)}
        if plan is not None:
            n_sats = {r.cell.id: r.scenario.n_sats for r in runs}
            res["rows"] = _preset_rows(plan, cells, res["cells"], n_sats)
            md = table_markdown(res)
        else:
            md = grid_markdown(res)
        res["provenance"] = provenance(sc, getattr(args, "_argv", None))
        commits = sorted({get_path(r, "provenance.git_commit") or "?" for r in reports.values()})
        res["provenance"]["runs_git_commits"] = commits  # (a resumed sweep may mix runs of two commits)
        write_text_atomic(folder.path / "sweep.csv", csv_text(cells, reports, seeds, metrics, axis_names))
        plots = []
        if not args.no_plots:
            # here, not at the top: matplotlib costs ~0.27 s to import, paid only when plots are made
            from bringup.analysis.grid_figures import plot_sweep

            plots = plot_sweep(folder.path / "plots", res, axis_names,
                               title=f"{sc.name}: {sc.n_sats} satellites, "
                                     f"{sc.scenario.horizon_s / 3600:g} h, {len(seeds)} seeds, {args.engine} engine")
        md += "".join(f"\n\n![{p.stem}](plots/{p.name})" for p in plots)
        write_text_atomic(folder.path / "sweep.md", md + "\n")
        write_text_atomic(folder.path / "sweep.json", json_text(res, indent=2) + "\n")
        folder.done()
    print(json.dumps(res) if args.json else md)
    return 0


_ROW_METRICS = {"value_cumulative": "value.cumulative", "gp_observed_fraction": "coverage.gp_observed_fraction",
                "observations": "observations.count", "duplicates_15min": "observations.duplicates_15min",
                "assumed_error_mean": "value.assumed_error_mean", "delivery_ratio": "dtn.delivery_ratio"}


def _preset_rows(plan, cells: list[Cell], summaries: list[dict], n_sats: dict) -> list[dict]:
    """The named sweeps' table rows: the means over the seeds, their 95 % CI of the value."""
    rows = []
    for (param, v, mode, _, is_base), cell, s in zip(plan, cells, summaries):
        row = {"parameter": param, "value": v, "baseline": is_base, "mode": mode, "cell": cell.id,
               "n_sats": n_sats[cell.id], "n_seeds": len(s["seeds"])}
        row.update({k: s["mean"].get(m) for k, m in _ROW_METRICS.items()})
        row["value_cumulative_ci95"] = s["ci95"].get("value.cumulative")
        rows.append(row)
    return rows


def grid_markdown(res: dict) -> str:
    """One row per cell: its parameters, then each metric's mean and 95 % CI over the seeds."""
    def f(x):
        return "-" if x is None else f"{x:.4g}"

    head = ["cell", "mode", *res["axes"], "n"] + [m for m in res["metrics"]]
    lines = [(f"Sweep on {res['scenario']} ({res['sats']} sats, {res['hours']:g} h, seeds {res['seeds']}, "
              f"{res['engine']} engine): mean over the seeds [95 % CI, Student's t]"), "",
             "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for c in res["cells"]:
        cells = [c["cell"], c["mode"], *(str(c["params"].get(a, "")) for a in res["axes"]), str(len(c["seeds"]))]
        for m in res["metrics"]:
            ci = c["ci95"].get(m)
            cells.append(f(c["mean"].get(m)) + (f" [{f(ci[0])}, {f(ci[1])}]" if ci else ""))
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def table_markdown(res: dict) -> str:
    def f(x, fmt):
        return "-" if x is None else fmt.format(x)

    seeds = f"seeds {res['seeds']}, mean over them" if len(res.get("seeds") or []) > 1 else f"seed {res['seed']}"
    title = (f"Sweep on {res['scenario']} ({res['sats']} sats baseline, {res['hours']:g} h, {seeds}); "
             "* = the scenario's own value")
    head = ("| parameter | value | mode | sats | cumulative value | GPs observed | observations | duplicates | "
            "assumed error | DTN delivery |")
    lines = [title, "", head, "|---|---|---|---|---|---|---|---|---|---|"]
    for r in res["rows"]:
        lines.append(f"| {r['parameter']} | {r['value']:g}{' *' if r['baseline'] else ''} | {r['mode']} | {r['n_sats']} | "
                     f"{f(r['value_cumulative'], '{:.0f}')} | {f(r['gp_observed_fraction'], '{:.1%}')} | "
                     f"{f(r['observations'], '{:g}')} | {f(r['duplicates_15min'], '{:g}')} | {f(r['assumed_error_mean'], '{:.1%}')} | "
                     f"{f(r['delivery_ratio'], '{:.1%}')} |")
    return "\n".join(lines)


def transiency_rows(sc, minutes: list[float], seeds: list[int], run=run_in_process, say=lambda *a: None) -> list[dict]:
    """One row per transiency: per seed the distributed and centralized values and their ratio, the
    ratio's mean and 95 % interval, the measured transiency (mean over seeds)."""
    variants = {(m, s): scenario_variant(sc, transiency_min=m, seed=s) for m in minutes for s in seeds}
    rows = []
    for m in minutes:
        per = []
        for s in seeds:
            t0 = time.perf_counter()
            d = run(variants[(m, s)], "distributed")
            c = run(variants[(m, s)], "centralized")
            vd, vc = get_path(d, "value.cumulative"), get_path(c, "value.cumulative")
            per.append({"seed": s, "distributed": vd, "centralized": vc, "ratio": (vd / vc) if vc else None,
                        "measured_min": get_path(d, "osse.transiency_min"),
                        "rank_corr_15min": get_path(d, "osse.rank_corr_15min"),
                        "info_age_median_s": {"distributed": get_path(d, "knowledge.info_age_s.median"),
                                              "centralized": get_path(c, "knowledge.info_age_s.median")}})
            say(f"sweep: transiency {m:g} min seed {s}: distributed {vd:.0f}, centralized {vc:.0f} "
                f"({time.perf_counter() - t0:.0f} s)")
        ci = mean_ci95([p["ratio"] for p in per])
        st = summarize([p["ratio"] for p in per])
        meas = [p["measured_min"] for p in per if p["measured_min"] is not None]
        rows.append({"transiency_min": m, "measured_min": sum(meas) / len(meas) if meas else None,
                     "mean": ci["mean"], "ci95": ci["ci95"], "sd": st["sd"], "ci95_interval": st["ci95"],
                     "values": ci["values"], "seeds": per,
                     "distributed_mean": mean_ci95([p["distributed"] for p in per])["mean"],
                     "centralized_mean": mean_ci95([p["centralized"] for p in per])["mean"]})
    return rows


def transiency_markdown(res: dict) -> str:
    def f(x, fmt):
        return "-" if x is None else fmt.format(x)

    lines = [(f"Transiency sweep on {res['scenario']} ({res['sats']} sats, {res['hours']:g} h, seeds {res['seeds']}, "
              f"knowledge {res['knowledge']}); ratio = distributed / centralized cumulative value, per seed"), "",
             "| transiency [min] | measured [min] | distributed | centralized | ratio mean | 95 % CI | per seed |",
             "|---|---|---|---|---|---|---|"]
    for r in res["rows"]:
        lines.append(f"| {r['transiency_min']:g} | {f(r['measured_min'], '{:.1f}')} | {f(r['distributed_mean'], '{:.0f}')} | "
                     f"{f(r['centralized_mean'], '{:.0f}')} | {f(r['mean'], '{:.3f}')} | "
                     f"{'±' + f(r['ci95'], '{:.3f}') if r['ci95'] is not None else '-'} | "
                     f"{', '.join(f'{v:.3f}' for v in r['values'])} |")
    return "\n".join(lines)


def _run_transiency(sc, args) -> int:
    minutes = _floats(args.transiency, "transiency")
    if args.seeds < 1:
        raise UserError(f"--seeds {args.seeds}: must be >= 1")
    seeds = [sc.scenario.seed + k for k in range(args.seeds)]
    rows = transiency_rows(sc, minutes, seeds, say=lambda *a: print(*a, file=sys.stderr))
    res = {"scenario": sc.name, "sats": sc.n_sats, "hours": sc.scenario.horizon_s / 3600,
           "seeds": seeds, "knowledge": sc.value.knowledge, "rows": rows,
           "statistics": {"mean": "mean of the per-seed ratios",
                          "sd": "sample standard deviation of the per-seed ratios (n - 1); null for one seed",
                          "ci95": "half-width of the 95 % confidence interval of the mean (Student's t, n - 1)",
                          "ci95_interval": "that interval, [low, high]"},
           "provenance": provenance(sc, getattr(args, "_argv", None))}
    md = transiency_markdown(res)
    if args.out:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "sweep.json").write_text(json.dumps(res, indent=2) + "\n")
        (args.out / "sweep.md").write_text(md + "\n")
    if args.out and not args.no_plots:
        # here, not at the top: matplotlib costs ~0.27 s to import, paid only when the plot is made
        from bringup.analysis.figures import plot_transiency_sweep

        plot_transiency_sweep(args.out / "transiency.png", rows,
                              title=f"{sc.name}: {sc.n_sats} satellites, "
                                    f"{sc.scenario.horizon_s / 3600:g} h, {len(seeds)} seeds, {sc.value.knowledge} knowledge")
    print(json.dumps(res) if args.json else md)
    return 0
