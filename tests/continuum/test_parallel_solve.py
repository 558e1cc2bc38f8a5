"""The compiled, threaded pieces of a continuum step (issue 35): the conjugate gradients of
the implicit pressure solve against scipy's, the same bits on one and two threads, and the
element-wise kernels against numpy's arithmetic."""

from __future__ import annotations

import numba
import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.linalg import cg

from pedmesh.models.continuum import fv_kernels as K
from pedmesh.models.continuum.implicit import conjugate_gradients

pytestmark = pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2,
                                reason="numba has fewer than 2 threads here")


def _system(n: int, seed: int):
    """A symmetric positive definite system scaled to a unit diagonal, as the implicit
    pressure correction builds it: (|T| + graph Laplacian of a random sparse graph)."""
    rng = np.random.default_rng(seed)
    A = sp.random(n, n, density=3.0 / n, random_state=seed, format="csr")
    A = abs(A) + abs(A).T
    d = np.asarray(A.sum(axis=1)).ravel() + rng.uniform(0.2, 2.0, n)
    s = sp.diags(1.0 / np.sqrt(d))
    M = (s @ (sp.diags(d) - A) @ s).tocsr()
    M.sort_indices()
    return M, rng.standard_normal(n), 0.1 * rng.standard_normal(n)


def _threads(t: int, fn, *args):
    old = numba.get_num_threads()
    numba.set_num_threads(t)
    try:
        return fn(*args)
    finally:
        numba.set_num_threads(old)


@pytest.mark.parametrize("n", [7, 1024, 5000])
def test_conjugate_gradients_solve_as_scipy_does(n):
    M, b, x0 = _system(n, seed=n)
    its = []
    x, it = conjugate_gradients(M.indptr, M.indices.astype(np.int32), M.data, b, x0, 1e-8, 500)
    ref, info = cg(M, b, x0=x0, rtol=1e-8, atol=0.0, maxiter=500,
                   callback=lambda _: its.append(1))
    assert info == 0
    assert np.linalg.norm(M @ x - b) < 1e-8 * np.linalg.norm(b)
    assert np.allclose(x, ref, rtol=0, atol=1e-12 * np.abs(ref).max())
    assert it == len(its)  # the same iterations, the same stopping rule


def test_conjugate_gradients_give_the_same_bits_on_any_thread_count():
    M, b, x0 = _system(20000, seed=3)
    args = (M.indptr, M.indices.astype(np.int32), M.data, b, x0, 1e-6, 500)
    x1, i1 = _threads(1, conjugate_gradients, *args)
    x2, i2 = _threads(2, conjugate_gradients, *args)
    assert i1 == i2 and np.array_equal(x1, x2)


def test_the_step_arithmetic_is_numpy_s():
    rng = np.random.default_rng(0)
    Q, L, S = (rng.standard_normal((3001, 3)) for _ in range(3))
    dt = 0.0731
    for t in (1, 2):
        V = np.empty_like(Q)
        _threads(t, K.stage_update, Q, dt, L, V)
        assert np.array_equal(V, Q + dt * L)
        out = np.empty_like(Q)
        lo, hi, finite = _threads(t, K.heun_combine, Q, S, out)
        ref = 0.5 * Q + 0.5 * S
        assert np.array_equal(out, ref) and finite
        assert (lo, hi) == (ref[:, 0].min(), ref[:, 0].max())
        cp = np.empty_like(Q)
        _threads(t, K.copy_cells, Q, cp)
        assert np.array_equal(cp, Q)
    S[17, 2] = np.nan
    assert not K.heun_combine(Q, S, np.empty_like(Q))[2]
    assert _threads(1, K.fingerprint, Q) == _threads(2, K.fingerprint, Q)
    assert K.fingerprint(Q) == pytest.approx(Q.sum(), rel=1e-12)


def test_the_active_set_grows_by_rings_of_face_neighbours():
    """Cells above eps and their neighbours up to ``rings`` faces away, as a plain
    breadth-first reference finds them; the live edges join two active cells (or one
    active cell and the boundary)."""
    import pedmesh
    from pedmesh.mesh import triangulate

    room = pedmesh.load_room("geometries/pillar_hall.json")
    mesh = triangulate(room, max_area=2.0)
    m = mesh.n_triangles
    rng = np.random.default_rng(1)
    Q = np.zeros((m, 3))
    Q[rng.choice(m, 5, replace=False), 0] = 1.0
    nbr, e2t = mesh.triangle_neighbors, mesh.edge_triangles
    ref = Q[:, 0] > 1e-6
    for _ in range(2):
        grown = ref.copy()
        for i in range(m):
            grown[i] |= any(j >= 0 and ref[j] for j in nbr[i])
        ref = grown
    for t in (1, 2):
        cact = np.zeros(m, np.bool_)
        live = np.zeros(len(e2t), np.bool_)
        n = _threads(t, K.active_set, Q, nbr, e2t, 1e-6, 2, cact, live)
        assert n == ref.sum() and np.array_equal(cact, ref)
        assert np.array_equal(live, ref[e2t[:, 0]] & ((e2t[:, 1] < 0) | ref[e2t[:, 1]]))


def test_short_edge_loops_reach_every_chunk():
    """The wall and exit edge loops (a room's hundred exit edges, a few thousand walls) are
    cut into blocks of at most 1/NCHUNK of the edges (rounded up), so that the chunks of
    the parallel loop share them, and the blocks cover every edge once (with BLOCK-sized
    blocks, 103 exit edges were one block, all on one thread)."""
    from pedmesh.models.continuum.fv_kernels import BLOCK, NCHUNK, short_block

    for n in (1, 5, 16, 17, 103, 3080, 8192, 100_000):
        bs = short_block(n)
        assert 1 <= bs <= BLOCK
        blocks = -(-n // bs)
        assert blocks * bs >= n > (blocks - 1) * bs
        assert bs <= -(-n // NCHUNK) or bs == BLOCK
        assert blocks >= min(n, NCHUNK // 2)
