"""The DP kernel gives the same plans compiled and interpreted (NUMBA_DISABLE_JIT=1), both exact."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
SCRIPT = """
import json, sys
sys.path.insert(0, {here!r})
from dp_instances import random_instance
from sat_node.scheduler import solve_brute, solve_dp
out = []
for seed in range(8):
    p = random_instance(seed, n_gp=5, n_steps=45, max_window=5, prior=seed % 2 == 1)
    d = solve_dp(p)
    out.append({{"seed": seed, "dp": d.value, "brute": solve_brute(p).value,
                 "plan": [[int(k), int(j)] for k, j in zip(d.steps, d.cols)]}})
# one bigger instance with long windows, repeats and a short revisit (heuristic regime)
p = random_instance(99, n_gp=25, n_steps=300, max_window=150, revisit_zero_s=30.0, spread_deg=6.0, prior=True)
d = solve_dp(p)
out.append({{"seed": 99, "dp": d.value, "brute": None, "plan": [[int(k), int(j)] for k, j in zip(d.steps, d.cols)]}})
print(json.dumps(out))
"""


def _run(disable_jit: str):
    env = dict(os.environ, NUMBA_DISABLE_JIT=disable_jit)
    r = subprocess.run([sys.executable, "-c", SCRIPT.format(here=str(HERE))], capture_output=True, text=True, check=False,
                       env=env, cwd=HERE.parents[1], timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    return json.loads(r.stdout)


@pytest.fixture(scope="module")
def results():
    return {mode: _run(mode) for mode in ("0", "1")}


@pytest.mark.parametrize("mode", ["0", "1"])
def test_dp_exact_in_both_modes(results, mode):
    for r in results[mode]:
        if r["brute"] is not None:
            assert r["dp"] == pytest.approx(r["brute"], abs=1e-9), r["seed"]


def test_same_plans_compiled_and_interpreted(results):
    assert results["0"] == results["1"]
