"""The study's comparison (Nag et al., ICAPS SPARK 2019, section 5, Table 2): distributed onboard
scheduling with DTN vs a centralized ground scheduler vs a non-agile constellation, same scenario,
same seeds.

Each (mode, seed) is one whole run, ``constellation run`` in a subprocess (local or ROS engine), so
what is compared is exactly what a user gets from a run: its ``report.json`` (docs/design.md section 6)
and its bag. The sweep (``constellation sweep``) instead runs the local engine in this process on a
scenario variant and builds the report from the envelopes (bringup/analysis/report.py build_report, the same
function), since it only needs the value figures.

Combining K seeds (``combine``): each mode's entry is report-shaped and holds the *means over the
seeds* (:func:`mean_report`: every number of report.json averaged over the seeds that have it, a
non-number kept where all seeds agree; ``seed`` the list of seeds), plus ``"seeds"``: ``{"seeds",
"n", "figures": {key: {mean, sd, ci95, n, min, max, per_seed}}}`` over the Table-2 keys (TABLE_KEYS,
dotted report.json paths), each summary from bringup/analysis/stats.py (sample standard deviation,
Student-t 95 % interval of the mean; a key missing or null in some seed is summarised over the
others). Ratios (``ratios``) are formed per seed, numerator and denominator from the same seed, then
summarised alike with the per-seed list; a zero or missing denominator gives null for that seed.
``table2`` sets the figures the study's Table 2 reports beside the study's own: its 11.3x is a
*coverage* ratio (agile 95.2 % of GPs / non-agile 8.4 %); the study gives no non-agile value, so the
value ratio is shown as not in the study.

How we know it is right: tests/unit/test_compare.py - hand-made reports with the means, sample
standard deviations, intervals and ratios worked out by hand; tests/system/test_compare_modes.py - a
reduced real compare (12 sats, 1 h, 2 seeds) whose JSON has every docs/design.md report key per
mode, whose top-level figures equal the mean of the run folders' own report.json, whose ratios
equal the reports' own values divided (an independent recomputation), with agile > non-agile in
value.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import msgspec
from scipy.stats import t as student_t

from bringup.analysis.grid import get_path
from bringup.analysis.report import REPORT_TOPIC_SUFFIXES, RunMeta, build_report
from bringup.analysis.stats import summarize
from bringup.engine.keys import resolve_bpsec_key
from bringup.engine.local import run_local
from bringup.errors import UserError
from bringup.scenario.config import _validate
from bringup.scenario.participants import all_participants
from bringup.scenario.world import World

__all__ = [
    "MODES",
    "RATIOS",
    "STUDY_TABLE2",
    "TABLE_KEYS",
    "combine",
    "compare_result",
    "get_path",
    "mean_ci95",
    "mean_report",
    "ratios",
    "ratios_markdown",
    "run_in_process",
    "run_matrix",
    "run_one",
    "scenario_variant",
    "table2",
    "table2_markdown",
    "table_markdown",
]

MODES = ("distributed", "centralized", "nonagile")

# (dotted report.json key, column title, format)
TABLE_KEYS: tuple[tuple[str, str, str], ...] = (
    ("value.cumulative", "cumulative value", "{:.0f}"),
    ("coverage.gp_observed_fraction", "GPs observed", "{:.1%}"),
    ("observations.count", "observations", "{:.0f}"),
    ("observations.duplicates_15min", "duplicate obs. (<15 min)", "{:.0f}"),
    ("value.assumed_error_mean", "assumed-value error, mean", "{:.1%}"),
    ("value.assumed_error.median", "error, median", "{:.1%}"),
    ("value.assumed_error.sum_based", "error, sum-based", "{:.1%}"),
    ("value.assumed_error.same_slot.mean", "error, same-slot looks", "{:.1%}"),
    ("value.assumed_error.other_slot.mean", "error, other-slot looks", "{:.1%}"),
    ("coverage.looks_per_gp", "looks per GP", "{:.2f}"),
    ("value.first_look_share", "value from first looks", "{:.0%}"),
    ("knowledge.info_age_s.median", "info age median [s]", "{:.0f}"),
    ("osse.rank_corr_15min", "rank corr. 15 min", "{:.2f}"),
)

# ratio name -> (report key, numerator mode, denominator mode)
RATIOS: dict[str, tuple[str, str, str]] = {
    "value.agile_over_nonagile": ("value.cumulative", "distributed", "nonagile"),
    "value.centralized_over_nonagile": ("value.cumulative", "centralized", "nonagile"),
    "value.distributed_over_centralized": ("value.cumulative", "distributed", "centralized"),
    "coverage.distributed_over_centralized": ("coverage.gp_observed_fraction", "distributed", "centralized"),
    "coverage.agile_over_nonagile": ("coverage.gp_observed_fraction", "distributed", "nonagile"),
    "observations.distributed_over_centralized": ("observations.count", "distributed", "centralized"),
    "assumed_error.distributed_over_centralized": ("value.assumed_error_mean", "distributed", "centralized"),
}

# The study's Table 2 (Nag et al. 2019, section 5): what it reports, for ``table2``. Its 11.3x is the
# coverage ratio 95.2 % / 8.4 %; it gives no non-agile value (None: not in the study).
STUDY_TABLE2: dict[str, float | None] = {
    "coverage.distributed": 0.952,
    "coverage.nonagile": 0.084,
    "coverage.agile_over_nonagile": 0.952 / 0.084,
    "value.agile_over_nonagile": None,
}


_MISSING = object()


def _leaves(d: dict, prefix: tuple = ()):
    for k, v in d.items():
        if isinstance(v, dict) and v:
            yield from _leaves(v, prefix + (k,))
        else:
            yield prefix + (k,), v


def _at(d: dict, path: tuple):
    for k in path:
        if not isinstance(d, dict) or k not in d:
            return _MISSING
        d = d[k]
    return d


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def mean_report(reports: list[dict]) -> dict:
    """One report-shaped dict of the means over ``reports``: a leaf that is a number (or null) in
    every report that has it is the mean of its finite values (null if none); any other leaf is kept
    where every report that has it agrees, else left out. Keys in first-seen order."""
    paths: dict[tuple, None] = {}
    for r in reports:
        for path, _v in _leaves(r):
            paths.setdefault(path, None)
    out: dict = {}
    for path in paths:
        vals = [v for v in (_at(r, path) for r in reports) if v is not _MISSING]
        if all(v is None or _is_number(v) for v in vals):
            value = summarize(vals)["mean"]
        elif all(v == vals[0] for v in vals):
            value = vals[0]
        else:
            continue
        d = out
        for k in path[:-1]:
            d = d.setdefault(k, {}) if isinstance(d, dict) else None
        if isinstance(d, dict):  # (a key that is a leaf in one report and a table in another: the table)
            d.setdefault(path[-1], value)
    return out


def combine(reports: list[dict], seeds: list[int]) -> dict:
    """One mode's reports over seeds (same order as ``seeds``) -> the means (:func:`mean_report`,
    ``seed`` the list of seeds) + ``"seeds"``: each Table-2 key's summary over the seeds."""
    if not reports:
        raise ValueError("combine: no reports")
    if len(reports) != len(seeds):
        raise ValueError(f"combine: {len(reports)} reports for {len(seeds)} seeds")
    out = mean_report(reports)
    out["seed"] = list(seeds)
    figures = {}
    for k, _, _ in TABLE_KEYS:
        per = [get_path(r, k) for r in reports]
        figures[k] = summarize(per) | {"per_seed": per}
    out["seeds"] = {"seeds": list(seeds), "n": len(seeds), "figures": figures}
    return out


def ratios(by_mode: dict[str, list[dict]], seeds: list[int]) -> dict:
    """Per-seed ratios of RATIOS and their summary over seeds (bringup/analysis/stats.py);
    ``by_mode[mode][i]`` is seed ``seeds[i]``'s report."""
    out = {}
    for name, (key, num, den) in RATIOS.items():
        if num not in by_mode or den not in by_mode:
            continue
        per = []
        for a, b in zip(by_mode[num], by_mode[den]):
            x, y = get_path(a, key), get_path(b, key)
            per.append(float(x) / float(y) if x is not None and y not in (None, 0) else None)
        out[name] = {"key": key, "numerator": num, "denominator": den, "per_seed": per, "seeds": list(seeds),
                     **summarize(per)}
    return out


def table2(result: dict) -> list[dict]:
    """The study's Table 2 beside ours: rows ``{"figure", "ours" (a summary over seeds), "study"
    (None: not in the study), "note"}``."""
    rows = []
    for m, label in (("distributed", "GPs observed, agile (distributed)"), ("nonagile", "GPs observed, non-agile")):
        if m in result:
            rows.append({"figure": label, "ours": result[m]["seeds"]["figures"]["coverage.gp_observed_fraction"],
                         "study": STUDY_TABLE2[f"coverage.{m}"], "format": "{:.1%}", "note": ""})
    r = result.get("ratios", {})
    if "coverage.agile_over_nonagile" in r:
        rows.append({"figure": "coverage ratio agile / non-agile", "ours": r["coverage.agile_over_nonagile"],
                     "study": STUDY_TABLE2["coverage.agile_over_nonagile"], "format": "{:.1f}x",
                     "note": "the study's 11.3x (95.2 % / 8.4 %)"})
    if "value.agile_over_nonagile" in r:
        rows.append({"figure": "value ratio agile / non-agile", "ours": r["value.agile_over_nonagile"],
                     "study": None, "format": "{:.1f}x", "note": "not in the study (no non-agile value)"})
    return rows


def compare_result(by_mode: dict[str, list[dict]], seeds: list[int]) -> dict:
    """The ``--json`` object: {"distributed", "centralized", "nonagile": mean reports, "ratios", "table2"}."""
    res = {m: combine(by_mode[m], seeds) for m in MODES if m in by_mode}
    res["ratios"] = ratios(by_mode, seeds)
    res["table2"] = table2(res)
    return res


# ---------------------------------------------------------------------------------------------- runs
def run_one(*, scenario: str, mode: str, seed: int | None, out: Path, engine: str = "local",
            sats: int | None = None, hours: float | None = None, plots: bool = False,
            extra: list[str] | None = None) -> dict:
    """``constellation run`` in a subprocess; its report.json. Its stderr goes to ``out/run.log``."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    cmd = [sys.executable, "-m", "bringup.cli", "run", "--scenario", scenario, "--mode", mode, "--engine", engine,
           "--out", str(out), "--no-progress"]
    for flag, v in (("--seed", seed), ("--sats", sats), ("--hours", hours)):
        if v is not None:
            cmd += [flag, str(v)]
    if not plots:
        cmd.append("--no-plots")
    cmd += list(extra or [])
    with open(out / "run.log", "w") as log:
        rc = subprocess.run(cmd, stdout=log, stderr=subprocess.STDOUT, check=False).returncode
    rep_path = out / "report.json"
    if rc != 0 or not rep_path.exists():
        tail = (out / "run.log").read_text(errors="replace").strip().splitlines()[-1:] or ["?"]
        raise UserError(f"run {mode} seed {seed} failed (exit {rc}): {tail[0]} (log: {out / 'run.log'})")
    return json.loads(rep_path.read_text())


def run_matrix(*, scenario: str, seeds: list[int | None], out: Path, engine: str = "local", sats=None,
               hours=None, jobs: int = 1, modes=MODES, say=lambda *a: None,
               extra: list[str] | None = None) -> dict[str, list[dict]]:
    """Every mode x seed; ``out/<mode>-s<seed>/``; the first seed's runs also write their plots.
    ``extra``: more ``constellation run`` arguments for every run (e.g. ``--knowledge observed``)."""
    tasks = [(m, i, s) for i, s in enumerate(seeds) for m in modes]

    def one(task):
        m, i, s = task
        d = Path(out) / f"{m}-s{s if s is not None else 'default'}"
        rep = run_one(scenario=scenario, mode=m, seed=s, out=d, engine=engine, sats=sats, hours=hours,
                      plots=(i == 0), extra=extra)
        say(f"compare: {m} seed {s}: value {get_path(rep, 'value.cumulative') or 0:.0f}, "
            f"{(get_path(rep, 'coverage.gp_observed_fraction') or 0) * 100:.1f} % GPs "
            f"({(get_path(rep, 'runtime.wall_s') or 0):.0f} s)")
        return task, rep

    res: dict = {}
    with ThreadPoolExecutor(max_workers=max(1, jobs)) as ex:
        for (m, i, _), rep in ex.map(one, tasks):
            res.setdefault(m, [None] * len(seeds))[i] = rep
    return res


# ---------------------------------------------------------------------------------------------- text
def _fmt(v, f: str) -> str:
    return "-" if v is None else f.format(v)


def _ci(s: dict, f: str) -> str:
    ci = s.get("ci95")
    return "-" if not ci else f"[{_fmt(ci[0], f)}, {_fmt(ci[1], f)}]"


def table_markdown(result: dict) -> str:
    """Table 2 equivalent: one row per mode, each cell the mean over seeds ± the sample standard
    deviation (K > 1; the 95 % intervals are in compare.json and the ratio table)."""
    k = max((len(result[m]["seeds"]["seeds"]) for m in MODES if m in result), default=1)
    head = "| mode | " + " | ".join(t for _, t, _ in TABLE_KEYS) + " |"
    lines = [f"Mean over {k} seed{'s' if k > 1 else ''}" + (" ± sample standard deviation" if k > 1 else "") + ".",
             "", head, "|" + "---|" * (len(TABLE_KEYS) + 1)]
    for m in MODES:
        if m not in result:
            continue
        figs = result[m]["seeds"]["figures"]
        cells = []
        for key, _, f in TABLE_KEYS:
            c = _fmt(figs[key]["mean"], f)
            if figs[key]["sd"] is not None:
                c += " ± " + _fmt(figs[key]["sd"], f)
            cells.append(c)
        lines.append(f"| {m} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def ratios_markdown(result: dict) -> str:
    lines = ["| ratio (per seed, then over seeds) | mean | sample sd | 95 % CI (Student t) | min | max | n |",
             "|---|---|---|---|---|---|---|"]
    for name, r in result.get("ratios", {}).items():
        lines.append(f"| {name} | {_fmt(r['mean'], '{:.3f}')} | {_fmt(r['sd'], '{:.3f}')} | {_ci(r, '{:.3f}')} | "
                     f"{_fmt(r['min'], '{:.3f}')} | {_fmt(r['max'], '{:.3f}')} | {r['n']} |")
    return "\n".join(lines)


def table2_markdown(result: dict) -> str:
    """The study's Table 2 figures beside ours (mean, 95 % CI over seeds)."""
    lines = ["| Table 2 figure | here: mean | 95 % CI | the study | note |", "|---|---|---|---|---|"]
    for row in result.get("table2", []):
        f, o = row["format"], row["ours"]
        study = "not in the study" if row["study"] is None else _fmt(row["study"], f)
        lines.append(f"| {row['figure']} | {_fmt(o['mean'], f)} | {_ci(o, f)} | {study} | {row['note']} |")
    return "\n".join(lines)


# ---------------------------------------------------------------------------------------------- sweep
def scenario_variant(sc, *, replan_period_s: float | None = None, isl_rate_bps: float | None = None,
                     sats_per_plane: int | None = None, n_stations: int | None = None,
                     transiency_min: float | None = None, seed: int | None = None):
    """A copy of scenario ``sc`` with one study parameter changed, validated like a file.
    ``replan_period_s`` also sets the plan lookahead to the period; ``n_stations`` keeps the first
    N ground stations of the scenario."""

    raw = msgspec.to_builtins(sc)
    raw.pop("source_path", None)
    if transiency_min is not None:
        raw["value"]["transiency_min"] = float(transiency_min)
    if seed is not None:
        raw["scenario"]["seed"] = int(seed)
    if replan_period_s is not None:
        # a plan must cover the time to the next replan, else the satellite idles in between:
        # the lookahead follows the period (the study's 10 min / 10 min)
        raw["scheduler"]["replan_period_s"] = float(replan_period_s)
        raw["scheduler"]["plan_lookahead_s"] = float(replan_period_s)
    if isl_rate_bps is not None:
        raw["isl"]["rate_bps"] = float(isl_rate_bps)
    if sats_per_plane is not None:
        if not isinstance(raw["constellation"], dict) or raw["constellation"].get("tle_file") \
                or raw["constellation"].get("omm_file"):
            raise UserError("satellites per plane: varies a single Walker shell, and this constellation is "
                            "another (catalogue or mixed)")
        raw["constellation"]["total_sats"] = int(sats_per_plane) * raw["constellation"]["planes"]
    if n_stations is not None:
        st = raw["ground"]["stations"]
        if not 0 <= n_stations <= len(st):
            raise UserError(f"ground-station count {n_stations}: the scenario has {len(st)} stations")
        raw["ground"]["stations"] = st[:n_stations]
    return _validate(raw, sc.source_path or "<variant>")


def run_in_process(sc, mode: str, *, store_dir: Path | None = None) -> dict:
    """One local-engine run of scenario ``sc`` in this process (no bag): its report dict."""

    world = World.build(sc)
    meta = RunMeta.for_world(world, mode, "local")
    envs: list = []

    def sink(env) -> None:
        if env.topic.endswith(REPORT_TOPIC_SUFFIXES):
            envs.append(env)

    with tempfile.TemporaryDirectory() as tmp:
        parts = all_participants(world, mode, store_dir=Path(store_dir or tmp), bpsec_key=resolve_bpsec_key()[0])
        res = run_local(parts, horizon_ns=sc.horizon_ns,
                        max_step_ns=round(sc.scenario.lockstep_max_step_s * 1e9), sink=sink)
    return build_report(envs, meta, {"wall_s": res.wall_s, "real_time_factor": res.real_time_factor})


def mean_ci95(xs: list) -> dict:
    """Mean and the 95 % confidence interval of the mean (Student's t, n - 1 degrees of freedom) of
    the finite values of ``xs``; half-width None for fewer than two."""
    v = [float(x) for x in xs if x is not None and math.isfinite(float(x))]
    if not v:
        return {"mean": None, "ci95": None, "n": 0, "values": []}
    m = sum(v) / len(v)
    if len(v) < 2:
        return {"mean": m, "ci95": None, "n": 1, "values": v}
    sd = math.sqrt(sum((x - m) ** 2 for x in v) / (len(v) - 1))
    return {"mean": m, "ci95": float(student_t.ppf(0.975, len(v) - 1)) * sd / math.sqrt(len(v)), "n": len(v),
            "values": v}
