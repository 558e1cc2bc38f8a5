"""The social force model's door physics (issue 44): the density cone of the desired speed,
the walls' social repulsion, the route's clearance from walls; the merged walls and sorted
rows of a run on its own route mesh."""

from __future__ import annotations

import math

import numpy as np
import pytest

import pedmesh
from pedmesh import Exit, Room, StartArea
from pedmesh.mesh import triangulate
from pedmesh.mesh.route_mesh import route_mesh
from pedmesh.models.sfm import kernels as K
from pedmesh.models.sfm.forces import NO_CONE, cone_norm
from pedmesh.models.sfm.walls import ROUTE_WALL_COST, WallSet, clearance_factor


@pytest.mark.parametrize("p", [0.5, 1.0, 2.0, 4.0])
def test_cone_norm_makes_a_uniform_crowd_read_its_density(p):
    """norm x mean over all directions of max(0, cos)^p is 1 (pi for p = 1, 4 for p = 2)."""
    th = np.linspace(0.0, 2.0 * math.pi, 200_001)[:-1]
    assert cone_norm(p) * np.mean(np.maximum(np.cos(th), 0.0) ** p) == pytest.approx(1.0,
                                                                                    rel=1e-6)
    assert cone_norm(1.0) == pytest.approx(math.pi) and cone_norm(2.0) == pytest.approx(4.0)


def _densities(x, e, cone):
    n = len(x)
    cell = 2.1
    lo = x.min(axis=0) - cell
    nx, ny = (np.ptp(x, axis=0) / cell).astype(int) + 3
    start, order = np.zeros(nx * ny + 1, np.int64), np.zeros(n, np.int64)
    K.build_cells(x - lo, n, 0.0, 0.0, 1.0 / cell, nx, ny, start, order)
    pi, pj, rho = np.empty(200 * n, np.int64), np.empty(200 * n, np.int64), np.zeros(n)
    K.build_pairs(x - lo, n, start, order, nx, ny, 1.4, 1.4, pi, pj, rho, 2.1, 0.7, True, e,
                  cone)
    return rho


def test_the_cone_reads_the_people_ahead():
    """In a large hexagonal crowd everyone facing +x, the cone density of those inside is the
    isotropic one (within 3 %); the front row reads hardly more than its own share, the back
    row the whole crowd ahead; with the cone off the two ends read alike."""
    a = 0.6
    g = [(i * a + (j % 2) * a / 2, j * a * math.sqrt(3) / 2) for i in range(30) for j in range(30)]
    x = np.array(g, float)
    e = np.tile([1.0, 0.0], (len(x), 1))
    iso = _densities(x, e, NO_CONE)
    cone = _densities(x, e, np.array([2.0, 4.0]))
    inner = np.all((x > x.min(axis=0) + 3) & (x < x.max(axis=0) - 3), axis=1)
    assert np.allclose(cone[inner], iso[inner], rtol=0.03)
    front = x[:, 0] > x[:, 0].max() - 0.01
    back = x[:, 0] < x[:, 0].min() + 0.01
    mid = (np.abs(x[:, 1] - np.median(x[:, 1])) < 3)
    w0 = 1.0 / (math.pi * 0.7 ** 2)
    assert np.all(cone[front & mid] < 0.5 * iso[front & mid])
    assert np.all(cone[front & mid] >= w0 * (1 - 1e-12))
    assert np.all(cone[back & mid] > 1.5 * iso[back & mid])
    assert np.allclose(iso[front & mid], iso[back & mid], rtol=0.02)


def test_walls_push_only_on_contact_without_their_social_repulsion():
    """wall_repulsion scales the walls' social term: at 0.2 m from a wall (no contact, r =
    0.15 m) the wall force is A exp((r - d)/B)/m with 1 and nothing with 0; in contact the
    body force is the same."""
    room = Room([(0, 0), (10, 0), (10, 4), (0, 4)], exits=[Exit("e", [(10, 1), (10, 3)])])
    mesh = triangulate(room, max_area=1.0)
    out = {}
    for w in (1.0, 0.0):
        for d in (0.2, 0.1):
            sim = pedmesh.models.sfm.Simulation(
                mesh, np.array([[5.0, d]]), params=pedmesh.models.sfm.SocialForceParams(
                    wall_repulsion=w), desired_velocity=np.array([1e-9, 0.0]),
                numerics=pedmesh.models.sfm.SFMNumerics(dt=1e-4))
            sim.step()
            out[(w, d)] = sim._F[0, 1]
    p = pedmesh.models.sfm.SocialForceParams()
    assert out[(1.0, 0.2)] == pytest.approx(p.A * math.exp((p.r - 0.2) / p.B) / p.m, rel=0.02)
    assert abs(out[(0.0, 0.2)]) < 1e-6
    body = p.k * (p.r - 0.1) / p.m
    assert out[(0.0, 0.1)] == pytest.approx(body, rel=0.05)
    assert out[(1.0, 0.1)] > out[(0.0, 0.1)]


def test_clearance_factor_and_a_route_through_the_middle_of_a_door():
    """The route cost's factor is 4 on a wall and 1 from route_clearance on; with the
    clearance a pedestrian beside a door heads for its middle, without it for the jamb."""
    room = Room([(0, 0), (8, 0), (8, 5), (5, 5), (5, 5.2), (8, 5.2), (8, 9), (0, 9), (0, 5.2),
                 (3, 5.2), (3, 5), (0, 5)], exits=[Exit("out", [(8, 9), (0, 9)])],
                start_areas=[StartArea("one", [(0.5, 3.4), (0.7, 3.4), (0.7, 3.6),
                                               (0.5, 3.6)], count=1)])
    mesh = route_mesh(room, resolution=0.1, kernel=2.0, clearance=0.5)
    f = clearance_factor(mesh, 0.5)
    on_wall = mesh.points[:, 1] == 0.0
    assert np.allclose(f[on_wall], 1.0 + ROUTE_WALL_COST)
    assert np.all(f[(mesh.points[:, 1] > 0.6) & (mesh.points[:, 1] < 4.4)
                    & (mesh.points[:, 0] > 0.6) & (mesh.points[:, 0] < 7.4)] == 1.0)
    aim = {}
    for c in (0.0, 0.5):
        run = pedmesh.build(room, "sfm", preset="paper",
                            params={"route_resolution": 0.1, "route_kernel": 2.0,
                                    "route_clearance": c})
        e = run.sim.desired_directions()[0]
        x = run.sim.positions[0]
        # where the heading crosses the door's front y = 5
        aim[c] = x[0] + e[0] * (5.0 - x[1]) / e[1]
    assert aim[0.0] == pytest.approx(3.0, abs=0.2)  # the jamb corner
    assert aim[0.5] > 3.25 and aim[0.5] > aim[0.0] + 0.3  # a body's width inside the door


def test_merged_walls_give_the_same_forces():
    """On a route mesh whose walls are split into 0.1-0.2 m edges, the merged wall set (one
    segment a straight piece) gives the wall accelerations of the split one to round-off."""
    room = pedmesh.load_room("geometries/experiments/uo-100-180-180.json")
    mesh = route_mesh(room, resolution=0.1, kernel=2.0, clearance=0.5)
    split, merged = WallSet.from_mesh(mesh, 1.05), WallSet.from_mesh(mesh, 1.05, merge=True)
    assert merged.n_segments < split.n_segments / 10
    rng = np.random.default_rng(0)
    x = mesh.points[rng.integers(0, mesh.n_points, 3000)] + rng.normal(0, 0.05, (3000, 2))
    x = x[mesh.locate(x) >= 0]
    n = len(x)
    v = rng.normal(0, 1, (n, 2))
    rad = np.full(n, 0.15)
    F = {}
    for name, w in (("split", split), ("merged", merged)):
        F[name] = np.zeros((n, 2))
        K.wall_accel(x, v, n, w.piece, w.next_seg, w.x0, w.y0, w.inv_cell, w.nx, w.ny,
                     w.cell_ptr, w.cell_seg, 1.05, rad, 962.0, 0.08, 1.2e5, 2.4e5, 60.0,
                     F[name], rad)
    assert np.abs(F["split"]).max() > 10
    np.testing.assert_allclose(F["merged"], F["split"], rtol=1e-9, atol=1e-9)


def test_rows_follow_the_route_mesh():
    """On its own route mesh the crowd's rows are put in the order of the neighbour grid's
    cells at every route solve; every row keeps its pedestrian (ids, positions in their
    triangles)."""
    room = pedmesh.load_room("geometries/experiments/uo-100-180-180.json")
    run = pedmesh.build(room, "sfm", preset="validated",
                        params={"route_kernel": 2.0, "route_resolution": 0.1})
    sim = run.sim
    assert sim.own_mesh
    while sim.t < 2.0:
        sim.step()
    before = {int(i): sim.x[k].copy() for k, i in enumerate(sim.ids[:sim.n])}
    sim._sort_rows()
    n = sim.n
    x = sim.x[:n]
    ci = np.clip(((x[:, 0] - sim._cx0) * sim._cinv).astype(int), 0, sim._cnx - 1)
    cj = np.clip(((x[:, 1] - sim._cy0) * sim._cinv).astype(int), 0, sim._cny - 1)
    assert np.all(np.diff(ci * sim._cny + cj) >= 0)
    assert not np.all(np.diff(sim.tri[:n]) >= 0)  # (not the triangles' order)
    assert sorted(before) == sorted(sim.ids[:n].tolist())
    for k, i in enumerate(sim.ids[:n]):
        assert np.array_equal(sim.x[k], before[int(i)])
    np.testing.assert_array_equal(sim.mesh.locate(sim.x[:n]), sim.tri[:n])
    assert not pedmesh.build(room, "sfm", preset="paper").sim.own_mesh
