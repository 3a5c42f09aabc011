"""``constellation dtn``: run the DTN alone (bundle agents + the ISL medium) on a contact plan and a
traffic table, on the engine of a whole run (bringup/analysis/dtn_alone.py), and print the dtn.*
figures with the latency bounds (bringup/analysis/dtn_bounds.py).

Inputs are checked before the run (orbit_clock/contact_plan_io.py, sat_node/dtn/traffic.py): bounds,
duplicates (merged with a ``warning:`` line), unknown nodes named; ``--json`` is strict JSON (a
figure that is not a finite number is null). ``--epoch now|UTC`` sets t = 0 of the plan and the
traffic: the bundles' creation times are DTN time of that clock (``--dump-bundles`` files are then
bundles a real node accepts while they live); default the study's epoch.

Checked by tests/unit/test_dtn_alone.py (the command's JSON on the study's inputs and drawn plans)
and tests/faults/test_hostile_inputs.py (bad plans, traffic and flags; duplicated rows give the
figures of the table without them).
"""

from __future__ import annotations

import argparse
import sys
import time
from datetime import UTC, datetime
from pathlib import Path

from bringup.analysis.dtn_alone import run_dtn
from bringup.analysis.dtn_bounds import (
    floor_mean,
    hops_within_ttl,
    latency_lower_bounds,
    store_forward_bound_mean,
)
from bringup.cli.common import add_epoch_arg, add_key_args
from bringup.cli.run_folder import json_text
from bringup.engine.keys import resolve_bpsec_key, write_key_file
from bringup.errors import UserError
from bringup.numba_blas import load_cython_blas
from orbit_clock.contact_plan import node_number
from orbit_clock.contact_plan_io import ContactPlanError, read_contact_plan
from sat_node.dtn.agent import SEND_ORDERS, AgentConfig
from sat_node.dtn.bpv7 import PAPER_EPOCH_DTN_MS, dtn_ms_of
from sat_node.dtn.traffic import TrafficError, read_traffic

# every file the command writes (--dump-bundles: the bundles, the key) is closed before run() returns:
# the console script may skip the interpreter's teardown (bringup/cli/main.py entry)
FAST_EXIT = True


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--contact-plan", type=Path, required=True,
                   help="contact plan file (.csv the study's table, .json HDTN, .rc/.txt ION)")
    p.add_argument("--plan-format", choices=["csv", "ion", "hdtn-json"], default=None,
                   help="contact plan format (default: from the suffix)")
    p.add_argument("--traffic", type=Path, required=True, help="traffic table (the study's traffic_case*.csv)")
    p.add_argument("--rate-bps", type=float, default=1000.0,
                   help="ISL rate [bit/s] for plans without a rate column (default: 1000)")
    p.add_argument("--bundle-bits", type=int, default=2000, help="bundle size on the link [bit] (default: 2000)")
    p.add_argument("--ttl-s", default="1:900,3:1800,15:3000",
                   help="TTL by priority as 'maxprio:seconds,...' (default: the study's 1:900,3:1800,15:3000)")
    p.add_argument("--queue", choices=list(SEND_ORDERS), default="priority",
                   help="send order: 'priority' (strict, 1 first; the study's), 'deadline' (earliest expiry "
                        "first: no bundle is left to its TTL while younger high-priority ones go, at the cost "
                        "of mean latency) or 'fifo' (oldest first, priority ignored: the no-priority case)")
    p.add_argument("--hop-tolerance-s", type=float, default=0.0, metavar="S",
                   help="CGR takes the route with the fewest hops among those arriving within S seconds of "
                        "the earliest (default 0: earliest arrival only); fewer relays where radios queue")
    p.add_argument("--forwarding", choices=["multicast", "unicast"], default="unicast",
                   help="'unicast': one bundle per (observation, recipient) - the study simulator's model, the "
                        "default on study-format inputs; 'multicast': one bundle per observation (traffic row) to "
                        "its recipient list, one transmission serving every next hop in view")
    p.add_argument("--json", action="store_true", help="print the figures as one JSON object")
    p.add_argument("--dump-bundles", type=Path, default=None, metavar="DIR",
                   help="write the encoded bytes of the first 100 bundles created, one <id>.bpv7 file each")
    p.add_argument("--no-lower-bound", action="store_true", help="skip the latency lower bounds")
    add_epoch_arg(p, "epoch")
    add_key_args(p)


_MAX_TTL_S = 10 * 365.25 * 86400  # ten years: any longer is a typo (the study's longest is 3000 s)


def _parse_ttl(text: str) -> dict[int, float]:
    try:
        out = {int(k): float(v) for k, v in (part.split(":") for part in text.split(","))}
    except ValueError:
        raise UserError(f"--ttl-s {text!r}: expected 'maxprio:seconds,...' e.g. 1:900,3:1800,15:3000") from None
    if not out or max(out) < 15 or any(not 0 < v <= _MAX_TTL_S for v in out.values()) or min(out) < 1:
        raise UserError(f"--ttl-s {text!r}: must cover priorities 1..15 with TTLs in 0..{_MAX_TTL_S:.3g} s")
    return out


def _check_args(args: argparse.Namespace) -> None:
    if not 1 <= args.rate_bps <= 1e15:
        raise UserError(f"--rate-bps {args.rate_bps:g}: must be in 1..1e15 bit/s")
    if not 1 <= args.bundle_bits <= 2**32:
        raise UserError(f"--bundle-bits {args.bundle_bits}: must be in 1..{2**32} (4 Gbit)")
    if args.hop_tolerance_s > _MAX_TTL_S:  # (a negative one: AgentConfig's own error)
        raise UserError(f"--hop-tolerance-s {args.hop_tolerance_s:g}: must be at most {_MAX_TTL_S:.3g} s")
    if args.dump_bundles is not None and args.dump_bundles.exists() and not args.dump_bundles.is_dir():
        raise UserError(f"--dump-bundles {args.dump_bundles}: is a file, not a folder")


def _check_nodes(plan, traffic, args) -> None:
    """Every node has an ipn node number (the agents name each other by it), and every traffic
    node is in the plan: unknown ones named."""
    bad = []
    for n in plan.nodes:
        try:
            node_number(n, [m for m in plan.nodes if m.startswith("gs_")])
        except ValueError:
            bad.append(n)
    if bad:
        raise UserError(f"{args.contact_plan}: nodes {bad[:5]} are neither satellites (sat_PS) nor ground "
                        "stations (gs_<name>)")
    nodes = set(plan.nodes)
    for what, names in (("sources", {t.source for t in traffic}), ("destinations", {t.dest for t in traffic})):
        unknown = sorted(names - nodes)
        if unknown:
            raise UserError(f"{args.traffic}: {what} {unknown[:5]} have no contact in {args.contact_plan}")


def run(args: argparse.Namespace) -> int:
    t0 = time.perf_counter()
    _check_args(args)
    # t = 0 of the plan and the traffic: --epoch, else the study's epoch (an ION plan's times are read
    # from this instant; without --epoch, from the plan's own '@' reference time)
    epoch = None if args.epoch is None else datetime.fromisoformat(args.epoch[:-1]).replace(tzinfo=UTC)
    epoch_dtn_ms = PAPER_EPOCH_DTN_MS if epoch is None else dtn_ms_of(epoch)

    def warn(line: str) -> None:
        print(f"constellation dtn: warning: {line}", file=sys.stderr)

    try:
        plan = read_contact_plan(args.contact_plan, args.plan_format, rate_bps=args.rate_bps, on_duplicate=warn,
                                 epoch_utc=epoch)
        traffic = read_traffic(args.traffic, on_duplicate=warn)
    except (ContactPlanError, TrafficError) as exc:
        raise UserError(str(exc)) from None
    _check_nodes(plan, traffic, args)
    ttl = _parse_ttl(args.ttl_s)
    key, key_from = resolve_bpsec_key(args.bpsec_key_file)
    try:
        config = AgentConfig.for_policy(args.queue, args.hop_tolerance_s, ttl_s_by_priority=ttl,
                                        bundle_bits=args.bundle_bits, forwarding=args.forwarding, key=key,
                                        epoch_dtn_ms=epoch_dtn_ms)
    except ValueError as exc:
        raise UserError(f"--hop-tolerance-s: {exc}") from None
    dump = None
    if args.dump_bundles is not None:
        args.dump_bundles.mkdir(parents=True, exist_ok=True)
        dump = args.dump_bundles
        if args.bpsec_key_file is None:
            # the BIBs of the dumped bundles verify under this key (another BPv7 stack needs it)
            write_key_file(dump / "bpsec.key", key)
            print(f"dtn: BPSec key {key_from} written to {dump / 'bpsec.key'}", file=sys.stderr)
    load_cython_blas()  # numba's first kernel call then skips importing scipy.linalg (bringup/numba_blas.py)
    run_ = run_dtn(plan, traffic, config=config, dump_dir=dump, dump_count=100)
    per_obs = args.forwarding == "multicast"
    report = run_.report(None if args.no_lower_bound else
                         latency_lower_bounds(plan, traffic, args.bundle_bits, run_.created_ids,
                                              per_observation=per_obs))
    report["dtn.forwarding"] = args.forwarding
    if not args.no_lower_bound:  # what no routing or send order can beat on the mean (dtn_bounds.py)
        hops = hops_within_ttl(plan, traffic, ttl)  # both bounds start from each pair's fewest hops
        report["dtn.latency_s.store_forward_bound_mean"] = store_forward_bound_mean(
            plan, traffic, args.bundle_bits, ttl, per_observation=per_obs, hops=hops)
        report["dtn.latency_s.floor_mean"] = floor_mean(plan, traffic, args.bundle_bits, ttl, hops=hops)
    report["dtn.sim_wall_s"] = run_.wall_s
    report["runtime.wall_s"] = time.perf_counter() - t0
    if args.json:
        print(json_text(report, indent=1, sort_keys=True))
    else:
        _print_table(report)
    return 0


def _fmt(v) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.3f}"
    return str(v)


def _print_table(r: dict) -> None:
    keys = ["dtn.forwarding", "dtn.observations", "dtn.bundles_originated", "dtn.bundles_created",
            "dtn.bundles_delivered", "dtn.delivery_ratio", "dtn.delivered_within_ttl_ratio", "dtn.latency_s.mean",
            "dtn.latency_s.floor_mean", "dtn.latency_s.lower_bound_mean",
            "dtn.latency_s.store_forward_bound_mean", "dtn.latency_s.median", "dtn.latency_s.p95", "dtn.latency_s.max",
            "dtn.dropped.ttl", "dtn.dropped.integrity", "dtn.dropped.other", "dtn.copies_discarded",
            "dtn.bundles_held_at_end", "dtn.conservation_ok", "dtn.transmissions_per_bundle",
            "dtn.transmissions_per_observation", "dtn.radio_busy_fraction.mean", "dtn.radio_busy_fraction.max",
            "dtn.bits_on_air", "dtn.tx_failed", "runtime.wall_s"]
    for k in keys:
        if k in r:
            print(f"{k:34s} {_fmt(r[k])}")
    print("(bundles_created / _delivered count (observation, recipient) pairs; means beside the floor and "
          "the store-and-forward bound)")
    print(f"{'priority':>8s} {'created':>8s} {'delivered':>9s} {'median_s':>9s} {'max_s':>9s}")
    for p in range(1, 16):
        c = r.get(f"dtn.latency_s_by_priority.{p}.created", 0)
        if c:
            print(f"{p:8d} {c:8d} {r[f'dtn.latency_s_by_priority.{p}.count']:9d} "
                  f"{_fmt(r[f'dtn.latency_s_by_priority.{p}.median']):>9s} "
                  f"{_fmt(r[f'dtn.latency_s_by_priority.{p}.max']):>9s}")
