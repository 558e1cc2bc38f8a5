"""Point location agrees with a brute-force barycentric search."""

from __future__ import annotations

import numpy as np
import pytest
from pedmesh.mesh import triangulate


def brute_force(mesh, q, tol=1e-12):
    """All triangles whose closed (tolerant) area contains each point, as a boolean matrix."""
    p = mesh.points[mesh.triangles]  # (m, 3, 2)
    a, b, c = p[:, 0], p[:, 1], p[:, 2]
    a2 = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1])
    x, y = q[:, 0:1], q[:, 1:2]

    def orient(u, v):
        return (v[:, 0] - u[:, 0]) * (y - u[:, 1]) - (v[:, 1] - u[:, 1]) * (x - u[:, 0])

    lim = -tol * a2
    return (orient(b, c) >= lim) & (orient(c, a) >= lim) & (orient(a, b) >= lim)


@pytest.mark.parametrize("name", ["example3.json", "pillar_hall.json", "l_shaped.json"])
def test_locate_matches_brute_force(name, load_shipped):
    room = load_shipped(name)
    mesh = triangulate(room, max_area=4.0 if name.startswith("example") else 0.5)
    rng = np.random.default_rng(1)
    x0, y0, x1, y1 = mesh.bounds
    n = 10_000
    k = n // 4
    box = rng.uniform([x0 - 2, y0 - 2], [x1 + 2, y1 + 2], size=(k, 2))  # inside, outside, holes
    e = rng.integers(0, mesh.n_edges, k)
    s = rng.uniform(0, 1, k)[:, None]
    on_edges = (1 - s) * mesh.points[mesh.edges[e, 0]] + s * mesh.points[mesh.edges[e, 1]]
    verts = mesh.points[rng.integers(0, mesh.n_points, k)]
    eb = rng.choice(mesh.boundary_edges, k)
    outside_near = mesh.edge_midpoints[eb] + 1e-6 * mesh.edge_normals[eb]
    q = np.concatenate([box, on_edges, verts, outside_near])
    got = mesh.locate(q)
    inside = np.zeros(len(q), bool)
    for i0 in range(0, len(q), 500):  # chunked brute force
        sl = slice(i0, i0 + 500)
        cand = brute_force(mesh, q[sl])
        inside[sl] = cand.any(axis=1)
        hit = got[sl]
        ok = np.where(hit >= 0, cand[np.arange(len(hit)), np.maximum(hit, 0)], ~cand.any(axis=1))
        assert ok.all()
    assert np.array_equal(got >= 0, inside)
    assert inside[k:3 * k].all()  # every edge and vertex point is found
    assert not inside[3 * k:].any()  # just outside the boundary is outside
    # NaN and far-away points are outside
    assert np.all(mesh.locate(np.array([[np.nan, 0.0], [1e9, 1e9], [-1e9, 0]])) == -1)


def test_barycentric_reproduces_points(load_shipped):
    mesh = triangulate(load_shipped("l_shaped.json"))
    rng = np.random.default_rng(2)
    t = rng.integers(0, mesh.n_triangles, 1000)
    lam = rng.dirichlet([1, 1, 1], 1000)
    q = np.einsum("ij,ijk->ik", lam, mesh.points[mesh.triangles[t]])
    np.testing.assert_allclose(mesh.barycentric(q, t), lam, atol=1e-10)
    np.testing.assert_array_equal(mesh.locate(q), t)
