"""`constellation sweep`: sensitivity of the cumulative value to the study's design parameters.

One table, one row per (parameter, value): replan period [s] and ISL rate [bit/s] (distributed
mode), satellites per plane (distributed and non-agile), ground-station count (centralized mode).
Each row is one local-engine run in this process on a scenario variant
(bringup/analysis/compare.py scenario_variant / run_in_process); the default scenario is reduced (--sats,
--hours) so the whole sweep runs in minutes. The scenario's own value of each parameter is marked
with ``*`` (the baseline row).

``--transiency 15,30,60,120 --seeds K`` sweeps the field's transiency instead (the question the
study asks: does reacting onboard beat the ground when the field changes fast?): for each
transiency and seed a distributed and a centralized run, their value ratio per seed, and per
transiency the mean with its 95 % confidence interval (Student's t over the seeds,
bringup/analysis/compare.py mean_ci95); ``--out`` also writes ``transiency.png``.

Checked by tests/unit/test_compare.py (the rows and the baseline mark, bad lists named; the
transiency sweep's rows, intervals and plot on a reduced run).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from bringup.analysis.compare import get_path, mean_ci95, run_in_process, scenario_variant
from bringup.cli.common import add_knowledge_args, scenario_from_args
from bringup.cli.run_folder import RunFolder, json_text, write_text_atomic
from bringup.errors import UserError

PARAMS = ("replan_period_s", "isl_rate_bps", "sats_per_plane", "n_stations")


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
    p.add_argument("--sats", type=int, default=12, help="satellites of the baseline (default 12)")
    p.add_argument("--hours", type=float, default=2.0, help="horizon [h] (default 2)")
    p.add_argument("--seed", type=int, default=None, help="seed (default: scenario)")
    p.add_argument("--replan-s", default="300,600,1200", help="replan periods [s] (distributed)")
    p.add_argument("--isl-rate-bps", default="250,1000,4000", help="ISL rates [bit/s] (distributed)")
    p.add_argument("--sats-per-plane", default="2,4,8", help="satellites per plane (distributed, non-agile)")
    p.add_argument("--stations", default="1,2", help="ground-station counts (centralized)")
    p.add_argument("--only", choices=PARAMS, action="append", default=None, help="sweep only this parameter")
    p.add_argument("--transiency", default=None, metavar="MIN,MIN,...",
                   help="sweep the field's transiency [min] instead (e.g. 15,30,60,120): distributed / "
                        "centralized value ratio per seed, mean and 95 %% CI")
    p.add_argument("--seeds", type=int, default=1, help="seeds per transiency: the scenario seed, +1, ... (default 1)")
    p.add_argument("--json", action="store_true", help="print the rows as one JSON object")
    p.add_argument("--out", type=Path, default=None, help="also write sweep.json and sweep.md here")
    add_knowledge_args(p)


def _rows_plan(sc, args) -> list[tuple[str, float, str, dict]]:
    s, i, c = sc.scheduler, sc.isl, sc.constellation
    only = set(args.only or PARAMS)
    plan = []
    if "replan_period_s" in only:
        plan += [("replan_period_s", v, "distributed", {"replan_period_s": v}) for v in _floats(args.replan_s, "replan-s")]
    if "isl_rate_bps" in only:
        plan += [("isl_rate_bps", v, "distributed", {"isl_rate_bps": v}) for v in _floats(args.isl_rate_bps, "isl-rate-bps")]
    if "sats_per_plane" in only:
        for v in _floats(args.sats_per_plane, "sats-per-plane"):
            for m in ("distributed", "nonagile"):
                plan.append(("sats_per_plane", int(v), m, {"sats_per_plane": int(v)}))
    if "n_stations" in only:
        plan += [("n_stations", int(v), "centralized", {"n_stations": int(v)}) for v in _floats(args.stations, "stations")]
    base = {"replan_period_s": s.replan_period_s, "isl_rate_bps": i.rate_bps, "sats_per_plane": c.sats_per_plane,
            "n_stations": len(sc.ground.stations)}
    return [(p, v, m, ch, base[p] == v) for p, v, m, ch in plan]


def run(args: argparse.Namespace) -> int:
    sc = scenario_from_args(args)
    if args.transiency is not None:
        return _run_transiency(sc, args)
    plan = _rows_plan(sc, args)
    variants = [scenario_variant(sc, **ch) for _, _, _, ch, _ in plan]  # validate all before running
    rows = []
    for (param, v, mode, _, is_base), var in zip(plan, variants):
        t0 = time.perf_counter()
        rep = run_in_process(var, mode)
        row = {"parameter": param, "value": v, "baseline": is_base, "mode": mode,
               "n_sats": var.constellation.total_sats, "value_cumulative": get_path(rep, "value.cumulative"),
               "gp_observed_fraction": get_path(rep, "coverage.gp_observed_fraction"),
               "observations": get_path(rep, "observations.count"),
               "duplicates_15min": get_path(rep, "observations.duplicates_15min"),
               "assumed_error_mean": get_path(rep, "value.assumed_error_mean"),
               "delivery_ratio": get_path(rep, "dtn.delivery_ratio"), "wall_s": time.perf_counter() - t0}
        rows.append(row)
        print(f"sweep: {param}={v:g} {mode}: value {row['value_cumulative']:.0f} ({row['wall_s']:.0f} s)",
              file=sys.stderr)
    res = {"scenario": sc.name, "sats": sc.constellation.total_sats, "hours": sc.scenario.horizon_s / 3600,
           "seed": sc.scenario.seed, "rows": rows}
    md = table_markdown(res)
    if args.out:
        with RunFolder(args.out, outputs=("sweep.json", "sweep.md")) as folder:
            write_text_atomic(folder.path / "sweep.md", md + "\n")
            write_text_atomic(folder.path / "sweep.json", json_text(res, indent=2) + "\n")
            folder.done()
    print(json.dumps(res) if args.json else md)
    return 0


def table_markdown(res: dict) -> str:
    def f(x, fmt):
        return "-" if x is None else fmt.format(x)

    title = (f"Sweep on {res['scenario']} ({res['sats']} sats baseline, {res['hours']:g} h, seed {res['seed']}); "
             "* = the scenario's own value")
    head = ("| parameter | value | mode | sats | cumulative value | GPs observed | observations | duplicates | "
            "assumed error | DTN delivery |")
    lines = [title, "", head, "|---|---|---|---|---|---|---|---|---|---|"]
    for r in res["rows"]:
        lines.append(f"| {r['parameter']} | {r['value']:g}{' *' if r['baseline'] else ''} | {r['mode']} | {r['n_sats']} | "
                     f"{f(r['value_cumulative'], '{:.0f}')} | {f(r['gp_observed_fraction'], '{:.1%}')} | "
                     f"{r['observations']} | {r['duplicates_15min']} | {f(r['assumed_error_mean'], '{:.1%}')} | "
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
        meas = [p["measured_min"] for p in per if p["measured_min"] is not None]
        rows.append({"transiency_min": m, "measured_min": sum(meas) / len(meas) if meas else None,
                     "mean": ci["mean"], "ci95": ci["ci95"], "values": ci["values"], "seeds": per,
                     "distributed_mean": mean_ci95([p["distributed"] for p in per])["mean"],
                     "centralized_mean": mean_ci95([p["centralized"] for p in per])["mean"]})
    return rows


def transiency_markdown(res: dict) -> str:
    def f(x, fmt):
        return "-" if x is None else fmt.format(x)

    lines = [f"Transiency sweep on {res['scenario']} ({res['sats']} sats, {res['hours']:g} h, seeds {res['seeds']}, "
             f"knowledge {res['knowledge']}); ratio = distributed / centralized cumulative value, per seed", "",
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
    res = {"scenario": sc.name, "sats": sc.constellation.total_sats, "hours": sc.scenario.horizon_s / 3600,
           "seeds": seeds, "knowledge": sc.value.knowledge, "rows": rows}
    md = transiency_markdown(res)
    if args.out:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "sweep.json").write_text(json.dumps(res, indent=2) + "\n")
        (args.out / "sweep.md").write_text(md + "\n")
        # here, not at the top: matplotlib costs ~0.27 s to import, paid only when the plot is made
        from bringup.analysis.figures import plot_transiency_sweep

        plot_transiency_sweep(args.out / "transiency.png", rows,
                              title=f"{sc.name}: {sc.constellation.total_sats} satellites, "
                                    f"{sc.scenario.horizon_s / 3600:g} h, {len(seeds)} seeds, {sc.value.knowledge} knowledge")
    print(json.dumps(res) if args.json else md)
    return 0
