"""report.md: the human summary of a run's report.json, with its plots embedded.

Checked by tests/unit/test_cli_exit.py (a whole local run writes a non-empty report.md beside
report.json and its plots).
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["write_report_md", "report_md"]


def _fmt(v, nd=3):
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:,.{nd}f}"
    return f"{v:,}" if isinstance(v, int) else str(v)


def _yes(x):
    return "-" if x is None else ("yes" if x else "no")


def _pct(x) -> str:
    return "-" if x is None else f"{x * 100:.1f} %"


def _rejected(sec: dict) -> str:
    rej = sec.get("rejected") or {}
    if not rej:
        return "0"
    return f"{sum(rej.values())} ({', '.join(f'{k} {n}' for k, n in rej.items())})"


def report_md(rep: dict, plots: list[Path] = (), base: Path | None = None) -> str:
    v, c, o, d, r = rep["value"], rep["coverage"], rep["observations"], rep.get("dtn", {}), rep.get("runtime", {})
    k, f = rep.get("knowledge") or {}, rep.get("osse") or {}
    age = k.get("info_age_s") or {}
    ae = v.get("assumed_error") or {}
    same, other = ae.get("same_slot") or {}, ae.get("other_slot") or {}
    rc, g = f.get("rel_change_at_info_age") or {}, rep.get("ground") or {}
    cad = (rep.get("looks") or {}).get("in_pass_interval_s") or {}
    lines = [
        f"# Run report: {rep['scenario']} / {rep['mode']} / {rep['engine']} engine",
        "",
        f"{rep['n_sats']} satellites, horizon {rep['horizon_s'] / 3600:g} h, seed {rep['seed']}.",
        "",
        "| figure | value |",
        "|---|---|",
        f"| cumulative value (Eq. 1) | {_fmt(v['cumulative'], 1)} |",
        f"| GPs observed | {c['gp_observed']} / {c['gp_total']} ({_fmt((c['gp_observed_fraction'] or 0) * 100, 1)} %) |",
        f"| observations | {o['count']} ({o['duplicates_15min']} within 15 min of another) |",
        f"| assumed vs recorded value error (mean) | {_fmt((v['assumed_error_mean'] or 0) * 100, 1)} % |",
        f"| error median / sum-based | {_pct(ae.get('median'))} / {_pct(ae.get('sum_based'))} |",
        f"| error of same-slot looks (mean, n) / other-slot looks | {_pct(same.get('mean'))} ({same.get('n', '-')}) / "
        f"{_pct(other.get('mean'))} ({other.get('n', '-')}) |",
        f"| looks per GP / value from first looks | {_fmt(c.get('looks_per_gp'), 2)} / "
        f"{_fmt((v.get('first_look_share') or 0) * 100, 1)} % |",
        f"| knowledge model; information age mean / median / p90 [s] | {k.get('model') or '-'}; "
        f"{_fmt(age.get('mean'), 0)} / {_fmt(age.get('median'), 0)} / {_fmt(age.get('p90'), 0)} |",
        f"| field: rank correlation at 15 / 60 min; transiency [min] | {_fmt(f.get('rank_corr_15min'), 2)} / "
        f"{_fmt(f.get('rank_corr_60min'), 2)}; {_fmt(f.get('transiency_min'), 1)} |",
        f"| field: OSSE resolution / decorrelation [min]; flash floods | {_fmt(f.get('osse_resolution_min'), 0)} / "
        f"{_fmt(f.get('decorrelation_min'), 1)}; {_yes(f.get('flash_floods'))} |",
        f"| field's relative change at the median information age, mean / median | "
        f"{_pct(rc.get('mean'))} / {_pct(rc.get('median'))} |",
        f"| ground passes / uplinks per satellite and orbit | {_fmt(g.get('passes_per_orbit'), 2)} / "
        f"{_fmt(g.get('uplinks_per_orbit'), 2)} |",
        f"| in-pass look interval: mode [s] (share) | {_fmt(cad.get('mode_s'))} "
        f"({_pct(cad.get('mode_share'))}) |",
        f"| bundles created / delivered | {_fmt(d.get('bundles_created'))} / {_fmt(d.get('bundles_delivered'))} |",
        f"| delivery ratio | {_fmt(d.get('delivery_ratio'))} |",
        f"| latency mean / median / p95 [s] | {_fmt((d.get('latency_s') or {}).get('mean'), 1)} / "
        f"{_fmt((d.get('latency_s') or {}).get('median'), 1)} / {_fmt((d.get('latency_s') or {}).get('p95'), 1)} |",
        f"| drops ttl / integrity / other | {_fmt((d.get('dropped') or {}).get('ttl'))} / "
        f"{_fmt((d.get('dropped') or {}).get('integrity'))} / {_fmt((d.get('dropped') or {}).get('other'))} |",
        f"| wall time [s] / real-time factor | {_fmt(r.get('wall_s'), 1)} / {_fmt(r.get('real_time_factor'), 0)} |",
        f"| scheduler CPU per satellite [s] | {_fmt(r.get('scheduler_cpu_s_per_sat'), 2)} |",
        f"| messages rejected (not the run's, malformed) | {_rejected(rep.get('security') or {})} |",
        "",
    ]
    by_p = d.get("latency_s_by_priority") or {}
    if by_p:
        lines += ["## Bundle latency by priority", "", "| priority | count | median [s] | max [s] |", "|---|---|---|---|"]
        for p in sorted(by_p, key=int):
            e = by_p[p]
            lines.append(f"| {p} | {_fmt(e.get('count'))} | {_fmt(e.get('median'), 1)} | {_fmt(e.get('max'), 1)} |")
        lines.append("")
    if plots:
        lines += ["## Plots", ""]
        for p in plots:
            rel = Path(p).relative_to(base) if base else Path(p).name
            lines.append(f"![{Path(p).stem}]({rel})")
        lines.append("")
    return "\n".join(lines)


def write_report_md(path: Path, rep: dict, plots: list[Path] = ()) -> Path:
    path = Path(path)
    path.write_text(report_md(rep, plots, base=path.parent))
    return path
