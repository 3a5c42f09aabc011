"""A planner knows only what reached it: the test that cannot be fooled, through whole runs.

Two truth fields (value files, ``value.osse_source = "file"``) are equal everywhere except in one
region R, with one a-priori forecast. The scenario is the paper's reduced to 12 satellites and 1 h
(DTN traffic crosses planes), the transient field of 15 min. R is the region observed last in the
first run. (What changes only the GPs nobody observed is tests/system/test_gp_twin.py.) Oracles:

* ``observed`` knowledge, R's truth different from the start: every plan (satellite schedules with
  items, values and information times) and every look (assumed, recorded, information time) before
  the first look at R, and every bundle delivered before it, are identical in the two runs - on the
  local engine and on the ROS engine; after it, the runs part (R's recorded values differ);
* ``region-truth`` knowledge (the sensitivity), R's truth different after the first slot (the
  epoch state is what the forecast was issued with, which that model may know): the same - it reads
  a region's truth no later than the region's information time;
* ``oracle`` knowledge (the truth at planning time, the behaviour before knowledge models): the plans
  part *before* the first look at R - the comparison can fail, and does on a peeking planner.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from bringup.analysis.trace import deliveries_from_bag, looks_from_bag, plans_from_bag

pytestmark = [pytest.mark.system]


@pytest.fixture(scope="module")
def work(field_runs):
    """The reduced scenario's runs on field files (tests/system/conftest.py: run A shared with
    tests/system/test_gp_twin.py)."""
    return {"runs": field_runs, "gp_region": field_runs.gp_region}


def _trace(out: Path) -> dict:
    bag = out / "bag"
    return {"plans": plans_from_bag(bag), "looks": looks_from_bag(bag), "deliveries": deliveries_from_bag(bag)}


def _until(rows: list, t_ns: int, key=lambda x: x[0]) -> list:
    return [x for x in rows if key(x) < t_ns]


def _passes(looks, gp_region) -> dict[int, list[int]]:
    by: dict[int, list[int]] = {}
    for t, _s, gp, *_ in looks:
        by.setdefault(int(gp_region[gp]), []).append(t)
    return by


def _latest_first(looks, gp_region, slot_ns) -> tuple[int, int]:
    """R = the region first observed last; different from the start."""
    by = _passes(looks, gp_region)
    return max(by, key=lambda r: by[r][0]), 0


def _seen_then_gap(looks, gp_region, slot_ns) -> tuple[int, int]:
    """R and a slot k: R was observed before k's start, and not again for a replan period after it
    (so a plan covering its next look is made after the change); different from slot k on."""
    for k in range(1, 8):
        t_k = k * slot_ns
        for r, ts in sorted(_passes(looks, gp_region).items()):
            later = [t for t in ts if t >= t_k]
            if any(t < t_k for t in ts) and later and later[0] - t_k >= 600 * 10 ** 9:
                return r, k
    raise AssertionError("no region is observed, then left alone for a replan period after a slot start")


def _pair(work, model: str, choose, engine: str) -> tuple[dict, dict, int, int, int]:
    fr = work["runs"]
    runs = {"a": _trace(fr.run(model, "distributed", engine))}
    gp_region = work["gp_region"]
    slot_ns = 900 * 10 ** 9
    r, k = choose(runs["a"]["looks"], gp_region, slot_ns)
    v = fr.field.values.copy()
    cols = np.flatnonzero(fr.field.region_index == r)
    v[k:, cols] = 257 - v[k:, cols]
    runs["b"] = _trace(fr.run(model, "distributed", engine, fr.truth(v, f"truth-{r}-{k}")))
    t_first = min(t for x in runs.values() for t, _s, gp, *_ in x["looks"] if gp_region[gp] == r and t >= k * slot_ns)
    return runs["a"], runs["b"], t_first, r, k * slot_ns


def _assert_same_until(a: dict, b: dict, t_first: int, t_change: int, gp_region, r: int) -> None:
    pa, pb = _until(a["plans"], t_first), _until(b["plans"], t_first)
    assert any(gp_region[it[0]] == r for p in pa if p[0] >= t_change for it in p[3]), \
        "no plan made between the change and the first look covers R: the comparison would prove nothing"
    assert pa == pb
    assert _until(a["looks"], t_first) == _until(b["looks"], t_first)
    assert _until(a["deliveries"], t_first, key=lambda x: x[2]) == _until(b["deliveries"], t_first, key=lambda x: x[2])
    assert len(_until(a["deliveries"], t_first, key=lambda x: x[2])) > 10, "no DTN traffic before the first look"
    # and then they part: the instrument records R's different truth
    rec_a = {(s, gp, t): rec for t, s, gp, _a, rec, _i in a["looks"] if gp_region[gp] == r and t >= t_change}
    rec_b = {(s, gp, t): rec for t, s, gp, _a, rec, _i in b["looks"] if gp_region[gp] == r and t >= t_change}
    assert any(rec_a[k] != rec_b[k] for k in rec_a.keys() & rec_b.keys())


@pytest.mark.parametrize("engine", ["local", pytest.param("ros", marks=pytest.mark.ros)])
def test_observed_knowledge_plans_nothing_from_an_unobserved_region(work, engine):
    a, b, t_first, r, t_change = _pair(work, "observed", _latest_first, engine)
    _assert_same_until(a, b, t_first, t_change, work["gp_region"], r)


def test_region_truth_uses_nothing_before_its_information_time(work):
    a, b, t_first, r, t_change = _pair(work, "region-truth", _seen_then_gap, "local")
    _assert_same_until(a, b, t_first, t_change, work["gp_region"], r)


@pytest.mark.parametrize("choose", [_latest_first, _seen_then_gap], ids=["unobserved", "seen-then-changed"])
def test_the_oracle_peeks_and_the_comparison_sees_it(work, choose):
    a, b, t_first, _r, _t = _pair(work, "oracle", choose, "local")
    assert _until(a["plans"], t_first) != _until(b["plans"], t_first)


def test_reports_carry_the_knowledge_figures(work):
    rep = json.loads((work["runs"].run("observed") / "report.json").read_text())
    assert rep["knowledge"]["model"] == "observed"
    ages = rep["knowledge"]["info_age_s"]
    assert 0 <= ages["median"] <= ages["p90"] and ages["mean"] >= 0
    assert sum(rep["knowledge"]["info_age_s"]["hist"]) == rep["observations"]["count"]
    assert 0 < rep["coverage"]["looks_per_gp"] and 0 < rep["value"]["first_look_share"] <= 1
    assert 0.3 < rep["osse"]["rank_corr_15min"] < 0.7  # the file holds the 15-min transient field
    assert rep["osse"]["rank_corr_60min"] is None       # a 1 h horizon has no 60-min pair of slots
