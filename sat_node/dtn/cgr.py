"""Contact graph routing (CGR): earliest-arrival routes over a contact plan.

Follows CCSDS 734.3-B-1 (Schedule-Aware Bundle Routing, SABR) and Fraire, De Jonckere, Burleigh,
"Routing in the Space Internet: A contact graph routing tutorial" (JNCA 2021): the contact graph has
one vertex per contact; Dijkstra over it gives the route with the earliest *arrival* of the bundle,
where each hop's transmission starts at max(arrival at its sender, contact start), lasts
bits / rate, must end inside the contact and fit the contact's residual volume, and the bundle
arrives one light time (range) after its last bit left. On the first hop the sender's queued
backlog (bits of equal or higher priority ahead of this bundle) delays the start, as SABR's
"earliest transmission opportunity". Ties (SABR 3.2.6.8): earliest arrival, then fewest hops, then
the smallest contact index (a stable key: the plan is sorted by (start, src, dst)). Labels are
(arrival, hops) per contact, kept Pareto-optimal (a later arrival with fewer hops can tie at the
destination after a wait, so one label per contact is not enough for the hop tie-break); a path
through a loop is dominated by the same path without the loop (no earlier, more hops), so routes
never repeat a node (checked on every route returned): no loops. A label is not even made when
its node already has one that arrives no later with no more hops (or as early with fewer): it
could never be the first to reach that node, nor reach anything the other does not reach as soon.
Contacts missed or failed are excluded by the caller (``excluded`` mask) and the route recomputed.

One search serves every destination that shares the query's source, time, size, backlog and
exclusions (:meth:`ContactGraph.routes`: a multicast bundle's recipients at one node), with the same
route for each as its own search: the search runs to the latest of their deadlines and stops once
every destination has been reached (the argument is in :func:`_dijkstra`'s docstring).

Two savings that provably leave every answer as it was (tests/unit/test_cgr_random.py
test_horizon_and_block_skip_give_the_plain_searchs_routes compares them with the plain search on
random plans; bench/bench_cgr.py with the routes of a whole run):

* The horizon (:meth:`ContactGraph._run`). A search with destinations first runs with its deadline
  cut to t + ``horizon_s`` (32 s), and again with a horizon 16 times as far each time it runs out of
  labels before reaching its destinations, up to the deadline itself. A search whose limit is T pops,
  up to arrival T, exactly the labels the search to the deadline pops, in the same order, with the
  same predecessors: the labels one has and the other has not all arrive after T (a contact that
  starts after T gives an arrival after T: every hop takes bits / rate > 0), and a label can only
  prune (or shadow, in a contact's row) one arriving no earlier than itself. So when the cut search
  stops on its own rule (every destination found, or a pop past the first arrival + hop tolerance)
  at a pop arriving by T, the search to the deadline stops at the same pop with the same routes; when
  it runs out of labels it proves nothing, and the next horizon is searched. The queries this saves
  are the common ones: the agents' deadlines are the bundles' lifetimes (up to an hour ahead) while
  routes over the ISL mesh arrive within seconds, and a search to the deadline scans every contact a
  node will open until then.
* The scan skips closed contacts by blocks. A node's outgoing contacts are in start order; a scan
  at time t skips any aligned block of 16 of them whose latest end is <= t (all closed: the plain
  scan passes over each of them), so only what may still be open is read - a node of a 6 h plan has
  thousands of contacts, most of them over by the time it is searched from.

Not done: Yen's k-shortest route lists (we recompute per bundle, which is cheap enough: see
bench/bench_dtn.py), route reuse across instants (a route found at t is not kept for a bundle at
t' > t: the queues and contacts it depends on change), anticipatory fragmentation.

How we know it is right: hand-worked drawn plans (tests/unit/test_cgr.py), an independent
brute-force search over every simple path on random plans with zero mismatches in arrival and hop
count, with and without a hop tolerance, and one search for many destinations against one each
(tests/unit/test_cgr_random.py), properties (arrival never before contact start + light time +
transmission time; no node repeated); on a whole run's queries, the routes of the kernel before
route reuse and node-level pruning, query for query (bench/bench_cgr.py).

The kernel is numba (cache=True) over flat arrays; :class:`ContactGraph` builds them and checks the
route it returns (contiguous, time-feasible) before handing it out. Its scratch arrays (labels per
contact and hop count) are reused query by query, so one graph serves every agent of a process;
``max_hops`` bounds the routes searched (the agents' hop limit), and with it those arrays.
"""

from __future__ import annotations

import heapq
from typing import NamedTuple

import numba
import numpy as np

from orbit_clock.contact_plan import ContactPlan

__all__ = ["ContactGraph", "Route", "NO_ROUTE"]

INF = np.inf
HORIZON_S = 32.0  # ContactGraph.horizon_s's default: a first search to 32 s after the query time
HORIZON_GROWTH = 16.0  # each further search looks this many times as far
RAN_OUT, STOPPED, POOL_FULL = 0, 1, 2  # how _dijkstra ended
_BLOCK_SHIFT = 4  # a scan skips blocks of 2 ** _BLOCK_SHIFT closed contacts at a time (ContactGraph.out_blockmax)
_BLOCK = 1 << _BLOCK_SHIFT
_BLOCK_MASK = _BLOCK - 1


@numba.njit(cache=True)
def _dijkstra(start, end, src, dst, rate, owlt, residual, out_ptr, out_idx, out_maxend, out_blockmax, excluded,
              node_excluded, source, is_dest, n_dests, t0, bits, backlog_bits, deadline, arr, pred, first_backlog,
              hop_tol, stamp, qid, found_c, found_h, slot, o_start, o_end, o_dst, o_rate, o_owlt, o_vol, has_excl,
              has_resid):
    """Label-setting search over (contact, hop count) states with Pareto pruning.

    First hop on contact c starts at max(t0 + backlog_bits / rate, start) + first_backlog[c] / rate
    (first_backlog: bits already waiting for that very contact, sent when it opens).

    arr[slot[c], h]: earliest arrival at dst[c] over routes ending with contact c after h hops;
    pred[slot[c], h]: the contact before c on that route (-1 first hop). The rows of arr and pred
    are a pool: a contact gets the next free row when the search first touches it (slot[c]); only
    contacts with start <= deadline and end > t0 are touched; a search that needs more rows than the
    pool has returns POOL_FULL at once (the caller grows the pool and searches again). A label is kept only if no label of the same
    contact with fewer-or-equal hops arrives no later. States pop in (arrival, hops, contact) order,
    so the first one popped at a destination is the SABR choice for it: (found_c, found_h)[node]
    (the caller sets them to -1 at the destinations first; ``is_dest`` marks them, ``n_dests`` counts
    them). The search stops when every destination has been found; a destination still wanted is a
    relay towards the others like any node. n_dests = 0: no early stop (one-to-all).
    hop_tol > 0 (one destination only): among routes arriving no later than the earliest arrival +
    hop_tol, the one with fewest hops (then earliest arrival) is chosen; hop_tol = 0 is the plain SABR
    order. slot[c] and its arr/pred row are valid only where stamp[c] == qid (rows are reset on first
    touch, so the arrays are reused across queries without clearing them).
    A node's outgoing contacts are scanned from the first that may still be open (out_maxend: the
    running maximum of their end times, in start order) up to the first that starts after the
    deadline (no arrival through it or a later one can meet it). o_start .. o_vol: start, end, dst, rate,
    owlt and full volume by position in out_idx (o_x[k] = x[out_idx[k]]); has_excl / has_resid: False
    when ``excluded`` is all False / ``residual`` is the full volumes (then not read in the scans).

    Several destinations in one search give each the route its own search would (``deadline`` the
    latest of theirs; the caller drops a route arriving after its destination's own deadline): every
    label one search has and the other has not arrives after the first pop at that destination -
    the labels past a destination's own deadline, and the labels made by expanding the destination
    itself (each hop adds a transmission time > 0) - so the labels popped up to that first pop, the
    prunings among them, and with them its route and arrival, are the same in both
    (tests/unit/test_cgr_random.py test_one_search_for_many_destinations_equals_one_each).

    Returns STOPPED when the search stopped on its own rule - every destination found, or (hop
    tolerance) a pop past the first arrival + tolerance - and RAN_OUT when it ran out of labels (the
    caller's horizon argument, :meth:`ContactGraph._run`, needs to know which); POOL_FULL above."""
    H = arr.shape[1] - 1
    n_rows = arr.shape[0]
    used = 0
    heap = [(np.inf, 0, 0)]
    heap.pop()
    # per node and hop count: the earliest arrival of a label made there with exactly that many hops
    # (nb), and with at most that many (pm, the running minimum over hops): a new label at a node
    # where an earlier one with no more hops - or as early with fewer - was made is never the first
    # pop there, and all it could reach the earlier one reaches no later (node_min_h's argument), so
    # it is not made (_node_dominated)
    n_nodes = node_excluded.shape[0]
    nb = np.full((n_nodes, H + 1), np.inf)
    pm = np.full((n_nodes, H + 1), np.inf)
    k = _first_open(out_maxend, out_ptr[source], out_ptr[source + 1], t0)
    hi = out_ptr[source + 1]
    while k < hi:
        if k & _BLOCK_MASK == 0 and out_blockmax[k >> _BLOCK_SHIFT] <= t0:
            k += _BLOCK  # every contact of this block has closed
            continue
        c = out_idx[k]
        k += 1
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
        if _node_dominated(nb, pm, dst[c], 1, a):
            continue
        _node_label(nb, pm, dst[c], 1, a)
        if stamp[c] != qid:
            if used >= n_rows:
                return POOL_FULL
            stamp[c] = qid
            slot[c] = used
            used += 1
            arr[slot[c], :] = np.inf
            pred[slot[c], :] = -1
        arr[slot[c], 1] = a
        pred[slot[c], 1] = -1
        heapq.heappush(heap, (a, 1, c))
    best_c = -1
    best_h = 0
    best_a = np.inf
    tol = hop_tol > 0.0
    stopped = False
    left = n_dests
    # fewest hops of a label already expanded at each node: states pop in (arrival, hops) order, so
    # one expanded there with <= h hops arrived no later, and it can take every contact this one
    # could (earlier start, same residual volume): expanding this one adds no better label
    node_min_h = np.full(node_excluded.shape[0], H + 1, np.int64)
    while len(heap) > 0:
        a, h, c = heapq.heappop(heap)
        rc = slot[c]
        if a > arr[rc, h]:
            continue
        if tol and best_c >= 0 and a > best_a + hop_tol:
            stopped = True
            break
        dominated = False
        for hh in range(1, h):
            if arr[rc, hh] <= a:
                dominated = True
                break
        if dominated:
            continue
        v = dst[c]
        if is_dest[v]:
            if tol:  # (one destination) the fewest hops within the tolerance of the first arrival
                if best_c < 0:
                    best_c, best_h, best_a = c, h, a
                elif h < best_h:
                    best_c, best_h = c, h
                continue
            if found_c[v] < 0:
                found_c[v] = c
                found_h[v] = h
                left -= 1
                if left == 0:
                    return STOPPED
        if node_min_h[v] <= h:
            continue
        node_min_h[v] = h
        if tol and best_c >= 0 and h + 1 >= best_h:
            continue  # within the tolerance only a route with fewer hops could still win
        if h >= H:
            continue
        k = _first_open(out_maxend, out_ptr[v], out_ptr[v + 1], a)
        hi = out_ptr[v + 1]
        while k < hi:
            if k & _BLOCK_MASK == 0 and out_blockmax[k >> _BLOCK_SHIFT] <= a:
                k += _BLOCK  # every contact of this block has closed
                continue
            # the contact's fields from the copies in out_idx order (o_*: read in sequence, where
            # the arrays by contact index are read at random); the same values, so the same sums
            kk = k
            k += 1
            if o_start[kk] > deadline:
                break
            e = out_idx[kk]
            w = o_dst[kk]
            if (has_excl and excluded[e]) or w == source or node_excluded[w] or o_end[kk] <= a:
                continue
            ts = max(a, o_start[kk])
            te = ts + bits / o_rate[kk]
            if te > o_end[kk] or (residual[e] if has_resid else o_vol[kk]) < bits:
                continue
            na = te + o_owlt[kk]
            if na > deadline or _node_dominated(nb, pm, w, h + 1, na):
                continue
            if stamp[e] != qid:
                if used >= n_rows:
                    return POOL_FULL
                stamp[e] = qid
                slot[e] = used
                used += 1
                arr[slot[e], :] = np.inf
                pred[slot[e], :] = -1
            re_ = slot[e]
            dom = False
            for hh in range(1, h + 2):
                if arr[re_, hh] <= na:
                    dom = True
                    break
            if dom:
                continue
            _node_label(nb, pm, w, h + 1, na)
            arr[re_, h + 1] = na
            pred[re_, h + 1] = c
            heapq.heappush(heap, (na, h + 1, e))
    if tol and best_c >= 0:
        for v in range(is_dest.shape[0]):
            if is_dest[v]:
                found_c[v] = best_c
                found_h[v] = best_h
    return STOPPED if stopped else RAN_OUT


@numba.njit(cache=True)
def _node_dominated(nb, pm, w, h, a):
    """A label (arrival a, h hops) at node w is beaten there by one already made: arriving earlier
    with no more hops, or as early with fewer (it pops first: the (arrival, hops) order)."""
    return pm[w, h - 1] <= a or nb[w, h] < a


@numba.njit(cache=True)
def _node_label(nb, pm, w, h, a):
    """Record a label (arrival a, h hops) made at node w (nb, pm of _dijkstra)."""
    if a < nb[w, h]:
        nb[w, h] = a
    for k in range(h, pm.shape[1]):
        if a < pm[w, k]:
            pm[w, k] = a
        else:
            break


@numba.njit(cache=True)
def _first_open(maxend, lo, hi, t):
    """First k in [lo, hi) with maxend[k] > t (maxend is non-decreasing there); hi if none."""
    while lo < hi:
        mid = (lo + hi) // 2
        if maxend[mid] > t:
            hi = mid
        else:
            lo = mid + 1
    return lo


class Route(NamedTuple):
    """A route: contact indices in order, the next hop node name, arrival [s] at the destination."""

    contacts: tuple[int, ...]
    next_hop: str
    arrival_s: float

    @property
    def hops(self) -> int:
        return len(self.contacts)


NO_ROUTE = None


class ContactGraph:
    """Flat arrays of a contact plan and the CGR queries over it. One per plan; shareable between
    agents (queries do not modify it; residual volumes are passed in by each agent)."""

    def __init__(self, plan: ContactPlan, max_hops: int | None = None):
        """``max_hops``: the longest route searched (default: every simple path, nodes - 1 hops);
        a bundle agent's hop limit (RFC 9171 hop-count block) is the natural bound."""
        self.plan = plan
        self.contacts = list(plan.contacts)
        self.node_names = plan.nodes
        self.node_index = {n: i for i, n in enumerate(self.node_names)}
        n = len(self.contacts)
        self.start_s = np.array([c.start_s for c in self.contacts], dtype=np.float64)
        self.end_s = np.array([c.end_s for c in self.contacts], dtype=np.float64)
        self.src = np.array([self.node_index[c.src] for c in self.contacts], dtype=np.int64)
        self.dst = np.array([self.node_index[c.dst] for c in self.contacts], dtype=np.int64)
        self.rate_bps = np.array([c.rate_bps for c in self.contacts], dtype=np.float64)
        self.owlt_s = np.array([c.range_light_s for c in self.contacts], dtype=np.float64)
        self.volume_bits = (self.end_s - self.start_s) * self.rate_bps
        order = np.lexsort((np.arange(n), self.start_s, self.src))
        counts = np.bincount(self.src, minlength=len(self.node_names))
        self.out_ptr = np.zeros(len(self.node_names) + 1, dtype=np.int64)
        self.out_ptr[1:] = np.cumsum(counts)
        self.out_idx = order.astype(np.int64)
        # per node, in its contacts' start order: the latest end so far (scans skip contacts that
        # have all closed, sat_node/dtn/cgr.py _dijkstra)
        self.out_maxend = np.empty(n, dtype=np.float64)
        for i in range(len(self.node_names)):
            lo, hi = self.out_ptr[i], self.out_ptr[i + 1]
            if hi > lo:
                self.out_maxend[lo:hi] = np.maximum.accumulate(self.end_s[self.out_idx[lo:hi]])
        # per block of _BLOCK positions of out_idx (aligned on the array, not on the nodes): the latest
        # end of its contacts; a scan at time t skips a whole block whose latest end is <= t
        pad = (-n) % _BLOCK
        ends_by_pos = np.concatenate([self.end_s[self.out_idx], np.full(pad, -INF)])
        self.out_blockmax = ends_by_pos.reshape(-1, _BLOCK).max(axis=1) if n else np.empty(0)
        # the scans' copies of the contacts' fields in out_idx order (_dijkstra's o_*)
        oi = self.out_idx
        self._o_start, self._o_end, self._o_dst = self.start_s[oi], self.end_s[oi], self.dst[oi]
        self._o_rate, self._o_owlt, self._o_vol = self.rate_bps[oi], self.owlt_s[oi], self.volume_bits[oi]
        self._no_exclusion = np.zeros(n, dtype=np.bool_)
        self._no_node_exclusion = np.zeros(len(self.node_names), dtype=np.bool_)
        self._node_masks: dict[tuple, np.ndarray] = {}  # excluded node names -> mask (never written)
        self._no_backlog = np.zeros(n, dtype=np.float64)
        H = len(self.node_names)  # a simple path has at most n_nodes - 1 hops
        if max_hops is not None:
            if max_hops < 1:
                raise ValueError(f"contact graph: max_hops must be >= 1, got {max_hops}")
            H = min(H, int(max_hops))
        self.max_hops = H
        # the label pool (_dijkstra's arr/pred: one row per contact a search touches, slot[c] its
        # row), doubled when a search runs out of rows (it is then run again); rows are reset on
        # first touch, never cleared
        self._slot = np.zeros(n, dtype=np.int64)
        self._arr = np.empty((min(n, 1024), H + 1))
        self._pred = np.empty((min(n, 1024), H + 1), dtype=np.int64)
        self._starts_sorted = np.sort(self.start_s)
        self._ends_sorted = np.sort(self.end_s)
        self._stamp = np.zeros(n, dtype=np.int64)
        self._qid = 0
        self.horizon_s = HORIZON_S  # first search horizon after the query time [s] (inf: none)
        self.horizon_retries = 0  # searches re-run with a wider horizon
        # no label arrives later than this (a contact's end + its light time): a horizon past it is none
        self._latest_arrival = float((self.end_s + self.owlt_s).max()) if n else -INF
        self.searches = 0  # searches run (a route, a routes() call without hop tolerance, one-to-all: one each)
        # per node: a destination of the running search, and the (contact, hops) found there
        self._is_dest = np.zeros(len(self.node_names), dtype=np.bool_)
        self._found_c = np.full(len(self.node_names), -1, dtype=np.int64)
        self._found_h = np.zeros(len(self.node_names), dtype=np.int64)
        # per node: its outgoing contacts' start times, sorted (when a new first hop appears)
        self.out_starts = {name: np.sort(self.start_s[self.out_idx[self.out_ptr[i]:self.out_ptr[i + 1]]])
                           for i, name in enumerate(self.node_names)}
        # the same values as Python floats, for the agents' per-decision arithmetic (a numpy scalar
        # operation costs several times a float's; the results are the same IEEE doubles)
        self.start_l: list[float] = self.start_s.tolist()
        self.end_l: list[float] = self.end_s.tolist()
        self.rate_l: list[float] = self.rate_bps.tolist()
        self.out_starts_l: dict[str, list[float]] = {name: a.tolist() for name, a in self.out_starts.items()}

    def outgoing(self, node: str) -> np.ndarray:
        i = self.node_index[node]
        return self.out_idx[self.out_ptr[i]:self.out_ptr[i + 1]]

    def _run(self, source, dests, t_s, bits, backlog_bits, deadline_s, residual, excluded, excluded_nodes,
             first_backlog=None, hop_tol_s=0.0):
        """One search from ``source`` towards the node indices ``dests`` (empty: one-to-all); the
        (found contact, hops) of each destination are left in ``self._found_c`` / ``_found_h``."""
        self.searches += 1
        node_ex = self._no_node_exclusion
        if excluded_nodes:
            key = tuple(excluded_nodes)
            node_ex = self._node_masks.get(key)
            if node_ex is None:
                node_ex = self._no_node_exclusion.copy()
                for x in excluded_nodes:
                    if x in self.node_index:
                        node_ex[self.node_index[x]] = True
                self._node_masks[key] = node_ex
        is_dest, found_c = self._is_dest, self._found_c
        t_s, deadline_s = float(t_s), float(deadline_s)
        # the horizon (class docstring): searches to t_s + w, w growing by HORIZON_GROWTH, until one
        # stops on its own rule or reaches the deadline
        w = self.horizon_s if dests else INF
        try:
            for d in dests:  # a few indices: item by item beats fancy indexing with a list
                is_dest[d] = True
            while True:
                limit = t_s + w
                if not (limit < deadline_s and limit < self._latest_arrival):
                    limit = deadline_s
                self._qid += 1
                for d in dests:
                    found_c[d] = -1
                done = _dijkstra(self.start_s, self.end_s, self.src, self.dst, self.rate_bps, self.owlt_s,
                                 self.volume_bits if residual is None else residual, self.out_ptr, self.out_idx,
                                 self.out_maxend, self.out_blockmax, self._no_exclusion if excluded is None else excluded, node_ex,
                                 self.node_index[source], is_dest, len(dests), t_s, float(bits),
                                 float(backlog_bits), limit, self._arr, self._pred,
                                 self._no_backlog if first_backlog is None else first_backlog,
                                 float(hop_tol_s), self._stamp, self._qid, found_c, self._found_h, self._slot,
                                 self._o_start, self._o_end, self._o_dst, self._o_rate, self._o_owlt, self._o_vol,
                                 excluded is not None, residual is not None)
                if done == POOL_FULL:
                    self._grow_pool()  # and the same search again
                    continue
                if done == STOPPED or limit == deadline_s:
                    break
                self.horizon_retries += 1
                w *= HORIZON_GROWTH
        finally:
            for d in dests:
                is_dest[d] = False
        return self._arr, self._pred

    def _grow_pool(self) -> None:
        """Double the label pool (a search ran out of rows; never past one row per contact, which
        every search fits)."""
        have = self._arr.shape[0]
        if have >= len(self.contacts):
            raise RuntimeError(f"CGR label pool of {have} rows full with {len(self.contacts)} contacts")
        rows = min(len(self.contacts), max(2 * have, 1024))
        self._arr = np.empty((rows, self.max_hops + 1))
        self._pred = np.empty((rows, self.max_hops + 1), dtype=np.int64)

    def _pool_for(self, t_s: float, deadline_s: float) -> None:
        """Make the label pool hold a row for every contact a search from ``t_s`` to ``deadline_s``
        may touch (start <= deadline and end > t_s: the contacts that start by the deadline less
        those that have ended by t_s, which all started before it): a bound of what a search may
        need (the searches themselves grow the pool only when it is full: _grow_pool)."""
        need = int(np.searchsorted(self._starts_sorted, deadline_s, side="right")
                   - np.searchsorted(self._ends_sorted, t_s, side="right"))
        have = self._arr.shape[0]
        if need > have:
            rows = min(len(self.contacts), max(need, 2 * have, 1024))
            self._arr = np.empty((rows, self.max_hops + 1))
            self._pred = np.empty((rows, self.max_hops + 1), dtype=np.int64)

    def _route_to(self, source, d, t_s, bits, backlog_bits, deadline_s, first_backlog_bits) -> Route | None:
        """The route the last search found to node index ``d`` (None: none by ``deadline_s``)."""
        best = int(self._found_c[d])
        if best < 0:
            return None
        hops = int(self._found_h[d])
        arrival = float(self._arr[self._slot[best], hops])
        if arrival > deadline_s:
            return None
        path = []
        c, h = best, hops
        while c >= 0:
            path.append(int(c))
            c, h = self._pred[self._slot[c], h], h - 1
        path.reverse()
        fb = 0.0 if first_backlog_bits is None else float(first_backlog_bits[path[0]])
        self._check(path, source, self.node_names[d], t_s, bits, backlog_bits, arrival, fb)
        return Route(tuple(path), self.contacts[path[0]].dst, arrival)

    def route(self, source: str, dest: str, t_s: float, bits: float, *, backlog_bits: float = 0.0,
              deadline_s: float = INF, residual_bits: np.ndarray | None = None,
              excluded: np.ndarray | None = None, excluded_nodes=(), first_backlog_bits: np.ndarray | None = None,
              hop_tolerance_s: float = 0.0) -> Route | None:
        """Best route from ``source`` at ``t_s`` for a bundle of ``bits`` (None if none arrives by
        ``deadline_s``). ``residual_bits``: per-contact remaining volume (default: full volumes);
        ``excluded``: boolean mask of contacts not to use; ``excluded_nodes``: names not to visit;
        ``first_backlog_bits``: per contact, bits already waiting for it at ``source`` (sent after it
        opens, before this bundle); ``hop_tolerance_s``: prefer fewer hops among routes arriving within
        this many seconds of the earliest."""
        return self.routes(source, [(dest, deadline_s)], t_s, bits, backlog_bits=backlog_bits,
                           residual_bits=residual_bits, excluded=excluded, excluded_nodes=excluded_nodes,
                           first_backlog_bits=first_backlog_bits, hop_tolerance_s=hop_tolerance_s)[0]

    def routes(self, source: str, dests, t_s: float, bits: float, *, backlog_bits: float = 0.0,
               residual_bits: np.ndarray | None = None, excluded: np.ndarray | None = None, excluded_nodes=(),
               first_backlog_bits: np.ndarray | None = None, hop_tolerance_s: float = 0.0) -> list[Route | None]:
        """:meth:`route` to each of ``dests`` [(node, deadline [s])], in that order, from ONE search
        (the same routes as one :meth:`route` each: :func:`_dijkstra`'s docstring says why). The
        other arguments are :meth:`route`'s, shared by every destination. With a hop tolerance the
        choice at one destination depends on the search stopping there: one search each then."""
        if len(dests) == 1:  # the agents' common query: what the general path below does for one
            d, deadline_s = dests[0]
            if source == d:
                raise ValueError(f"route from {source} to itself")
            ni = self.node_index
            if source not in ni or d not in ni:
                return [None]
            di, dl = ni[d], float(deadline_s)
            self._run(source, (di,), t_s, bits, backlog_bits, dl, residual_bits, excluded, excluded_nodes,
                      first_backlog_bits, hop_tolerance_s)
            return [self._route_to(source, di, t_s, bits, backlog_bits, dl, first_backlog_bits)]
        out: list[Route | None] = [None] * len(dests)
        idx = []  # (position in dests, node index, deadline)
        for k, (d, deadline_s) in enumerate(dests):
            if source == d:
                raise ValueError(f"route from {source} to itself")
            if source in self.node_index and d in self.node_index:
                idx.append((k, self.node_index[d], float(deadline_s)))
        if not idx:
            return out
        kw = dict(residual=residual_bits, excluded=excluded, excluded_nodes=excluded_nodes,
                  first_backlog=first_backlog_bits, hop_tol_s=hop_tolerance_s)
        if hop_tolerance_s > 0.0 and len(idx) > 1:
            for k, d, dl in idx:
                self._run(source, [d], t_s, bits, backlog_bits, dl, **kw)
                out[k] = self._route_to(source, d, t_s, bits, backlog_bits, dl, first_backlog_bits)
            return out
        nodes = sorted({d for _k, d, _dl in idx})
        self._run(source, nodes, t_s, bits, backlog_bits, max(dl for _k, _d, dl in idx), **kw)
        for k, d, dl in idx:
            out[k] = self._route_to(source, d, t_s, bits, backlog_bits, dl, first_backlog_bits)
        return out

    def earliest_arrivals(self, source: str, t_s: float, bits: float) -> dict[str, float]:
        """One-to-all earliest arrival [s] with full volumes and no backlog (lower bounds)."""
        pool, _pred = self._run(source, [], t_s, bits, 0.0, INF, None, None, ())
        reached = np.flatnonzero(self._stamp == self._qid)  # the contacts this search wrote (the others: INF)
        by_node = np.full(len(self.node_names), INF)
        # per node: the earliest over the contacts into it
        np.minimum.at(by_node, self.dst[reached], pool[self._slot[reached]].min(axis=1))
        out = {self.node_names[i]: float(by_node[i]) for i in np.nonzero(np.isfinite(by_node))[0]}
        out.pop(source, None)
        return out

    def _check(self, path, source, dest, t_s, bits, backlog_bits, arrival, first_backlog=0.0):
        t = t_s
        seen = {source}
        for k, ci in enumerate(path):
            c = self.contacts[ci]
            ts = max(t + (backlog_bits / c.rate_bps if k == 0 else 0.0), c.start_s) \
                + (first_backlog / c.rate_bps if k == 0 else 0.0)
            te = ts + bits / c.rate_bps
            if (k == 0 and c.src != source) or (k > 0 and c.src != self.contacts[path[k - 1]].dst) \
                    or te > c.end_s + 1e-9 or c.dst in seen:
                raise AssertionError(f"CGR kernel returned an infeasible route {path}")
            seen.add(c.dst)
            t = te + c.range_light_s
        if self.contacts[path[-1]].dst != dest or abs(t - arrival) > 1e-6:
            raise AssertionError(f"CGR kernel arrival {arrival} != replayed {t} on {path}")
