"""Benchmark contact graph routing (sat_node/dtn/cgr.py) on the queries of a real run.

Two steps:

* ``capture``: run a scenario in-process (local engine) with ``ContactGraph.routes`` wrapped, and
  keep every query the bundle agents made (source, destinations with their deadlines, time, size,
  backlog, the first-hop backlog and excluded contacts as sparse lists, excluded nodes, hop
  tolerance) with the routes returned, and the contact plan - one pickle (not committed: tens of MB
  at 240 satellites).

      .venv/bin/python bench/bench_cgr.py capture --out /tmp/cgr240.pkl.gz -- \\
          --sats 240 --planes 3 --hours 1 --planning alone

* ``time``: replay every query on a fresh graph of the same plan, in the same process, interleaved,
  best of ``--repeat``:

  - baseline: one search per destination with the kernel as it was before route reuse
    (``_base_dijkstra`` below: main's ``_dijkstra`` as of fb46649, verbatim but for the name);
  - product: one ``ContactGraph.routes`` call per query (one search for the destinations that
    share it, node-level label pruning).

  ``--against no-horizon`` replaces the baseline by the product with its searches run to their
  deadlines (``ContactGraph.horizon_s`` = inf: the product before the horizon, sat_node/dtn/cgr.py),
  one search per query as the product: what the horizon saves, on the same queries.

  Checks that both give the captured routes (contacts, next hop, arrival), and prints searches,
  CPU seconds (``time.process_time``: less sensitive than wall time to the other core's load) and
  the ratio.

      .venv/bin/python bench/bench_cgr.py time /tmp/cgr240.pkl.gz [--repeat 3] [--limit N] \
          [--against fb46649|no-horizon]

A capture of the 1000-satellite run (``-- --sats 1000 --planes 25 --hours 0.5 --planning alone
--force``) holds ~5000 queries with ~15 destinations each: the routes the old code gave, the oracle
of any change to the search.
"""

from __future__ import annotations

import argparse
import gzip
import heapq
import pickle
import sys
import time
from pathlib import Path

import numba
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from sat_node.dtn import cgr  # noqa: E402
from sat_node.dtn.cgr import ContactGraph, Route  # noqa: E402

# ------------------------------------------------------------------------------------ baseline kernel
# main's _dijkstra as of fb46649 (one destination per search), verbatim but for the name: the
# baseline the product is timed against and must agree with route for route.


@numba.njit(cache=True)
def _base_dijkstra(start, end, src, dst, rate, owlt, residual, out_ptr, out_idx, out_maxend, excluded,
                   node_excluded, source, dest, t0, bits, backlog_bits, deadline, arr, pred, first_backlog,
                   hop_tol, stamp, qid):
    H = arr.shape[1] - 1
    heap = [(np.inf, 0, 0)]
    heap.pop()
    for k in range(cgr._first_open(out_maxend, out_ptr[source], out_ptr[source + 1], t0), out_ptr[source + 1]):
        c = out_idx[k]
        if start[c] > deadline:
            break
        if excluded[c] or node_excluded[dst[c]] or dst[c] == source or end[c] <= t0:
            continue
        ts = max(t0 + backlog_bits / rate[c], start[c]) + first_backlog[c] / rate[c]
        te = ts + bits / rate[c]
        if te > end[c] or residual[c] < bits:
            continue
        a = te + owlt[c]
        if a > deadline:
            continue
        if stamp[c] != qid:
            stamp[c] = qid
            arr[c, :] = np.inf
            pred[c, :] = -1
        arr[c, 1] = a
        pred[c, 1] = -1
        heapq.heappush(heap, (a, 1, c))
    best_c = -1
    best_h = 0
    best_a = np.inf
    node_min_h = np.full(node_excluded.shape[0], H + 1, np.int64)
    while len(heap) > 0:
        a, h, c = heapq.heappop(heap)
        if a > arr[c, h]:
            continue
        if best_c >= 0 and a > best_a + hop_tol:
            break
        dominated = False
        for hh in range(1, h):
            if arr[c, hh] <= a:
                dominated = True
                break
        if dominated:
            continue
        v = dst[c]
        if v != dest:
            if node_min_h[v] <= h:
                continue
            node_min_h[v] = h
        if v == dest:
            if best_c < 0:
                best_c, best_h, best_a = c, h, a
                if hop_tol <= 0.0:
                    break
            elif h < best_h:
                best_c, best_h = c, h
            continue
        if best_c >= 0 and h + 1 >= best_h:
            continue
        if h >= H:
            continue
        for k in range(cgr._first_open(out_maxend, out_ptr[v], out_ptr[v + 1], a), out_ptr[v + 1]):
            e = out_idx[k]
            if start[e] > deadline:
                break
            w = dst[e]
            if excluded[e] or w == source or node_excluded[w] or end[e] <= a:
                continue
            ts = max(a, start[e])
            te = ts + bits / rate[e]
            if te > end[e] or residual[e] < bits:
                continue
            na = te + owlt[e]
            if na > deadline:
                continue
            if stamp[e] != qid:
                stamp[e] = qid
                arr[e, :] = np.inf
                pred[e, :] = -1
            dom = False
            for hh in range(1, h + 2):
                if arr[e, hh] <= na:
                    dom = True
                    break
            if dom:
                continue
            arr[e, h + 1] = na
            pred[e, h + 1] = c
            heapq.heappush(heap, (na, h + 1, e))
    return best_c, best_h


def _base_route(g: ContactGraph, q: dict, d: str, deadline_s: float, buf_ex, buf_fb) -> Route | None:
    """One destination with the baseline kernel (the product's route() as of fb46649)."""
    g._qid += 1
    node_ex = g._no_node_exclusion
    if q["excluded_nodes"]:
        node_ex = g._no_node_exclusion.copy()
        for x in q["excluded_nodes"]:
            if x in g.node_index:
                node_ex[g.node_index[x]] = True
    best, hops = _base_dijkstra(g.start_s, g.end_s, g.src, g.dst, g.rate_bps, g.owlt_s, g.volume_bits, g.out_ptr,
                                g.out_idx, g.out_maxend, buf_ex, node_ex, g.node_index[q["source"]], g.node_index[d],
                                q["t_s"], q["bits"], q["backlog_bits"], deadline_s, g._arr, g._pred, buf_fb,
                                q["hop_tol"], g._stamp, g._qid)
    if best < 0:
        return None
    arrival = float(g._arr[best, hops])
    path = []
    c, h = best, hops
    while c >= 0:
        path.append(int(c))
        c, h = g._pred[c, h], h - 1
    path.reverse()
    return Route(tuple(path), g.contacts[path[0]].dst, arrival)


# ------------------------------------------------------------------------------------ capture
def capture(out: Path, run_argv: list[str]) -> int:
    from bringup.cli import main as cli

    orig = ContactGraph.routes
    queries: list[dict] = []
    graphs: dict[int, ContactGraph] = {}

    def hooked(self, source, dests, t_s, bits, *, backlog_bits=0.0, residual_bits=None, excluded=None,
               excluded_nodes=(), first_backlog_bits=None, hop_tolerance_s=0.0):
        if residual_bits is not None:
            raise SystemExit("bench_cgr: a query with residual volumes: not captured (the agents pass none)")
        found = orig(self, source, dests, t_s, bits, backlog_bits=backlog_bits, excluded=excluded,
                     excluded_nodes=excluded_nodes, first_backlog_bits=first_backlog_bits,
                     hop_tolerance_s=hop_tolerance_s)
        graphs.setdefault(id(self), self)
        fb = [] if first_backlog_bits is None else [(int(c), float(first_backlog_bits[c]))
                                                    for c in np.flatnonzero(first_backlog_bits)]
        ex = [] if excluded is None else [int(c) for c in np.flatnonzero(excluded)]
        queries.append({"graph": id(self), "source": source, "dests": [(d, float(dl)) for d, dl in dests],
                        "t_s": float(t_s), "bits": float(bits), "backlog_bits": float(backlog_bits), "fb": fb,
                        "excluded": ex, "excluded_nodes": tuple(excluded_nodes), "hop_tol": float(hop_tolerance_s),
                        "routes": found})
        return found

    ContactGraph.routes = hooked
    try:
        code = cli.main(["run", "--engine", "local", "--no-progress", "--no-plots", *run_argv])
    finally:
        ContactGraph.routes = orig
    plans = {gid: (g.plan, g.max_hops) for gid, g in graphs.items()}
    with gzip.open(out, "wb", compresslevel=1) as f:
        pickle.dump({"plans": plans, "queries": queries, "argv": run_argv}, f, protocol=5)
    n_dest = sum(len(q["dests"]) for q in queries)
    print(f"capture: {len(queries)} queries, {n_dest} destinations, {len(plans)} contact graph(s) -> {out}; "
          f"run exit {code}")
    return 0


# ------------------------------------------------------------------------------------ time
def _set(buf_ex, buf_fb, q, on: bool) -> None:
    for c in q["excluded"]:
        buf_ex[c] = on
    for c, x in q["fb"]:
        buf_fb[c] = x if on else 0.0


def _replay(graphs, queries, product: bool, base=None, against="fb46649"):
    """Every query once; returns (CPU s, searches, routes). The baseline (``product`` False) runs on
    the graphs ``base``: with the fb46649 kernel, or (``against`` no-horizon) with the product's code
    on graphs whose searches run to the deadline (``horizon_s`` = inf)."""
    if not product:
        graphs = base
        product = against == "no-horizon"
    bufs = {gid: (np.zeros(len(g.contacts), np.bool_), np.zeros(len(g.contacts), np.float64))
            for gid, g in graphs.items()}
    out = []
    searches = 0
    t0 = time.process_time()
    for q in queries:
        g = graphs[q["graph"]]
        buf_ex, buf_fb = bufs[q["graph"]]
        _set(buf_ex, buf_fb, q, True)
        if product:
            n0 = g.searches
            out.append(g.routes(q["source"], q["dests"], q["t_s"], q["bits"], backlog_bits=q["backlog_bits"],
                                excluded=buf_ex if q["excluded"] else None, excluded_nodes=q["excluded_nodes"],
                                first_backlog_bits=buf_fb if q["fb"] else None, hop_tolerance_s=q["hop_tol"]))
            searches += g.searches - n0
        else:
            out.append([_base_route(g, q, d, dl, buf_ex, buf_fb) for d, dl in q["dests"]])
            searches += len(q["dests"])
        _set(buf_ex, buf_fb, q, False)
    return time.process_time() - t0, searches, out


def time_corpus(path: Path, repeat: int, limit: int | None, against: str = "fb46649") -> int:
    with gzip.open(path, "rb") as f:
        doc = pickle.load(f)
    queries = doc["queries"][:limit] if limit else doc["queries"]
    graphs = {gid: ContactGraph(plan, max_hops=h) for gid, (plan, h) in doc["plans"].items()}
    base = {gid: ContactGraph(plan, max_hops=h) for gid, (plan, h) in doc["plans"].items()}
    for g in base.values():
        if against == "no-horizon":
            g.horizon_s = float("inf")
        else:  # the fb46649 kernel indexes the label arrays by contact: a row for each
            g._pool_for(-np.inf, np.inf)
    n_dest = sum(len(q["dests"]) for q in queries)
    print(f"{path}: run {' '.join(doc['argv'])}; {len(queries)} queries, {n_dest} destinations, "
          f"{sum(len(g.contacts) for g in graphs.values())} contacts")
    warm = queries[:50]  # compile / load both kernels outside the timing
    _replay(graphs, warm, False, base, against)
    _replay(graphs, warm, True)
    best = {False: float("inf"), True: float("inf")}
    counts = {}
    for _ in range(repeat):
        for product in (False, True):
            cpu, searches, routes = _replay(graphs, queries, product, base, against)
            best[product] = min(best[product], cpu)
            counts[product] = searches
            bad = sum(r != q["routes"] for r, q in zip(routes, queries))
            if bad:
                raise SystemExit(f"bench_cgr: {'product' if product else 'baseline'}: {bad} queries give other "
                                 "routes than the run's")
    print(f"{'':10} {'searches':>9} {'CPU s':>8} {'ms/search':>9}")
    for product, name in ((False, against), (True, "product")):
        print(f"{name:10} {counts[product]:>9} {best[product]:>8.2f} {1000 * best[product] / counts[product]:>9.3f}")
    print(f"every query's routes equal the run's in both; product / baseline CPU {best[True] / best[False]:.3f} "
          f"(best of {repeat}, interleaved)")
    return 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    c = sub.add_parser("capture", help="run a scenario and keep its CGR queries")
    c.add_argument("--out", type=Path, required=True)
    c.add_argument("run_argv", nargs=argparse.REMAINDER, help="-- then constellation run arguments")
    t = sub.add_parser("time", help="replay a capture: baseline against product")
    t.add_argument("capture", type=Path)
    t.add_argument("--repeat", type=int, default=3)
    t.add_argument("--limit", type=int, default=None, help="the first N queries only")
    t.add_argument("--against", choices=("fb46649", "no-horizon"), default="fb46649",
                   help="the baseline: the fb46649 kernel, one search per destination; or the product's "
                        "searches run to the deadline (ContactGraph.horizon_s = inf)")
    args = ap.parse_args()
    if args.cmd == "capture":
        argv = [a for a in args.run_argv if a != "--"]
        return capture(args.out, argv)
    return time_corpus(args.capture, args.repeat, args.limit, args.against)


if __name__ == "__main__":
    sys.exit(main())
