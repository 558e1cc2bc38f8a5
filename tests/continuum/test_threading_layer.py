"""numba's TBB threading layer is really used where the ``tbb`` package is installed
(pedmesh._threads loads oneTBB by its path before the first parallel loop, so a fresh
virtual environment needs no LD_LIBRARY_PATH), and a layer that is not TBB is said, with
what it costs."""

from __future__ import annotations

import subprocess
import sys

import pytest

from pedmesh._threads import tbb_library


def _layer_in_a_fresh_process(env_extra: str = "") -> str:
    code = ("import numpy as np\n"
            "from pedmesh.models.continuum.solver import threading_layer\n"
            "print(threading_layer())\n")
    r = subprocess.run([sys.executable, "-c", env_extra + code], capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    return r.stdout.strip().splitlines()[-1]


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="TBB wheels: Linux x86-64")
def test_the_layer_is_tbb_where_the_tbb_package_is_installed():
    try:
        from importlib.metadata import distribution

        distribution("tbb")
    except Exception:
        pytest.skip("the tbb package is not installed here")
    assert tbb_library() is not None, "the tbb package's libtbb.so.12 was not found"
    assert _layer_in_a_fresh_process() == "tbb"


def test_a_layer_that_is_not_tbb_is_explained(monkeypatch):
    from pedmesh.models.continuum import solver

    monkeypatch.setattr(solver, "threading_layer", lambda: "omp")
    note = solver.threading_note()
    assert "'omp' threading layer, not TBB" in note and "pip install tbb" in note


def test_version_names_the_threading_layer():
    r = subprocess.run([sys.executable, "-m", "pedmesh", "--version"], capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 0
    assert r.stdout.startswith("pedmesh ") and "threading layer" in r.stdout
