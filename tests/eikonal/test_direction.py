"""The desired-direction field: unit length, out through exits, never into walls."""

from __future__ import annotations

import numpy as np
import pytest

from pedmesh import Exit, Room
from pedmesh.eikonal import DirectionField, p1_gradients, solve_eikonal
from pedmesh.mesh import triangulate

NAMES = ["example3.json", "pillar_hall.json", "l_shaped.json", "corridor_bottleneck.json"]


@pytest.fixture(scope="module", params=NAMES)
def field(request, load_shipped):
    room = load_shipped(request.param)
    mesh = triangulate(room)
    return mesh, DirectionField(mesh, solve_eikonal(mesh))


def _unit(v):
    return np.hypot(v[:, 0], v[:, 1])


def test_unit_length(field):
    mesh, f = field
    np.testing.assert_allclose(_unit(f.triangle_directions), 1.0, atol=1e-12)
    np.testing.assert_allclose(_unit(f.vertex_directions), 1.0, atol=1e-12)
    rng = np.random.default_rng(0)
    t = rng.integers(0, mesh.n_triangles, 5000)
    lam = rng.dirichlet([1, 1, 1], 5000)
    pts = np.einsum("ij,ijk->ik", lam, mesh.points[mesh.triangles[t]])
    np.testing.assert_allclose(_unit(f.at(pts)), 1.0, atol=1e-12)
    np.testing.assert_array_equal(f.at(pts), f.at(pts, t))


def test_points_out_through_exits(field):
    mesh, f = field
    x = mesh.exit_edges()
    rng = np.random.default_rng(1)
    s = rng.uniform(0, 1, len(x))[:, None]
    pts = (1 - s) * mesh.points[mesh.edges[x, 0]] + s * mesh.points[mesh.edges[x, 1]]
    e = f.at(pts, mesh.edge_triangles[x, 0])
    assert np.all(np.einsum("ij,ij->i", e, mesh.edge_normals[x]) > 0.99)


def test_never_into_a_wall(field):
    mesh, f = field
    w = mesh.wall_edges()
    rng = np.random.default_rng(2)
    for s in (np.zeros(len(w)), np.ones(len(w)), rng.uniform(0, 1, len(w))):
        pts = ((1 - s[:, None]) * mesh.points[mesh.edges[w, 0]]
               + s[:, None] * mesh.points[mesh.edges[w, 1]])
        e = f.at(pts, mesh.edge_triangles[w, 0])
        assert np.all(np.einsum("ij,ij->i", e, mesh.edge_normals[w]) <= 1e-12)
        np.testing.assert_allclose(_unit(e), 1.0, atol=1e-12)


def test_p1_gradient_is_exact_for_linear_data(load_shipped):
    mesh = triangulate(load_shipped("pillar_hall.json"))
    g = p1_gradients(mesh, 3.0 * mesh.points[:, 0] - 2.0 * mesh.points[:, 1] + 1.0)
    np.testing.assert_allclose(g, np.broadcast_to([3.0, -2.0], g.shape), atol=1e-12)


def test_plane_wave_direction():
    room = Room([(0, 0), (20, 0), (20, 10), (0, 10)], exits=[Exit("w", [(0, 10), (0, 0)])])
    mesh = triangulate(room, max_area=0.5)
    f = DirectionField(mesh, solve_eikonal(mesh))
    np.testing.assert_allclose(f.triangle_directions,
                               np.broadcast_to([-1.0, 0.0], (mesh.n_triangles, 2)), atol=1e-9)
    inner = ~mesh.boundary_vertices
    np.testing.assert_allclose(f.vertex_directions[inner],
                               np.broadcast_to([-1.0, 0.0], (inner.sum(), 2)), atol=1e-9)


def test_outside_and_unreachable_give_zero(load_shipped):
    mesh = triangulate(load_shipped("l_shaped.json"))
    f = DirectionField(mesh, solve_eikonal(mesh))
    assert np.all(f.at(np.array([[-5.0, -5.0], [20.0, 20.0]])) == 0.0)
    phi = solve_eikonal(mesh).copy()
    phi[:] = np.inf
    g = DirectionField(mesh, phi)
    assert np.all(g.vertex_directions == 0) and np.all(g.triangle_directions == 0)
