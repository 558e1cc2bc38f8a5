"""The finite-volume kernels run on all cores (numba prange): every parallel loop writes
only its own cell or edge and gathers a cell's edge terms in a fixed order, so a run must be
bitwise the same with 1 and 2 threads, conserve mass to round-off and keep rho >= 0."""

from __future__ import annotations

import numba
import numpy as np
import pytest

import pedmesh
from pedmesh.models import get_model
from pedmesh.mesh import triangulate

pytestmark = pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2,
                                reason="numba has fewer than 2 threads here")

MODELS = ["eos", "pw", "rdue", "mac1", "mac2-nonlocal-friction", "mac2-local"]


@pytest.fixture(scope="module")
def hall():
    room = pedmesh.load_room("geometries/pillar_hall.json")
    return room, triangulate(room, max_area=2.0)


def _run(room, mesh, name, threads, steps=12):
    factory = get_model(name).build
    run = factory(room, mesh, {"threads": threads})  # (this small mesh would get 1 thread)
    assert run.solver.threads == threads
    n0 = run.n_initial
    out = []
    for _ in range(steps):
        run.step()
        out.append(run.state.Q.copy())
    return run, n0, out


@pytest.mark.parametrize("name", MODELS)
def test_one_and_two_threads_give_the_same_bits(hall, name):
    room, mesh = hall
    _, _, one = _run(room, mesh, name, 1)
    run, n0, two = _run(room, mesh, name, 2)
    for a, b in zip(one, two):
        np.testing.assert_array_equal(a, b)
    # and in parallel the scheme keeps its invariants: rho >= 0 everywhere, and the people
    # inside plus those out equal the initial crowd to round-off
    assert two[-1][:, 0].min() >= 0.0
    assert run.controller.mass_error < 1e-12
    assert run.evacuated + run.remaining == pytest.approx(n0, rel=1e-12)


def test_thread_policy(hall, monkeypatch):
    """One thread below the threshold of the threading layer (PARALLEL_MIN_CELLS under
    OpenMP, whose spinning threads cost a large loss on a busy machine, the smaller
    PARALLEL_MIN_CELLS_TBB under TBB), numba's thread count above; an explicit count is
    taken as given; the caller's numba thread setting is restored after each step."""
    from pedmesh.errors import ParameterError
    from pedmesh.models.continuum import solver as S
    from pedmesh.models.continuum.solver import FVOptions, _threads

    room, mesh = hall
    assert S.threading_layer() in ("tbb", "omp", "workqueue")
    assert S.PARALLEL_MIN_CELLS_TBB < S.PARALLEL_MIN_CELLS
    most = numba.get_num_threads()
    for layer, limit in (("omp", S.PARALLEL_MIN_CELLS), ("tbb", S.PARALLEL_MIN_CELLS_TBB)):
        monkeypatch.setattr(S, "threading_layer", lambda layer=layer: layer)
        assert S.parallel_min_cells() == limit
        assert _threads(None, limit - 1) == 1
        assert _threads(None, limit) == most
    monkeypatch.undo()
    assert mesh.n_triangles < S.parallel_min_cells()
    assert _threads(None, mesh.n_triangles) == 1
    assert _threads(1, 10**6) == 1
    factory = get_model("eos").build
    run = factory(room, mesh, {"threads": 2})
    before = numba.get_num_threads()
    run.step()
    assert numba.get_num_threads() == before
    for bad in (0, 1.5, -2, True):
        with pytest.raises(ParameterError, match="threads"):
            FVOptions(threads=bad)
