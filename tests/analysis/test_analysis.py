"""Analysis functions against hand-computed cases, and the comparison pipeline."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pedmesh import Exit, Room, StartArea
from pedmesh.analysis import (
    PAPER_BINS,
    continuum_outflow,
    crossing_rate,
    curve_distance,
    density_flow_diagram,
    density_l1,
    evacuation_curve,
    evacuation_times,
    kernel_density,
    kernel_velocity,
    exit_gauss_points,
    particle_outflow,
    reference_flow,
)
from pedmesh.mesh import triangulate


def test_single_pedestrian_density_integrates_to_one():
    g = np.arange(-3.0, 3.0, 0.01) + 0.005
    X, Y = np.meshgrid(g, g, indexing="ij")
    pts = np.column_stack([X.ravel(), Y.ravel()])
    rho = kernel_density(positions=np.array([[0.02, -0.01]]), points=pts, R=0.7)
    total = rho.sum() * 0.01**2
    assert total == pytest.approx(1.0 - math.exp(-9.0), abs=1e-4)  # cut at 3 R
    assert rho.max() == pytest.approx(1 / (math.pi * 0.49), rel=1e-3)


def test_kernel_velocity_is_a_weighted_mean():
    pos = np.array([[0.0, 0.0], [1.0, 0.0]])
    vel = np.array([[1.0, 0.0], [0.0, 2.0]])
    u = kernel_velocity(positions=pos, velocities=vel, points=np.array([[0.5, 0.0], [0.0, 0.0]]))
    np.testing.assert_allclose(u[0], [0.5, 1.0])
    w = math.exp(-1 / 0.49)
    np.testing.assert_allclose(u[1], [1 / (1 + w), 2 * w / (1 + w)])
    assert np.all(kernel_velocity(positions=pos, velocities=vel,
                                  points=np.array([[9.0, 9.0]])) == 0)


@pytest.fixture(scope="module")
def door_mesh():
    room = Room([(0, 0), (10, 0), (10, 8), (0, 8)], exits=[Exit("door", [(10, 2), (10, 6)])])
    return triangulate(room, max_area=0.2)


def test_uniform_stream_outflow_continuum(door_mesh):
    m = door_mesh.n_triangles
    f = continuum_outflow(mesh=door_mesh, rho=np.full(m, 2.0), velocity=np.tile([1.0, 0.3], (m, 1)))
    assert f[0] == pytest.approx(2.0 * 1.0 * 4.0, rel=1e-12)  # rho u.n w


def test_uniform_stream_outflow_particles(door_mesh):
    # a square lattice (2 ped/m^2) moving at 1 m/s across the door, extended beyond it so
    # that the kernel fields are uniform there
    s = 1 / math.sqrt(2.0)
    g = np.arange(-10, 25, s)
    X, Y = np.meshgrid(g, g, indexing="ij")
    pos = np.column_stack([X.ravel(), Y.ravel()])
    vel = np.tile([1.0, 0.0], (len(pos), 1))
    f = particle_outflow(mesh=door_mesh, positions=pos, velocities=vel)
    assert f[0] == pytest.approx(8.0, rel=1e-3)
    # the plain crossing rate of a steady stream: one pedestrian every 0.125 s
    times = np.arange(0, 100, 0.125)
    r = crossing_rate(exit_times=times, t=np.array([20.0, 50.0]), window=4.0)
    np.testing.assert_allclose(r, 8.0)


def test_outflow_of_several_exits_is_each_exits_own():
    """particle_outflow measures all exits in one neighbour search: each exit's flow is,
    to the bit, the kernel density and kernel velocity at that exit's own Gauss points
    (their neighbours and their order are those of a search of those points alone), and
    ``n_exits`` keeps the first exits only."""
    exits = [Exit("east", [(10, 2), (10, 6)]), Exit("north", [(3, 8), (1, 8)]),
             Exit("south", [(4, 0), (7, 0)])]
    mesh = triangulate(Room([(0, 0), (10, 0), (10, 8), (0, 8)], exits=exits), max_area=0.2)
    rng = np.random.default_rng(4)
    pos = rng.uniform((0.2, 0.2), (9.8, 7.8), (400, 2))
    vel = rng.normal(0.0, 1.0, (400, 2))
    f = particle_outflow(mesh=mesh, positions=pos, velocities=vel)
    assert np.all(f != 0.0)
    for k in range(len(exits)):
        pts, w, n, _ = exit_gauss_points(mesh=mesh, exit=k)
        rho = kernel_density(positions=pos, points=pts)
        u = kernel_velocity(positions=pos, velocities=vel, points=pts)
        assert np.sum(w * rho * np.einsum("ij,ij->i", u, n)) == f[k]
    np.testing.assert_array_equal(
        particle_outflow(mesh=mesh, positions=pos, velocities=vel, n_exits=2), f[:2])


@pytest.mark.parametrize("spread", [0.3, 3.0, 30.0])
def test_kernel_pairs_are_those_of_the_whole_crowd(spread):
    """The kernel fields' neighbour pairs (only the pedestrians near the query points go
    into the search tree) are exactly those of a tree of the whole crowd, in its order:
    by point, then by pedestrian."""
    from scipy.spatial import cKDTree

    from pedmesh.analysis.fields import _pairs

    rng = np.random.default_rng(7)
    pos = rng.random((3000, 2)) * 40.0
    for pts in (np.array([[20.0, 20.0]]), 20.0 + spread * rng.random((12, 2)),
                np.array([[-50.0, -50.0]])):
        row, col, d = _pairs(pos, pts, 1.8)
        lists = cKDTree(pos).query_ball_point(pts, 1.8)
        want_col = np.concatenate([np.full(len(li), k) for k, li in enumerate(lists)])
        want_row = np.concatenate([np.asarray(li, np.int64) for li in lists])
        np.testing.assert_array_equal(row, want_row)
        np.testing.assert_array_equal(col, want_col)
        np.testing.assert_array_equal(d, np.hypot(*(pos[want_row] - pts[want_col]).T))


def test_binning_puts_points_in_the_right_bins():
    d = np.array([0.01, 0.04, 0.05, 10.48, 11.0, -0.1])
    f = np.array([1.0, 2.0, 4.0, 5.0, 9.0, 9.0])
    fd = density_flow_diagram(density=d, flow=f)
    assert len(fd.centers) == len(PAPER_BINS) - 1 == 350
    assert fd.counts[0] == 1 and fd.mean_flow[0] == 1.0
    assert fd.counts[1] == 2 and fd.mean_flow[1] == 3.0  # 0.03 <= d < 0.06
    assert fd.counts[-1] == 1 and fd.mean_flow[-1] == 5.0  # 10.47 <= d < 10.50
    assert fd.counts.sum() == 4  # 11.0 and -0.1 are outside the bins
    assert np.isnan(fd.mean_flow[2])
    assert reference_flow(density=np.array([20.0]))[0] == pytest.approx(20 * 1.034 / math.e)


def test_evacuation_curve_and_distances(door_mesh):
    et = np.array([1.0, 2.0, 2.0, np.nan])
    np.testing.assert_array_equal(evacuation_curve(exit_times=et, t=np.array([0.5, 1.0, 2.0, 9.0])),
                                  [0, 1, 3, 3])
    assert evacuation_times(et, 4) == [2.0, None, None]
    assert evacuation_times(et, 3) == [2.0, 2.0, 2.0]
    # N1 rises 0 -> 4 on [0, 10] s, N2 the same on [10, 20] s: |N1 - N2| averages 2 = N/2
    t = np.array([0.0, 10.0, 20.0])
    d = curve_distance(t1=t, n1=np.array([0.0, 4.0, 4.0]), t2=t, n2=np.array([0.0, 0.0, 4.0]),
                       n_total=4.0, dt=0.01)
    assert d == pytest.approx(0.5, rel=1e-3)
    m = door_mesh.n_triangles
    assert density_l1(mesh=door_mesh, rho1=np.ones(m), rho2=np.zeros(m)) == pytest.approx(80.0)


def test_compare_pipeline_small_room(tmp_path, capsys):
    import json

    from pedmesh import save_room
    from pedmesh.cli import main

    room = Room([(0, 0), (8, 0), (8, 5), (0, 5)], exits=[Exit("door", [(8, 2), (8, 3)])],
                start_areas=[StartArea("crowd", [(0.5, 0.5), (4.5, 0.5), (4.5, 4.5), (0.5, 4.5)],
                                       spacing=0.8)])
    geo = save_room(room, tmp_path / "small.json")
    out = tmp_path / "cmp"
    args = ["compare", str(geo), "--models", "sfm,rdue,pw:c0=0.8,mac1,eos", "--max-area", "0.4",
            "--out", str(out), "-q"]
    assert main(args) == 0
    for name in ("evacuation.png", "outflow.png", "fundamental.png", "density.png",
                 "comparison.csv", "comparison.md"):
        assert (out / name).exists(), name
    rows = (out / "comparison.csv").read_text().splitlines()
    assert rows[0].startswith("label,model,t_evac_50") and len(rows) == 6
    s = {lab: json.loads((out / lab / "summary.json").read_text())
         for lab in ("sfm", "rdue", "pw_c00.8", "mac1", "eos")}
    assert all(v["status"] == "finished" for v in s.values())
    assert s["pw_c00.8"]["parameters"]["c0"] == 0.8
    assert s["eos"]["exit_condition"] == "godunov"
    # resumable: a second call reuses every finished run
    capsys.readouterr()
    assert main(args[:-1]) == 0
    assert capsys.readouterr().err.count("reusing the finished run") == 5
