"""Benchmark: access + contacts for the paper scenario (24 satellites, 500 GPs, 6 h).

Prints wall times of the coarse-then-refine searches used by the product and, in the same run, the
brute-force 1 s grid baselines (every GP / every pair at every second), plus how the two agree,
and the ISL plan's figures against the study's own plan (tests/fixtures/paper_inputs).

Run: .venv/bin/python bench/bench_orbit.py [--no-baseline]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bringup.scenario.config import load_scenario
from orbit_clock import (
    access_windows,
    access_windows_bruteforce,
    build_constellation,
    ground_contact_plan,
    ground_points,
    isl_contact_plan,
    isl_windows,
)
from orbit_clock.contact_plan import canonical_node
from orbit_clock.contact_plan_io import read_contact_plan


def _t(fn):
    t = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--no-baseline", action="store_true")
    args = ap.parse_args()
    sc = load_scenario("paper")
    H = float(sc.scenario.horizon_s)
    (c, g), t_setup = _t(lambda: (build_constellation(sc), ground_points(sc)))
    print(f"scenario paper: {len(c)} sats, {len(g)} GPs, {H / 3600:.0f} h; setup {t_setup:.3f} s")
    w, t_acc = _t(lambda: access_windows(c, g, 0.0, H, sc.instrument.for_off_nadir_deg))
    isl, t_isl = _t(lambda: isl_contact_plan(sc, c))
    gnd, t_gnd = _t(lambda: ground_contact_plan(sc, c))
    total = t_acc + t_isl + t_gnd
    print(f"access (coarse 20 s + 1 s refine): {len(w)} windows in {t_acc:.3f} s "
          f"({w.meta['coarse_samples']} coarse sat-samples, {w.meta['fine_samples']} fine sat-samples)")
    print(f"ISL contacts (10 s grid + bisection): {len(isl)} directed in {t_isl:.3f} s")
    print(f"ground contacts: {len(gnd)} directed in {t_gnd:.3f} s")
    print(f"TOTAL access + contacts: {total:.3f} s (target well under 10 s)")

    pairs = isl.pairs()
    full = {p for p in pairs if any(x.start_s == 0 and x.end_s == H for x in isl if tuple(sorted((x.src, x.dst))) == p)}
    cross = [x.duration_s for x in isl if x.src[4] != x.dst[4]]
    print(f"ours : contacts {len(isl)}, pairs {len(pairs)}, in-plane pairs in contact all horizon {len(full)}, "
          f"cross-plane window median {statistics.median(cross):.0f} s (min {min(cross):.0f}, max {max(cross):.0f}, "
          f"n {len(cross)})")
    inputs = Path(os.environ.get("PAPER_INPUTS",
                                 Path(__file__).resolve().parents[1] / "tests" / "fixtures" / "paper_inputs"))
    paper = inputs / "contact_plan_3p_8s.csv"
    if paper.exists():
        th = read_contact_plan(paper, rate_bps=1000.0)
        tp = {tuple(sorted(map(canonical_node, p))) for p in th.pairs()}
        tfull = {tuple(sorted(map(canonical_node, (x.src, x.dst)))) for x in th if x.start_s == 0 and x.end_s == H}
        tc = [x.duration_s for x in th if x.src[-2] != x.dst[-2]]
        print(f"study: contacts {len(th)}, pairs {len(tp)}, all-horizon pairs {len(tfull)}, cross-plane median "
              f"{statistics.median(tc):.0f} s (min {min(tc):.0f}, max {max(tc):.0f}, n {len(tc)}); same pair set: "
              f"{tp == pairs}")

    if not args.no_baseline:
        b, t_b = _t(lambda: access_windows_bruteforce(c, g, 0.0, H, sc.instrument.for_off_nadir_deg))
        same = len(b) == len(w) and np.array_equal(b.gp, w.gp) and np.array_equal(b.sat, w.sat)
        dmax = float(max(np.abs(b.start_s - w.start_s).max(), np.abs(b.end_s - w.end_s).max())) if same else float("nan")
        print(f"BASELINE access brute force 1 s grid, all 500 GPs: {len(b)} windows in {t_b:.3f} s "
              f"(x{t_b / t_acc:.0f} slower); identical windows: {same}, max edge diff {dmax:.2e} s")
        (bi, _bj, _bs, _be), t_bi = _t(lambda: isl_windows(c, 0.0, H, step_s=1.0, refine=False))
        print(f"BASELINE ISL brute force 1 s grid: {len(bi)} undirected windows in {t_bi:.3f} s "
              f"(refined plan has {len(isl) // 2})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
