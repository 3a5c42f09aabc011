"""Study: which send order and which routing knowledge could meet issue 4's case1 targets?

A simplified store-and-forward model of the DTN (not the product's, which is
bringup/analysis/dtn_alone.py: the bundle agents and the ISL medium on the run's engine): one radio per node, every bundle ``bits / rate`` on air, light time from the
plan, routes recomputed at each hop when the radio is free by a time-dependent Dijkstra over the
contact plan whose cost is the arrival time plus ``lam * tx * Q[v]`` for every relay v on the route
(Q = bundles queued at v, as far as the deciding node knows them). No BPv7, no BIB, no contact
volume bookkeeping: it runs case1 in ~8 s, so many policies can be compared.

Knowledge of Q (``--knowledge``):
  none        lam = 0: plain earliest arrival (what CGR does from local state);
  neighbours  only the queues of nodes in contact now (what a node could overhear on the broadcast
              medium), others taken as empty;
  oracle      every node's queue at that instant (no DTN node has this: a what-if);
  penalty:S   no queue knowledge, every relay on the route costs a fixed S seconds (routes that
              wait for a contact with fewer hops instead of relaying now).

Paring (``--pare-fraction F``, off by default): a congestion-control what-if that spends the
target's 1 % loss allowance. A bundle is refused at its source at creation ("traffic pared", RFC 9171
reason 10) when the source already holds more than ``--pare-backlog-s`` of radio time, its priority
number is at least ``--pare-min-priority``, it needs at least ``--pare-min-hops`` hops over the
contacts open now, and the run has pared fewer than F of the bundles created so far.

Send orders: priority (1 first, then creation), deadline (earliest expiry first), and srpt-guard
(fewest remaining hops over the contacts open now first, then earliest expiry; a bundle queued
within 300 s of its expiry goes before all others). A node's order key is fixed when the bundle
reaches it.

How we know the model is close enough to draw conclusions: its priority/none and deadline/none rows
land within ~5 % of bench/bench_dtn.py's full DES on the same inputs (case1: 91.7 % at 428 s against
90.7 % at 423 s; 100 % at 773 s against 798 s). Figures measured with it are in the README (DTN
section) and in issue 4's notes.

    .venv/bin/python bench/dtn_policy_study.py [--case case1] [--orders priority,deadline,srpt-guard]
        [--knowledge none,neighbours,oracle,penalty:300] [--lam 0.1] [--pare-fraction 0.009]
"""

from __future__ import annotations

import argparse
import bisect
import heapq
import itertools
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bringup.analysis.dtn_bounds import latency_lower_bounds
from orbit_clock.contact_plan_io import read_contact_plan
from sat_node.dtn.agent import AgentConfig, ttl_s_for_priority
from sat_node.dtn.traffic import read_traffic

INPUTS = Path(os.environ.get("PAPER_INPUTS",
                            Path(__file__).resolve().parents[1] / "tests" / "fixtures" / "paper_inputs"))
GUARD_S = 300.0


class Plan:
    """Per ordered pair: its contact windows (start-sorted) and light time; earliest departures."""

    def __init__(self, plan, bits: int):
        self.names = plan.nodes
        idx = {n: i for i, n in enumerate(self.names)}
        self.index = idx
        win: dict[tuple[int, int], list] = {}
        self.tx_s: dict[tuple[int, int], float] = {}
        self.light_s: dict[tuple[int, int], float] = {}
        for c in plan.contacts:
            k = (idx[c.src], idx[c.dst])
            win.setdefault(k, []).append((c.start_s, c.end_s))
            self.tx_s[k] = bits / c.rate_bps
            self.light_s[k] = c.range_light_s
        self.win = {k: sorted(v) for k, v in win.items()}
        self.starts = {k: [s for s, _e in v] for k, v in self.win.items()}
        self.adj: list[list[int]] = [[] for _ in self.names]
        for u, v in self.win:
            self.adj[u].append(v)

    def depart(self, u: int, v: int, t: float) -> float | None:
        """Earliest start >= t of a transmission u -> v that ends inside a window."""
        ws = self.win[(u, v)]
        k = max(0, bisect.bisect_right(self.starts[(u, v)], t) - 1)
        tx = self.tx_s[(u, v)]
        for s, e in ws[k:]:
            st = max(t, s)
            if st + tx <= e:
                return st
        return None

    def hops_now(self, u: int, t: float) -> list[int]:
        """Fewest hops from u over the contacts open at t (-1: unreachable now)."""
        hops = [-1] * len(self.names)
        hops[u] = 0
        frontier = [u]
        while frontier:
            nxt = []
            for x in frontier:
                for v in self.adj[x]:
                    if hops[v] < 0 and self.depart(x, v, t) == t:
                        hops[v] = hops[x] + 1
                        nxt.append(v)
            frontier = nxt
        return hops

    def route(self, src: int, dest: int, t: float, q: list[int], lam: float, deadline: float, excl: int) -> int:
        """First hop of the route minimising arrival + lam * tx * q[relay] summed over relays (-1: none)."""
        n = len(self.names)
        cost = [math.inf] * n
        first = [-1] * n
        cost[src] = t
        heap = [(t, t, src)]
        while heap:
            c, a, x = heapq.heappop(heap)
            if c > cost[x]:
                continue
            if x == dest:
                return first[dest]
            for v in self.adj[x]:
                if v == excl:
                    continue
                dp = self.depart(x, v, a)
                if dp is None:
                    continue
                na = dp + self.tx_s[(x, v)] + self.light_s[(x, v)]
                if na > deadline:
                    continue
                nc = c + (na - a) + (lam * self.tx_s[(x, v)] * q[x] if x != src else 0.0)
                if nc < cost[v]:
                    cost[v] = nc
                    first[v] = v if x == src else first[x]
                    heapq.heappush(heap, (nc, na, v))
        return -1


def simulate(plan: Plan, items: list[tuple], order: str, knowledge: str, lam: float,
             pare: dict | None = None) -> dict:
    """items: (t_s, src, dest, priority, ttl_s) in creation order; ``pare``: fraction, backlog_s,
    min_priority, min_hops (module docstring) or None. Returns the run's figures."""
    n = len(plan.names)
    tx_min = min(plan.tx_s.values())
    penalty_s = float(knowledge.split(":", 1)[1]) if knowledge.startswith("penalty:") else None
    if knowledge == "none":
        lam = 0.0
    elif penalty_s is not None:  # lam * tx * q == penalty_s for every relay
        lam, fixed_q = 1.0, [penalty_s / tx_min] * n
    queues: list[list] = [[] for _ in range(n)]
    qlen = [0] * n
    busy = [0.0] * n
    pending = [False] * n
    events = [(it[0], 0, i, (it[1], -1)) for i, it in enumerate(items)]
    heapq.heapify(events)
    seq = itertools.count(len(items))
    delivered: list[float | None] = [None] * len(items)
    left_source: list[float | None] = [None] * len(items)
    prev = [-1] * len(items)
    hops_cache: dict[tuple[int, int], list[int]] = {}
    tx_count = 0
    pared = 0
    now = [0.0]

    def remaining_hops(u: int, d: int) -> int:
        key = (u, int(now[0] // 10))
        if key not in hops_cache:
            hops_cache[key] = plan.hops_now(u, now[0])
        h = hops_cache[key][d]
        return h if h > 0 else n

    def rank(i: int, u: int) -> tuple:
        t, _s, d, p, ttl = items[i]
        if order == "priority":
            return (p, t)
        if order == "deadline":
            return (t + ttl, p)
        if t + ttl - now[0] < GUARD_S:  # srpt-guard: near its expiry (when queued here) it goes first
            return (0, 0, t + ttl)
        return (1, remaining_hops(u, d), t + ttl)

    while events:
        t, kind, i, data = heapq.heappop(events)
        now[0] = t
        if kind == 0:  # bundle i reaches node u
            u, from_node = data
            if u == items[i][2]:
                delivered[i] = t
                continue
            prev[i] = from_node
            if (pare and from_node < 0 and qlen[u] * tx_min > pare["backlog_s"]
                    and items[i][3] >= pare["min_priority"] and pared < pare["fraction"] * (i + 1)
                    and remaining_hops(u, items[i][2]) >= pare["min_hops"]):
                pared += 1  # refused at its source: counted as not delivered
                continue
            heapq.heappush(queues[u], (rank(i, u), i))
            qlen[u] += 1
            if not pending[u]:
                pending[u] = True
                heapq.heappush(events, (max(t, busy[u]), 1, next(seq), u))
            continue
        u = data  # node u's radio is free: choose what to send
        pending[u] = False
        if knowledge == "neighbours":
            q = [0] * n
            for v in plan.adj[u]:
                if plan.depart(u, v, t) == t:
                    q[v] = qlen[v]
        elif penalty_s is not None:
            q = fixed_q
        else:
            q = qlen
        waiting, sent, wake = [], False, math.inf
        while queues[u]:
            k, j = heapq.heappop(queues[u])
            tc, s, d, _p, ttl = items[j]
            nh = -1
            if t < tc + ttl:
                nh = plan.route(u, d, t, q, lam, tc + ttl, prev[j])
                if nh < 0:
                    nh = plan.route(u, d, t, q, lam, tc + ttl, -1)
            if nh < 0:  # expired or no route within its lifetime: dropped
                qlen[u] -= 1
                continue
            dp = plan.depart(u, nh, t)
            if dp > t:  # its best route waits for a contact: keep it, look further
                waiting.append((k, j))
                wake = min(wake, dp)
                continue
            qlen[u] -= 1
            if u == s:
                left_source[j] = t
            tx_count += 1
            busy[u] = t + plan.tx_s[(u, nh)]
            heapq.heappush(events, (busy[u] + plan.light_s[(u, nh)], 0, j, (nh, u)))
            sent = True
            break
        for w in waiting:
            heapq.heappush(queues[u], w)
        if queues[u] and (sent or wake < math.inf):
            pending[u] = True
            heapq.heappush(events, (busy[u] if sent else wake, 1, next(seq), u))
    ok = [j for j, dv in enumerate(delivered) if dv is not None and dv - items[j][0] <= items[j][4] + 1e-9]
    lat = np.array([delivered[j] - items[j][0] for j in ok])
    return {"delivered": len(ok) / len(items), "mean_s": float(lat.mean()),
            "source_wait_s": float(np.mean([left_source[j] - items[j][0] for j in ok])),
            "tx_per_bundle": tx_count / len(items), "pared": pared / len(items)}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--case", default="case1")
    ap.add_argument("--rate-bps", type=float, default=1000.0)
    ap.add_argument("--bundle-bits", type=int, default=2000)
    ap.add_argument("--orders", default="priority,deadline,srpt-guard")
    ap.add_argument("--knowledge", default="none,neighbours,oracle")
    ap.add_argument("--lam", type=float, default=0.1, help="weight of a relay's queue in the route cost")
    ap.add_argument("--pare-fraction", type=float, default=0.0, help="paring allowance (0: off)")
    ap.add_argument("--pare-backlog-s", type=float, default=200.0)
    ap.add_argument("--pare-min-priority", type=int, default=4)
    ap.add_argument("--pare-min-hops", type=int, default=2)
    args = ap.parse_args()
    contact_plan = read_contact_plan(INPUTS / "contact_plan_3p_8s.csv", rate_bps=args.rate_bps)
    plan = Plan(contact_plan, args.bundle_bits)
    traffic = read_traffic(INPUTS / f"traffic_{args.case}.csv")
    ttls = AgentConfig(key=bytes(16)).ttl_s_by_priority
    items = [(it.t_s, plan.index[it.source], plan.index[it.dest], it.priority,
              ttl_s_for_priority(it.priority, ttls)) for it in traffic]
    per_bundle = latency_lower_bounds(contact_plan, traffic, args.bundle_bits, {i: i for i in range(len(traffic))})
    bound = float(np.mean(list(per_bundle.values())))
    print(f"{args.case}: {len(items)} bundles at {args.rate_bps:g} b/s; issue's bound mean {bound:.1f} s "
          f"(target: >= 99 % delivered, mean <= {1.25 * bound:.1f} s)")
    pare = None if args.pare_fraction <= 0 else {
        "fraction": args.pare_fraction, "backlog_s": args.pare_backlog_s,
        "min_priority": args.pare_min_priority, "min_hops": args.pare_min_hops}
    print("order       knowledge   delivered  mean_s  /bound  source_wait_s  tx/bundle  pared  wall_s")
    for order in args.orders.split(","):
        for knowledge in args.knowledge.split(","):
            t0 = time.perf_counter()
            r = simulate(plan, items, order, knowledge, args.lam, pare)
            print(f"{order:11s} {knowledge:11s} {100 * r['delivered']:8.2f}% {r['mean_s']:7.1f} {r['mean_s'] / bound:6.2f}x "
                  f"{r['source_wait_s']:14.1f} {r['tx_per_bundle']:10.3f} {100 * r['pared']:5.2f}% {time.perf_counter() - t0:7.1f}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
