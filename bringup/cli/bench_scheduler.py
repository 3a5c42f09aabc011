"""`constellation bench-scheduler`: DP runtime over a whole horizon and DP/MILP value ratio.

Two measurements in one run (docs/design.md section 1 "scheduler runtime 1 % of the horizon"):

1. One satellite scheduled over the scenario's whole horizon (all its passes) the way the flight
   software does it: replan every ``scheduler.replan_period_s`` over ``plan_lookahead_s`` on the
   ``dp_step_s`` grid, with its seeded belief of the OSSE value, knowing its own executed
   observations, starting each plan from where it last pointed. ``dp_s_per_sat_6h`` is the DP wall
   time summed over the replans (scaled to 6 h if the horizon differs), ``horizon_fraction`` = DP
   time / horizon (the study: 1 %; target here <= 0.01 %). Instance building (SGP4, FOR masks,
   OSSE lookups) is reported separately as ``build_s_per_sat_6h``.
2. Small single-satellite instances cut from the same scenario's passes (several satellites, a
   ``--milp-window-s`` slice, ``--milp-gps`` random GPs of the pass) solved by the DP and by the
   exact MILP (HiGHS): ``dp_over_milp_min`` / ``dp_over_milp_mean`` (the study: >= 90 %).
3. The same for pairs of satellites whose fields of regard overlap over a region (joint planning,
   sat_node/scheduler/joint.py): ``joint_dp_over_milp_min`` / ``_mean`` against the joint MILP.

The logic lives here (the package is installed; ``bench/`` is not) and ``bench/bench_scheduler.py``
runs it with a human summary.

Checked by tests/unit/test_dp_bench_cli.py.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from bringup.cli.common import add_out_arg, add_scenario_args, output_stream, scenario_from_args
from bringup.errors import UserError
from bringup.scenario.world import OrbitContext
from sat_node.scheduler import Knowledge, build_problem, solve_dp, solve_joint, solve_milp, solve_milp_joint
from sat_node.value import Belief, KnownObservation, true_value


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_scenario_args(p)
    p.add_argument("--sat", default=None, help="satellite to schedule over the horizon (default: the first)")
    p.add_argument("--instances", type=int, default=8, help="number of DP-vs-MILP instances (default: 8)")
    p.add_argument("--milp-gps", type=int, default=20, help="GPs per MILP instance (default: 20)")
    p.add_argument("--milp-window-s", type=float, default=60.0, help="MILP instance length [s] (default: 60)")
    p.add_argument("--milp-time-limit-s", type=float, default=120.0, help="HiGHS time limit per instance [s]")
    p.add_argument("--json", action="store_true", help="print the figures as one JSON object")
    add_out_arg(p)


def horizon_run(ctx, sat: str) -> dict:
    """Schedule one satellite over the whole horizon with periodic replanning; timings and values."""
    sc = ctx.scenario
    planner = ctx.planner()
    horizon = float(sc.scenario.horizon_s)
    period = float(sc.scheduler.replan_period_s)
    lookahead = float(sc.scheduler.plan_lookahead_s)
    belief = Belief.from_scenario(sc, sat, n_gp=len(ctx.gps), n_slots=ctx.osse.n_slots)
    known: list = []
    last_target = None
    last_t = None
    dp_s = build_s = 0.0
    dp_max = 0.0
    assumed = true_total = 0.0
    seen_last: dict[int, float] = {}
    seen_n: dict[int, int] = {}
    replans = 0
    t0 = 0.0
    while t0 < horizon:
        window = min(lookahead, horizon - t0)
        tb = time.perf_counter()
        p = planner.instance(sat, t0, Knowledge(ctx.osse, known, belief), window_s=window,
                             init_target_km=last_target, init_t_s=last_t)
        build_s += time.perf_counter() - tb
        td = time.perf_counter()
        plan = solve_dp(p)
        dt = time.perf_counter() - td
        dp_s += dt
        dp_max = max(dp_max, dt)
        replans += 1
        for g, t, v in zip(plan.gp_ids, plan.t_s, plan.values):
            if t >= t0 + period:
                break
            g = int(g)
            absval = float(ctx.osse.value_at(g, t))
            true_total += float(true_value(absval, t, seen_last.get(g, -np.inf), seen_n.get(g, 0),
                                           sc.value.revisit_zero_s))
            assumed += float(v)
            seen_last[g] = float(t)
            seen_n[g] = seen_n.get(g, 0) + 1
            known.append(KnownObservation(float(t), g, sat))
            last_target, last_t = ctx.gps.ecef_km[g], float(t)
        t0 += period
    scale = 21600.0 / horizon
    return {
        "sat": sat, "horizon_s": horizon, "replans": replans, "observations": len(known),
        "gps_observed": len(seen_n), "value_assumed": assumed, "value_true": true_total,
        "dp_s_per_sat_6h": dp_s * scale, "horizon_fraction": dp_s / horizon, "dp_max_replan_s": dp_max,
        "build_s_per_sat_6h": build_s * scale, "belief_sigma": belief.sigma,
    }


def milp_comparison(ctx, *, instances: int, n_gps: int, window_s: float, time_limit_s: float) -> dict:
    """DP and MILP on small instances cut from the scenario's passes (several satellites)."""
    sc = ctx.scenario
    planner = ctx.planner()
    field = Knowledge(ctx.osse)  # the OSSE field itself: the instances compare solvers, not knowledge
    rng = np.random.default_rng(sc.scenario.seed)
    rows = []
    for sat in sc.sat_names:
        if len(rows) >= instances:
            break
        for t_pass in planner.pass_starts_s(sat, 0.0, float(sc.scenario.horizon_s)):
            if len(rows) >= instances:
                break
            full = planner.instance(sat, float(t_pass), field, window_s=float(sc.scheduler.plan_lookahead_s))
            if len(full.gp_ids) < n_gps:
                continue
            # start where the pass is busiest, so the instance is not trivially empty
            busy = int(np.argmax(full.in_for.sum(axis=1)))
            t0 = float(t_pass) + max(0.0, busy * full.step_s - window_s / 2)
            ids = np.sort(rng.choice(full.gp_ids, size=n_gps, replace=False))
            p = planner.instance(sat, t0, field, window_s=window_s, gp_ids=ids)
            d = solve_dp(p)
            m = solve_milp(p, time_limit_s=time_limit_s)
            rows.append({"sat": sat, "t0_s": t0, "dp": d.value, "milp": m.objective, "milp_bound": m.dual_bound,
                         "optimal": m.optimal, "dp_s": d.solve_s, "milp_s": m.solve_s, "n_vars": m.n_vars})
    if not rows:
        raise UserError("bench-scheduler: no pass with enough GPs for a MILP instance (try --milp-gps smaller)")
    ratios = [r["dp"] / r["milp"] for r in rows if r["milp"] > 0]
    return {
        "instances": len(rows), "dp_over_milp_min": min(ratios) if ratios else 1.0,
        "dp_over_milp_mean": float(np.mean(ratios)) if ratios else 1.0,
        "milp_all_optimal": all(r["optimal"] for r in rows),
        "milp_s_total": sum(r["milp_s"] for r in rows), "dp_s_on_milp_instances": sum(r["dp_s"] for r in rows),
        "milp_instances": rows,
    }


def joint_milp_comparison(ctx, *, instances: int, n_gps: int, window_s: float, time_limit_s: float) -> dict:
    """Joint DP and joint MILP on two-satellite instances: a satellite's pass and another satellite that
    sees at least ``n_gps`` of the same GPs within ``revisit_zero_s`` (so the GPs count once for the
    two); each gets a ``window_s`` slice where it sees most of them, over ``n_gps`` random shared GPs."""
    sc = ctx.scenario
    planner = ctx.planner()
    field = Knowledge(ctx.osse)
    rng = np.random.default_rng(sc.scenario.seed + 1)
    span = float(sc.value.revisit_zero_s)
    rows = []
    names = list(sc.sat_names)
    for a in names:
        if len(rows) >= instances:
            break
        for t_pass in planner.pass_starts_s(a, 0.0, float(sc.scenario.horizon_s)):
            if len(rows) >= instances:
                break
            t_pass = float(t_pass)
            ids = planner.candidates(a, t_pass, t_pass + span) if planner.candidates else None
            if ids is not None and len(ids) == 0:
                continue
            pa = planner.instance(a, t_pass, field, window_s=span, gp_ids=ids)
            for b in names:
                if b == a or len(rows) >= instances:
                    continue
                pb = planner.instance(b, t_pass, field, window_s=span, gp_ids=pa.gp_ids)
                vis_a, vis_b = pa.in_for.any(axis=0), pb.in_for.any(axis=0)
                shared = pa.gp_ids[vis_a & vis_b]
                if len(shared) < n_gps:
                    continue
                ka = int(np.argmax(pa.in_for[:, vis_a & vis_b].sum(axis=1)))
                kb = int(np.argmax(pb.in_for[:, vis_a & vis_b].sum(axis=1)))
                t_a = t_pass + max(0.0, ka * pa.step_s - window_s / 2)
                t_b = t_pass + max(0.0, kb * pb.step_s - window_s / 2)
                if max(t_a, t_b) + window_s - min(t_a, t_b) > span:
                    continue
                pick = np.sort(rng.choice(shared, size=n_gps, replace=False))
                probs = [planner.instance(a, t_a, field, window_s=window_s, gp_ids=pick),
                         planner.instance(b, t_b, field, window_s=window_s, gp_ids=pick)]
                j = solve_joint(probs)
                _plans, obj, optimal = solve_milp_joint(probs, time_limit_s=time_limit_s)
                rows.append({"sats": [a, b], "t0_s": [t_a, t_b], "joint_dp": j.value, "milp": obj,
                             "optimal": optimal, "exact": j.exact, "dp_solves": j.dp_solves})
                break
    ratios = [r["joint_dp"] / r["milp"] for r in rows if r["milp"] > 0]
    return {"joint_instances": len(rows), "joint_dp_over_milp_min": min(ratios) if ratios else None,
            "joint_dp_over_milp_mean": float(np.mean(ratios)) if ratios else None,
            "joint_milp_all_optimal": all(r["optimal"] for r in rows), "joint_instances_detail": rows}


def run_benchmark(sc, *, sat: str | None = None, instances: int = 8, n_gps: int = 20, window_s: float = 60.0,
                  time_limit_s: float = 120.0) -> dict:
    if sat is not None and sat not in sc.sat_names:
        raise UserError(f"--sat {sat!r}: not a satellite of scenario {sc.name} ({sc.sat_names[0]}..{sc.sat_names[-1]})")
    if instances < 1 or n_gps < 1 or window_s <= 0:
        raise UserError("--instances, --milp-gps and --milp-window-s must be positive")
    if window_s > sc.value.revisit_zero_s:
        raise UserError(f"--milp-window-s {window_s} is longer than value.revisit_zero_s {sc.value.revisit_zero_s}")
    ctx = OrbitContext.from_scenario(sc)
    _warm_up(ctx)
    out = {"scenario": sc.name, "dp_step_s": sc.scheduler.dp_step_s,
           "plan_lookahead_s": sc.scheduler.plan_lookahead_s, "replan_period_s": sc.scheduler.replan_period_s}
    out.update(horizon_run(ctx, sat or sc.sat_names[0]))
    out.update(milp_comparison(ctx, instances=instances, n_gps=n_gps, window_s=window_s, time_limit_s=time_limit_s))
    out.update(joint_milp_comparison(ctx, instances=max(2, instances // 2), n_gps=n_gps, window_s=window_s,
                                     time_limit_s=time_limit_s))
    return out


def _warm_up(ctx) -> None:
    """Load (or compile once) the numba kernel so the timings measure scheduling, not compilation."""
    sat = np.array([[7088.0, 0.0, 0.0], [7088.0, 7.0, 0.0]])
    gp = np.array([[6378.0, 0.0, 0.0]])
    solve_dp(build_problem(t0_s=0.0, step_s=1.0, sat_pos_km=sat, gp_ecef_km=gp, in_for=np.ones((2, 1), bool),
                           absval=np.ones(1), slew=ctx.slew, revisit_zero_s=900.0))


def format_summary(r: dict) -> str:
    lines = [
        (f"scenario {r['scenario']}: {r['sat']} over {r['horizon_s']:.0f} s, {r['replans']} replans "
         f"(lookahead {r['plan_lookahead_s']:.0f} s, step {r['dp_step_s']:g} s)"),
        (f"  DP time          {r['dp_s_per_sat_6h']:.3f} s per satellite per 6 h "
         f"({100 * r['horizon_fraction']:.5f} % of the horizon; study: 1 %, target <= 0.01 %)"),
        f"  slowest replan   {r['dp_max_replan_s']:.3f} s; instance building {r['build_s_per_sat_6h']:.2f} s / 6 h",
        (f"  observations     {r['observations']} of {r['gps_observed']} GPs; value assumed "
         f"{r['value_assumed']:.0f}, true {r['value_true']:.0f} (belief sigma {100 * r['belief_sigma']:.1f} %)"),
        (f"  DP / MILP        min {r['dp_over_milp_min']:.4f}, mean {r['dp_over_milp_mean']:.4f} over "
         f"{r['instances']} instances (all MILP optimal: {r['milp_all_optimal']})"),
        f"  MILP time        {r['milp_s_total']:.2f} s total; DP on the same {r['dp_s_on_milp_instances']:.3f} s",
        (f"  joint DP / MILP  min {r['joint_dp_over_milp_min'] or 0:.4f}, mean {r['joint_dp_over_milp_mean'] or 0:.4f} "
         f"over {r['joint_instances']} two-satellite instances"),
    ]
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    sc = scenario_from_args(args)
    r = run_benchmark(sc, sat=args.sat, instances=args.instances, n_gps=args.milp_gps,
                      window_s=args.milp_window_s, time_limit_s=args.milp_time_limit_s)
    with output_stream(args.out) as fh:
        if args.json:
            fh.write(json.dumps(r, sort_keys=True) + "\n")
        else:
            fh.write(format_summary(r) + "\n")
    return 0
