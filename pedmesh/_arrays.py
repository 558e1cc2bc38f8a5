"""Arrays handed to the compiled kernels.

numba compiles a kernel once for each combination of argument types it is called with, and
a read-only array is another type than a writable one: a kernel called with a mesh's
(read-only) arrays in one place and with a fresh array in another is compiled twice, the
same machine code (up to half a minute of a first run for the fast-marching kernel). The
kernels that see both take :func:`readonly` views, and compile once
(``benchmarks/compile_time.py``, ``tests/test_kernel_specialisations.py``).
"""

from __future__ import annotations

import numpy as np

__all__ = ["readonly"]


def readonly(a: np.ndarray) -> np.ndarray:
    """A read-only view of ``a`` (``a`` itself stays as it is)."""
    v = a.view()
    v.setflags(write=False)
    return v
