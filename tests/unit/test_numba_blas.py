"""bringup/numba_blas.py: numba's BLAS check satisfied by scipy's own cython_blas module, loaded
without the scipy.linalg package. Each case runs in a fresh interpreter (the test process has
numba and scipy imported already)."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

_PLAN = textwrap.dedent("""
    from orbit_clock.contact_plan import Contact, ContactPlan
    from sat_node.dtn.cgr import ContactGraph
    plan = ContactPlan([Contact(0.0, 100.0, "sat_11", "sat_12", 1000.0, 0.1),
                        Contact(10.0, 200.0, "sat_12", "sat_13", 1000.0, 0.1)])
    route = ContactGraph(plan).route("sat_11", "sat_13", 0.0, 2000)
    """)


def _run(code: str) -> str:
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, check=False)
    assert r.returncode == 0, r.stderr
    return r.stdout.strip()


@pytest.mark.parametrize("seeded", [True, False])
def test_numba_check_finds_blas_without_scipy_linalg(seeded):
    """With the module loaded first, a CGR query (numba's first kernel: its target initialised)
    leaves scipy.linalg unimported and numba's BLAS flag as it is without (True); the module in
    sys.modules is scipy's cython_blas file, with its BLAS entry points (dgemm...)."""
    code = ("import sys\nfrom bringup.numba_blas import load_cython_blas\n"
            + ("print(load_cython_blas())\n" if seeded else "print(None)\n") + _PLAN
            + textwrap.dedent("""
                from numba.np import arraymath
                m = sys.modules["scipy.linalg.cython_blas"]
                print(route is not None, arraymath._HAVE_BLAS, "scipy.linalg" in sys.modules,
                      "/".join(m.__file__.split("/")[-3:-1]), "dgemm" in m.__pyx_capi__, sep="|")
                """))
    first, second = _run(code).splitlines()
    routed, have_blas, linalg, where, dgemm = second.split("|")
    assert first == ("True" if seeded else "None")
    assert routed == have_blas == dgemm == "True"
    assert where == "scipy/linalg"
    assert linalg == ("False" if seeded else "True")


def test_scipy_linalg_and_optimize_work_after_it():
    """Code that does use scipy.linalg afterwards imports it as usual (the multicast latency bound's
    linear_sum_assignment, a solve), and a second call does nothing."""
    code = ("from bringup.numba_blas import load_cython_blas\nassert load_cython_blas()\n" + _PLAN
            + textwrap.dedent("""
                import numpy as np
                import scipy.linalg
                from scipy.linalg import cython_blas
                from scipy.optimize import linear_sum_assignment
                rows, cols = linear_sum_assignment(np.array([[4.0, 1.0], [2.0, 3.0]]))
                x = scipy.linalg.solve(np.array([[2.0, 0.0], [0.0, 4.0]]), np.array([2.0, 8.0]))
                print(cols.tolist(), x.tolist(), cython_blas.__name__, load_cython_blas())
                """))
    assert _run(code) == "[1, 0] [1.0, 2.0] scipy.linalg.cython_blas False"
