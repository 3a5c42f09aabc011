"""The application around the flight software: scenarios, the two engines, recording, analysis,
deployment files and the ``constellation`` command line (README "Layout"; docs/design.md section 2).

Process set-up, before numpy is first imported: OpenBLAS's worker threads sleep as soon as a
threaded call ends (``OPENBLAS_THREAD_TIMEOUT``, unless the caller set it) instead of spinning for
about 2^28 cycles waiting for the next call. The planners' matrix-vector products
(sat_node/knowledge.py) are threaded above OpenBLAS's size threshold; spinning after each of them
burns a core a whole run long (and slows the clock a process reads for its own CPU time). The
threads, and how a product is split among them, stay as they are, so every number is the same
(tests/unit/test_blas_threads.py runs a threaded product with and without the variable).
"""

import os

os.environ.setdefault("OPENBLAS_THREAD_TIMEOUT", "4")  # 2^4 cycles, OpenBLAS's least


def __getattr__(name: str):
    """``bringup.__version__``: the project's version, from pyproject.toml in a source checkout or the
    installed distribution's metadata (bringup/scenario/provenance.py version)."""
    if name == "__version__":
        from bringup.scenario.provenance import version

        return version()
    raise AttributeError(f"module 'bringup' has no attribute {name!r}")
