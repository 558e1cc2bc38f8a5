"""Every compiled kernel of pedmesh is cached on disk and lets go of Python's lock while it
runs.

``cache=True``: a second process loads the machine code instead of compiling it again.
``nogil=True``: a run writes its output on a thread of its own
(:mod:`pedmesh.run.background`), and a kernel that holds the lock stops that thread for
as long as it runs. VTK's writer lets go of the lock, so the frames can be written while
the model steps, but only beside kernels that let go of it too: beside a 0.6 s kernel
holding it the writer thread finished none of Example 2's density frames, beside the
same kernel with ``nogil`` 170 (a probe when the continuum's kernels were made so).
"""

from __future__ import annotations

import importlib
import pkgutil

import numba

import pedmesh


def _dispatchers() -> dict[str, numba.core.registry.CPUDispatcher]:
    found = {}
    for info in pkgutil.walk_packages(pedmesh.__path__, "pedmesh."):
        if info.name.endswith("__main__"):
            continue
        for obj in list(vars(importlib.import_module(info.name)).values()):
            if isinstance(obj, numba.core.registry.CPUDispatcher):
                f = obj.py_func
                found[f"{f.__module__}.{f.__name__}"] = obj
    return found


def test_every_kernel_is_cached_and_releases_the_gil():
    kernels = _dispatchers()
    assert len(kernels) > 100  # (the search finds them: 170 when this was written)
    holding = sorted(k for k, d in kernels.items() if not d.targetoptions.get("nogil"))
    uncached = sorted(k for k, d in kernels.items()
                      if type(d._cache).__name__ == "NullCache")
    assert not holding, "kernels that hold the GIL: " + ", ".join(holding)
    assert not uncached, "kernels not cached: " + ", ".join(uncached)
