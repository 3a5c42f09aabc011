"""The memory estimate of a scenario (bringup/scenario/limits.py) against the arrays a run really
makes, and the refusal of scenarios over the budget.

Oracle: for small scenarios, each term of the estimate is at least the bytes of the arrays it
counts (counted with ``ndarray.nbytes`` on a built world, its beliefs and the largest planner
instance of one satellite over the horizon) and at most 10 times them, so the estimate neither lets
a big run through nor refuses a small one by an order of magnitude; the sizes of the issue's
inputs (gp_spacing_km = 1e-3, horizon_s = 1e12, dp_step_s = 1e-6) are refused in one line naming
the estimate and the key that drives it.
"""

from __future__ import annotations

import math

import msgspec
import numpy as np
import pytest
from scenario_edit import raw_scenario

from bringup.scenario.config import ScenarioError, _validate, load_scenario
from bringup.scenario.limits import ENV_BUDGET, check_run_size, estimate_bytes, gib, memory_budget_bytes
from bringup.scenario.world import World
from sat_node.scheduler.planner import Knowledge, PersistenceView
from sat_node.value import Belief


def _scenario(**keys):
    raw = raw_scenario(load_scenario("paper").with_overrides(sats=6, hours=1))
    for k, v in keys.items():
        sec, key = k.split("__")
        raw[sec][key] = v
    return _validate(raw, "<test>")


def _nbytes(*arrays) -> int:
    return sum(np.asarray(a).nbytes for a in arrays)


@pytest.mark.parametrize("keys", [{}, {"regions__gp_spacing_km": 4.0, "scheduler__dp_step_s": 2.0}])
def test_terms_bound_the_arrays_they_count(keys):
    sc = _scenario(**keys)
    est = {k: b for k, (b, _) in estimate_bytes(sc).items()}
    w = World.build(sc)
    g = w.gps
    n_slots = w.osse.n_slots
    counted = {
        "ground points": _nbytes(g.region_index, g.row, g.col, g.lat_deg, g.lon_deg, g.ecef_km),
        "OSSE field": _nbytes(w.osse.values),
        "beliefs": (len(w.sat_names) + 1) * Belief.from_scenario(sc, w.sat_names[0], w.n_gp, n_slots).z.nbytes,
    }
    planner = w.planner
    biggest = 0
    for t0 in np.arange(0.0, sc.scenario.horizon_s - sc.scheduler.plan_lookahead_s, 300.0):
        ids = planner.candidates(w.sat_names[0], t0, t0 + sc.scheduler.plan_lookahead_s) if hasattr(
            planner, "candidates") else None
        p = planner.instance(w.sat_names[0], float(t0), Knowledge(PersistenceView(w.osse, float(t0))), gp_ids=ids)
        biggest = max(biggest, _nbytes(p.in_for, p.absval, p.prior_count, p.prior_recent))
    counted["planner instance"] = biggest
    for k, n in counted.items():
        assert n > 0, k
        assert n <= est[k] <= 10 * n, (k, n, est[k])
    assert est["beliefs"] == counted["beliefs"]  # one float64 per GP and slot, per satellite and the ground


@pytest.mark.parametrize("key,value,driver", [
    ("regions__gp_spacing_km", 1e-3, "regions.gp_spacing_km 0.001"),
    ("scenario__horizon_s", 1e12, "scenario.horizon_s 1e+12"),
    ("scheduler__dp_step_s", 1e-6, "scheduler.dp_step_s 1e-06"),
])
def test_the_issues_sizes_are_refused(key, value, driver):
    sc = _scenario(**{key: value})
    with pytest.raises(ScenarioError) as ei:
        check_run_size(sc, budget=20 * 2**30)
    line = str(ei.value)
    assert "\n" not in line and "would need about" in line and driver in line and "over the 20 GiB budget" in line


def test_the_reference_runs_fit_and_the_budget_can_be_set(monkeypatch):
    paper = load_scenario("paper")
    assert check_run_size(paper, budget=2 * 2**30) < 2**30  # the 24-satellite, 6 h study run: under 1 GiB
    monkeypatch.setenv(ENV_BUDGET, "0.1")
    assert memory_budget_bytes() == pytest.approx(0.1 * 2**30)
    with pytest.raises(ScenarioError, match=ENV_BUDGET):
        check_run_size(paper)
    for bad in ("x", "-1", "nan", "inf"):
        monkeypatch.setenv(ENV_BUDGET, bad)
        with pytest.raises(ScenarioError, match=ENV_BUDGET):
            memory_budget_bytes()
    monkeypatch.delenv(ENV_BUDGET)
    assert math.isfinite(memory_budget_bytes())


def test_gib():
    assert gib(47.7 * 2**30) == "47.7 GiB" and gib(512 * 2**20) == "512 MiB" and gib(math.inf) == "inf TiB"
    assert msgspec.to_builtins(estimate_bytes(load_scenario("paper")))  # plain numbers and strings
