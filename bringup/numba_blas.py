"""numba's BLAS check without importing the whole of scipy.linalg.

The first numba call of a process (a kernel compiled or loaded from numba's cache) initialises
numba's CPU target, which imports ``numba.np.arraymath``; that module checks once that a BLAS is
there (for ``np.dot`` and the like) by ``import scipy.linalg.cython_blas``. Python imports the
package ``scipy.linalg`` first, and with numpy 2 its ``__init__`` walks numpy's namespace through
scipy's array-API layer (numpy.f2py, numpy.testing...): 0.15-0.2 s of CPU for a check that needs
one extension module. :func:`load_cython_blas` loads that module from scipy's folder and registers
it under its own name, so the check finds it in ``sys.modules`` (the same module, the same BLAS
function pointers numba reads) and ``scipy.linalg`` is imported only by code that uses it
(``import scipy.linalg`` later works as before; only the attribute ``scipy.linalg.cython_blas`` is
then missing, and nothing in this project reads it). A short-lived command that calls a numba kernel
and no scipy.linalg (``constellation dtn`` on unicast forwarding) calls it before its first kernel.

When scipy.linalg is already imported, the module already registered, or the file not found where
scipy keeps it, nothing is done and numba's check imports what it always did.

How we know it is right: tests/unit/test_numba_blas.py (in a fresh process: scipy.linalg not
imported by a CGR query after it, numba's BLAS flag set as without it, the module the one scipy
itself loads, and scipy.linalg and scipy.optimize usable afterwards) and the dtn command's outputs
(tests/unit/test_dtn_alone.py, tests/unit/test_dtn_expected.py).
"""

from __future__ import annotations

import importlib.machinery
import importlib.util
import sys
from pathlib import Path

__all__ = ["load_cython_blas"]

_NAME = "scipy.linalg.cython_blas"


def load_cython_blas() -> bool:
    """Register scipy's ``cython_blas`` extension module without its package (module docstring).
    True when it was loaded here."""
    if _NAME in sys.modules or "scipy.linalg" in sys.modules:
        return False
    spec = importlib.util.find_spec("scipy")
    if spec is None or not spec.submodule_search_locations:
        return False
    for folder in spec.submodule_search_locations:
        for suffix in importlib.machinery.EXTENSION_SUFFIXES:
            path = Path(folder) / "linalg" / f"cython_blas{suffix}"
            if path.is_file():
                mod_spec = importlib.util.spec_from_file_location(_NAME, path)
                if mod_spec is None or mod_spec.loader is None:
                    return False
                module = importlib.util.module_from_spec(mod_spec)
                sys.modules[_NAME] = module
                try:
                    mod_spec.loader.exec_module(module)
                except Exception:  # noqa: BLE001 - whatever failed, numba's own import decides
                    del sys.modules[_NAME]
                    return False
                return True
    return False
