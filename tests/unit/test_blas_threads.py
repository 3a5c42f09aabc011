"""bringup's process set-up keeps OpenBLAS's threads from spinning without changing a number.

Oracle: the same threaded matrix-vector product (large enough that OpenBLAS splits it among its
threads, shaped as sat_node/knowledge.py's region sums, an odd number of rows so that the split
falls inside a block of four) computed in a fresh interpreter without the variable and with it
set as bringup sets it: the bits are equal (and, on two cores or more, differ from one thread's: the
products are split). And the variable is set by importing bringup, unless
the caller set it first.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]

_PRODUCT = """
import hashlib, numpy as np
rng = np.random.default_rng(5)
out = []
for g, n in ((401, 6500), (65, 9000), (1603, 4000)):
    k = np.exp(rng.uniform(-300, 0, size=(g, n)) * rng.uniform(0, 1, size=(1, n)))
    d = rng.normal(size=n)
    out.append((k @ d).tobytes() + k.sum(axis=1).tobytes())
print(hashlib.sha256(b"".join(out)).hexdigest())
"""


def _run(code: str, **env) -> str:
    base = {k: v for k, v in os.environ.items() if k != "OPENBLAS_THREAD_TIMEOUT"}
    base["PYTHONPATH"] = str(REPO)
    return subprocess.run([sys.executable, "-c", code], env={**base, **env}, capture_output=True, text=True,
                          check=True, timeout=120).stdout.strip()


def test_importing_bringup_sets_the_timeout_unless_set():
    show = "import bringup, os; print(os.environ.get('OPENBLAS_THREAD_TIMEOUT'))"
    assert _run(show) == "4"
    assert _run(show, OPENBLAS_THREAD_TIMEOUT="12") == "12"


def test_threaded_products_are_the_same_with_the_timeout():
    plain = _run(_PRODUCT)
    assert len(plain) == 64
    assert _run("import bringup\n" + _PRODUCT) == plain
    assert _run(_PRODUCT, OPENBLAS_THREAD_TIMEOUT="4") == plain
    if len(os.sched_getaffinity(0)) >= 2:  # the products are split among threads: one thread sums otherwise
        assert _run(_PRODUCT, OPENBLAS_NUM_THREADS="1") != plain
