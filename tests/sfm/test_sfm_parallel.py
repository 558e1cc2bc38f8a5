"""The social force model's kernels on threads give the serial kernels' results bit for bit
(tests/sfm/serial_kernels.py, the loops before they ran on threads), for any number of
blocks of cells (one per thread), and a run writes the same exits.csv and trajectories.txt
on 1 and on 2 threads."""

from __future__ import annotations

import json

import numba
import numpy as np
import pytest

import serial_kernels as S  # (tests/sfm/serial_kernels.py)
from pedmesh.cli import main
from pedmesh.models.sfm import kernels as K
from pedmesh.models.sfm import simulation as sim_module
from pedmesh.models.sfm.params import SFMNumerics

two_threads = pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2,
                                 reason="numba has fewer than 2 threads here")

ROOM = {
    "format": "pedmesh-room", "version": 1, "name": "two_doors", "units": "m",
    "outline": [[0.0, 0.0], [24.0, 0.0], [24.0, 12.0], [0.0, 12.0]],
    "obstacles": [{"name": "pillar",
                   "polygon": [[4.0, 5.0], [6.0, 5.0], [6.0, 7.0], [4.0, 7.0]]}],
    "exits": [{"name": "east", "polyline": [[24.0, 4.5], [24.0, 6.0]]},
              {"name": "north", "polyline": [[19.0, 12.0], [20.5, 12.0]]}],
    "start_areas": [{"name": "crowd", "polygon": [[9.0, 0.5], [23.5, 0.5], [23.5, 11.5],
                                                   [9.0, 11.5]], "spacing": 0.55}],
}


def _bits(a) -> np.ndarray:
    a = np.ascontiguousarray(a)
    return a.view(np.uint8) if a.dtype.kind == "f" else a


def _same(a, b) -> bool:
    return np.array_equal(_bits(a), _bits(b))


def _crowd(seed: int, n: int = 900):
    """A crowd with dense clumps and gaps on a 30 x 18 m grid of 2.1 m cells."""
    rng = np.random.default_rng(seed)
    centres = rng.uniform([2, 2], [28, 16], (6, 2))
    x = centres[rng.integers(0, 6, n)] + rng.normal(0, 1.6, (n, 2))
    x = np.clip(x, 0.05, [29.95, 17.95])
    v = rng.normal(0, 0.7, (n, 2))
    rad = rng.uniform(0.2, 0.3, n)
    e = rng.normal(0, 1, (n, 2))
    e /= np.hypot(*e.T)[:, None]
    cell = 2.1
    nx, ny = int(30 / cell) + 1, int(18 / cell) + 1
    start = np.zeros(nx * ny + 1, np.int64)
    order = np.zeros(n, np.int64)
    S.build_cells(x, n, 0.0, 0.0, 1.0 / cell, nx, ny, start, order)
    return x, v, rad, e, nx, ny, start, order


#: the density cones the parallel kernels are checked with: none, and Example p = 2
CONES = [np.array([0.0, 1.0]), np.array([2.0, 4.0])]


@pytest.mark.parametrize("cone", CONES, ids=["isotropic", "cone2"])
@pytest.mark.parametrize("with_density", [True, False])
@pytest.mark.parametrize("seed", [0, 1])
def test_cells_and_pair_list_are_the_serial_ones(seed, with_density, cone):
    x, v, rad, e, nx, ny, start, order = _crowd(seed)
    n = len(x)
    start2, order2 = np.zeros_like(start), np.zeros_like(order)
    K.build_cells(x, n, 0.0, 0.0, 1.0 / 2.1, nx, ny, start2, order2)
    assert _same(start, start2) and _same(order, order2)
    rc, rc_near = (1.4, 1.4) if with_density else (2.1, 1.4)
    cap = 100 * n  # (each block gets cap / blocks of it)
    pi0, pj0, rho0 = np.full(cap, -1), np.full(cap, -1), np.zeros(n)
    m0 = S.build_pairs(x, n, start, order, nx, ny, rc, rc_near, pi0, pj0, rho0, 2.1, 0.7,
                       with_density, e, cone)
    assert m0[0] > 0 and (m0[1] > 0) != with_density
    for nblocks in (1, 2, 3, 5, 8):
        lay, pos = K.pair_blocks(n, start, order, nx, ny, nblocks)
        pi, pj, rho = np.full(cap, -1), np.full(cap, -1), np.zeros(n)
        m = K.list_pairs(x, n, start, order, nx, ny, rc, rc_near, pi, pj, rho, 2.1, 0.7,
                         with_density, lay, pos, e, cone)
        assert m == m0, nblocks
        near, far = slice(0, m[0]), slice(cap - m[1], cap)
        for a, b in ((pi, pi0), (pj, pj0)):
            assert _same(a[near], b[near]) and _same(a[far], b[far]), nblocks
        if with_density:
            assert _same(rho, rho0), nblocks
        if nblocks > 1:  # the halos and the blocks' first pairs mark real places
            assert np.all(np.diff(lay[:, 1]) >= 0) and np.all(lay[:-1, 3] <= lay[:-1, 1])
    # a list too long for pi/pj, or for a block's share of them: -1 (the caller enlarges)
    for size, nblocks in ((m0[0] + m0[1] - 1, 1), (m0[0] + m0[1] + 1, 8)):
        lay, pos = K.pair_blocks(n, start, order, nx, ny, nblocks)
        assert K.list_pairs(x, n, start, order, nx, ny, rc, rc_near, np.empty(size, np.int64),
                            np.empty(size, np.int64), np.zeros(n), 2.1, 0.7, with_density,
                            lay, pos, e, cone) == (-1, -1)


def _work(start, nx, ny):
    """The distances the half-stencil search tests per cell (counted here with numpy)."""
    m = np.diff(start).reshape(nx, ny)
    pad = np.pad(m, 1)
    near = pad[2:, :-2] + pad[2:, 1:-1] + pad[2:, 2:] + pad[1:-1, 2:]
    return np.where(m > 0, m * (m - 1) // 2 + m * near + m, 0).ravel()


def test_blocks_share_the_work():
    """A crowd packed in one corner and sparse elsewhere: cut by head count, the block
    holding the packed cells would get most of the distances to test; the blocks are cut by
    those distances instead (where the running sum of the cells' work reaches each block's
    share), so each gets its share up to one cell's work."""
    rng = np.random.default_rng(5)
    n = 1500
    x = np.concatenate([rng.uniform([0.1, 0.1], [4.0, 4.0], (1000, 2)),
                        rng.uniform([4.0, 0.1], [29.9, 17.9], (n - 1000, 2))])
    cell = 2.1
    nx, ny = int(30 / cell) + 1, int(18 / cell) + 1
    start, order = np.zeros(nx * ny + 1, np.int64), np.zeros(n, np.int64)
    K.build_cells(x, n, 0.0, 0.0, 1.0 / cell, nx, ny, start, order)
    work = _work(start, nx, ny)
    before = np.concatenate([[0], np.cumsum(work)])  # the work before each cell
    for nblocks in (2, 3, 4, 7):
        lay, pos = K.pair_blocks(n, start, order, nx, ny, nblocks)
        cuts = lay[:, 0]
        assert cuts[0] == 0 and cuts[-1] == nx * ny and np.all(np.diff(cuts) >= 0)
        # block b starts at the first cell with at least b / nblocks of the work before it
        for b in range(1, nblocks):
            assert cuts[b] == np.argmax(before * nblocks >= b * work.sum()), (nblocks, b)
        np.testing.assert_array_equal(pos[order], np.arange(n))  # each one's place
        share = np.array([work[cuts[b]:cuts[b + 1]].sum() for b in range(nblocks)])
        assert share.max() <= work.sum() / nblocks + work.max(), (nblocks, share)
        # cut by head count, one block would have had far more than its share
        by_heads = np.searchsorted(start, np.arange(nblocks + 1) * n // nblocks)
        by_heads[-1] = nx * ny
        old = np.array([work[by_heads[b]:by_heads[b + 1]].sum() for b in range(nblocks)])
        assert old.max() > 1.3 * work.sum() / nblocks, (nblocks, old)


def test_everyone_in_one_cell():
    """All in one cell: the other blocks are empty, and the list and densities are still
    the serial ones."""
    rng = np.random.default_rng(6)
    n = 60
    x = rng.uniform([10.2, 6.4], [12.5, 8.3], (n, 2))
    nx, ny = 15, 9
    start, order = np.zeros(nx * ny + 1, np.int64), np.zeros(n, np.int64)
    S.build_cells(x, n, 0.0, 0.0, 1.0 / 2.1, nx, ny, start, order)
    assert np.count_nonzero(np.diff(start)) <= 4
    cap = 1000 * n  # (one block holds every pair: its share of pi/pj must take them)
    pi0, pj0, rho0 = np.full(cap, -1), np.full(cap, -1), np.zeros(n)
    e = np.zeros((n, 2))
    cone = CONES[0]
    m0 = S.build_pairs(x, n, start, order, nx, ny, 1.4, 1.4, pi0, pj0, rho0, 2.1, 0.7, True,
                       e, cone)
    for nblocks in (2, 4, 8):
        lay, pos = K.pair_blocks(n, start, order, nx, ny, nblocks)
        pi, pj, rho = np.full(cap, -1), np.full(cap, -1), np.zeros(n)
        m = K.list_pairs(x, n, start, order, nx, ny, 1.4, 1.4, pi, pj, rho, 2.1, 0.7, True,
                         lay, pos, e, cone)
        assert m == m0 and _same(pi[:m[0]], pi0[:m0[0]]) and _same(rho, rho0), nblocks


@pytest.mark.parametrize("cone", CONES, ids=["isotropic", "cone2"])
@pytest.mark.parametrize("lam", [1.0, 0.4])
@pytest.mark.parametrize("with_density", [True, False])
def test_pair_forces_are_the_serial_ones(lam, with_density, cone):
    """F from 0 and rho from the self term, then every pair's terms in list order: near
    pairs from the front, the far ones (density only) from the back; with the field of
    vision the terms of i and j differ."""
    x, v, rad, e, nx, ny, start, order = _crowd(2)
    n = len(x)
    rs = rad - 0.03
    cap = 100 * n
    pi, pj = np.full(cap, -1), np.full(cap, -1)
    nn, nf = S.build_pairs(x, n, start, order, nx, ny, 2.1, 1.4, pi, pj, np.zeros(n), 2.1,
                           0.7, False, e, cone)
    args = (1.2, 2.1, rad, 2000.0, 0.08, 1.2e5, 2.4e5, 80.0, 0.7)
    F0, rho0 = np.full((n, 2), np.nan), np.full(n, 7.0)
    S.pair_accel_list(x, v, n, pi, pj, nn, nf, *args, F0, rho0, with_density, rs, lam, e,
                      cone)
    assert np.abs(F0).max() > 1.0
    F1, rho1 = np.full((n, 2), np.nan), np.full(n, 7.0)
    K.pair_accel_list(x, v, n, pi, pj, nn, nf, *args, F1, rho1, with_density, rs, lam, e,
                      cone)
    assert _same(F1, F0) and _same(rho1, rho0)
    for nblocks in (2, 3, 5, 8):
        lay, pos = K.pair_blocks(n, start, order, nx, ny, nblocks)
        pi2, pj2 = np.full(cap, -1), np.full(cap, -1)
        assert K.list_pairs(x, n, start, order, nx, ny, 2.1, 1.4, pi2, pj2, np.zeros(n), 2.1,
                            0.7, False, lay, pos, e, cone) == (nn, nf)
        F2, rho2 = np.full((n, 2), np.nan), np.full(n, 7.0)
        K.pair_accel_blocks(x, v, n, pi2, pj2, nn, nf, lay, pos, start, *args, F2, rho2,
                            with_density, rs, lam, e, cone)
        assert _same(F2, F0) and _same(rho2, rho0), nblocks


def _room(tmp_path):
    path = tmp_path / "two_doors.json"
    path.write_text(json.dumps(ROOM))
    return path


def test_steps_are_the_serial_ones(tmp_path, monkeypatch):
    """Whole steps (Runge-Kutta stages, walls, routes, settle) with the parallel kernels on
    2 threads and with the serial kernels give the same states, bit for bit, with the
    validated preset's dense-crowd terms, a field of vision, a density cone and weaker walls."""
    import pedmesh

    def run(threads):
        sim = pedmesh.build(_room(tmp_path), model="sfm", preset="validated",
                            params={"vision": 0.5, "threads": threads, "density_cone": 2.0,
                                    "wall_repulsion": 0.3, "exit_ghosts": 0}).sim
        assert sim.n_initial > 300
        for _ in range(150):
            sim.step()
        return sim

    new = run(2)
    for name in ("build_cells", "settle", "density_at", "first_bad"):
        monkeypatch.setattr(K, name, getattr(S, name))
    # (the serial kernels take neither the pairs over a building's stair edges, none in a
    # room, nor the people beyond the exits (off here: their kernels run on one thread in
    # any case), nor the blocks, nor whether a building's step built the cell list first)
    monkeypatch.setattr(K, "rk3_step", lambda *args: S.rk3_step(*args[:-5]))
    ref = run(1)
    assert ref.n < ref.n_initial  # some left: the exits worked
    for name in ("x", "v", "rho", "tri", "ids", "exit_time", "exit_id", "_e"):
        assert _same(getattr(new, name), getattr(ref, name)), name


@two_threads
def test_run_files_are_the_same_on_one_and_two_threads(tmp_path, background_writers):
    """Every file of the run but the summary (its wall times), byte for byte; on 2 threads
    the output is written by the background writer (pedmesh.run.background)."""
    made = background_writers
    room = _room(tmp_path)
    files = {}
    for threads in (1, 2):
        out = tmp_path / f"t{threads}"
        assert main(["run", str(room), "--model", "sfm", "--preset", "validated", "--param",
                     f"threads={threads}", "--t-end", "12", "--out", str(out), "-q"]) == 0
        summary = json.loads((out / "summary.json").read_text())
        assert summary["parameters"]["threads"] == threads
        assert len(made) == threads - 1  # (in the background on 2 threads only)
        files[threads] = {str(f.relative_to(out)): f.read_bytes() for f in out.rglob("*")
                          if f.is_file() and f.name not in ("summary.json", ".lock")}
    assert {"exits.csv", "trajectories.txt", "trajectories.sqlite", "outflow_kernel.csv",
            "density.pvd", "pedestrians.pvd"} <= set(files[1])
    assert files[1]["exits.csv"].count(b"\n") > 10  # people left through the doors
    assert files[1] == files[2]


def test_threads_parameter_and_the_crowd_threshold(monkeypatch):
    """``threads`` N: N threads (at most numba's); None: one thread below the crowd size
    where threads pay, numba's count above."""
    sim = sim_module.Simulation.__new__(sim_module.Simulation)
    sim.numerics = SFMNumerics(threads=1)
    assert sim.threads_for(10**6) == 1
    sim.numerics = SFMNumerics(threads=10**3)
    assert sim.threads_for(1) == numba.config.NUMBA_NUM_THREADS
    sim.numerics = SFMNumerics()
    assert sim.threads_for(10) == 1
    assert sim.threads_for(10**6) == numba.get_num_threads()
