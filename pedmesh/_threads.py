"""Load Intel oneTBB for numba's threading layer when the ``tbb`` package is installed.

The ``tbb`` wheel puts ``libtbb.so.12`` into ``<sys.prefix>/lib``. In a virtual
environment the dynamic loader does not search that folder, so numba cannot load its TBB
layer and falls back to OpenMP (whose waiting threads spin: two runs at once slow each
other down many times). Loading the library by its path, globally, before numba's first
parallel loop lets numba find it without ``LD_LIBRARY_PATH``. :func:`ensure_tbb` does that
once; the modules with parallel kernels call it when they are imported.
"""

from __future__ import annotations

import ctypes
import os
import sys
from pathlib import Path

__all__ = ["ensure_tbb", "tbb_library", "tbb_load_status"]

_STATE: dict[str, object] = {}


def tbb_library() -> Path | None:
    """The oneTBB library of the ``tbb`` package in this environment, or None."""
    if not sys.platform.startswith("linux"):
        return None
    for prefix in dict.fromkeys((sys.prefix, sys.base_prefix)):
        for name in ("libtbb.so.12", "libtbb.so"):
            p = Path(prefix) / "lib" / name
            if p.is_file():
                return p
    return None


def ensure_tbb() -> str:
    """Load the environment's oneTBB (once) so that numba's TBB layer can start; returns
    what happened: ``'loaded'``, ``'absent'`` (no ``tbb`` package library here) or
    ``'failed: <reason>'``. ``PEDMESH_NO_TBB=1`` skips it."""
    if "status" in _STATE:
        return str(_STATE["status"])
    status = "absent"
    lib = None if os.environ.get("PEDMESH_NO_TBB") == "1" else tbb_library()
    if lib is not None:
        try:
            ctypes.CDLL(str(lib), mode=ctypes.RTLD_GLOBAL)
            status = "loaded"
        except OSError as exc:
            status = f"failed: {exc}"
    _STATE["status"] = status
    return status


def tbb_load_status() -> str:
    """What :func:`ensure_tbb` did (it runs now if it has not yet)."""
    return ensure_tbb()
