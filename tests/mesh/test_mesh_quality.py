"""Every shipped geometry meshes into a valid, fully tagged quality mesh."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from pedmesh import BoundaryKind, MeshError, TriMesh

from pathlib import Path
from pedmesh.mesh import triangulate

SHIPPED = sorted(p for p in (Path(__file__).resolve().parents[2] / "geometries").iterdir()
                 if p.suffix in (".json", ".geojson", ".dxf")
                 and '"levels"' not in p.read_text(errors="replace"))  # (rooms; buildings:
# tests/mesh/test_building_mesh.py)


@pytest.fixture(scope="module", params=[p.name for p in SHIPPED])
def room_and_mesh(request, load_shipped):
    room = load_shipped(request.param)
    return room, triangulate(room)


def test_area_identity(room_and_mesh):
    room, mesh = room_and_mesh
    outline = shapely.Polygon(room.outline).area
    holes = sum(o.shape.area for o in room.obstacles)
    assert mesh.total_area == pytest.approx(outline - holes, rel=1e-9, abs=0)
    assert np.all(mesh.areas > 0)


def test_exit_lengths(room_and_mesh):
    room, mesh = room_and_mesh
    for k, ex in enumerate(room.exits):
        exact = shapely.LineString(ex.polyline).length
        assert abs(mesh.exit_lengths[k] - exact) <= 1e-12 * max(exact, 1.0)


def test_quality(room_and_mesh):
    _, mesh = room_and_mesh
    assert mesh.min_angle >= 28.0


def test_every_boundary_edge_is_tagged(room_and_mesh):
    room, mesh = room_and_mesh
    b = mesh.boundary_edges
    # each boundary edge is one of Triangle's tagged segments ...
    assert np.all(mesh.find_edges(mesh.segments) >= 0)
    assert set(mesh.find_edges(mesh.segments)) == set(b)
    assert np.all(mesh.edge_kind[b] != BoundaryKind.INTERIOR)
    assert np.all(mesh.edge_kind[mesh.edge_triangles[:, 1] >= 0] == BoundaryKind.INTERIOR)
    # ... and the tag is right: the edge lies on the element it names
    mids = mesh.edge_midpoints[b]
    for e, mid in zip(b, mids):
        kind, owner = mesh.edge_kind[e], mesh.edge_owner[e]
        p = shapely.Point(mid)
        if kind == BoundaryKind.EXIT:
            assert shapely.LineString(room.exit_polyline(owner)).distance(p) < 1e-9
        elif kind == BoundaryKind.OBSTACLE:
            assert room.obstacles[owner].shape.exterior.distance(p) < 1e-9
            assert not any(shapely.LineString(room.exit_polyline(k)).distance(p) < 1e-9
                           for k in range(len(room.exits)))
        else:
            assert kind == BoundaryKind.WALL and owner == -1
            assert shapely.LinearRing(room.outline).distance(p) < 1e-9
            assert not any(shapely.LineString(room.exit_polyline(k)).distance(p) < 1e-9
                           for k in range(len(room.exits)))


def test_exit_end_points_are_vertices(room_and_mesh):
    room, mesh = room_and_mesh
    for k in range(len(room.exits)):
        for q in room.exit_polyline(k):
            d = np.hypot(*(mesh.points - q).T).min()
            assert d == 0.0
            v = int(np.argmin(np.hypot(*(mesh.points - q).T)))
            assert mesh.exit_vertices[v] == k


def test_no_triangle_inside_an_obstacle(room_and_mesh):
    room, mesh = room_and_mesh
    c = mesh.centroids
    for o in room.obstacles:
        assert not shapely.contains_xy(o.shape, c[:, 0], c[:, 1]).any()
    assert shapely.contains_xy(shapely.Polygon(room.outline), c[:, 0], c[:, 1]).all()


def test_topology_is_consistent(room_and_mesh):
    _, mesh = room_and_mesh
    t2e, e2t, nbr = mesh.triangle_edges, mesh.edge_triangles, mesh.triangle_neighbors
    m = mesh.n_triangles
    # local edge i is opposite vertex i
    for i in range(3):
        e = mesh.edges[t2e[:, i]]
        tv = mesh.triangles[:, i]
        assert np.all((e[:, 0] != tv) & (e[:, 1] != tv))
    # neighbours are symmetric and share the edge
    has = nbr >= 0
    t, i = np.nonzero(has)
    back = nbr[nbr[t, i]]
    assert np.all((back == t[:, None]).sum(axis=1) == 1)
    assert np.all(e2t[:, 0] >= 0)
    # Euler characteristic: V - E + F = 1 - holes (one outer boundary)
    n_holes = len(mesh.obstacle_names)
    assert mesh.n_points - mesh.n_edges + m == 1 - n_holes
    # CSR vertex -> triangle adjacency lists each triangle three times in total
    ptr, idx = mesh.vertex_triangles
    assert ptr[-1] == 3 * m
    for v in (0, mesh.n_points // 2, mesh.n_points - 1):
        assert np.all(np.any(mesh.triangles[idx[ptr[v]:ptr[v + 1]]] == v, axis=1))


def test_normals_point_out_of_the_first_triangle(room_and_mesh):
    room, mesh = room_and_mesh
    n = mesh.edge_normals
    assert np.allclose(np.hypot(n[:, 0], n[:, 1]), 1.0)
    d = mesh.edge_midpoints - mesh.centroids[mesh.edge_triangles[:, 0]]
    assert np.all(np.einsum("ij,ij->i", n, d) > 0)
    # on the boundary they point out of the walkable area
    b = mesh.boundary_edges
    probe = mesh.edge_midpoints[b] + 1e-6 * n[b]
    assert not shapely.contains_xy(room.walkable, probe[:, 0], probe[:, 1]).any()
    # divergence theorem per triangle: sum of l_e n_e over its edges vanishes
    own = mesh.edge_triangles[mesh.triangle_edges, 0] == np.arange(mesh.n_triangles)[:, None]
    sign = np.where(own, 1.0, -1.0)
    s = np.einsum("ij,ijk->ik", sign * mesh.edge_lengths[mesh.triangle_edges],
                  n[mesh.triangle_edges])
    assert np.abs(s).max() < 1e-12 * mesh.edge_lengths.max()


def test_triangles_counter_clockwise(room_and_mesh):
    _, mesh = room_and_mesh
    p = mesh.points[mesh.triangles]
    a2 = (p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1]) - (p[:, 2, 0]
                                                                  - p[:, 0, 0]) * (p[:, 1, 1]
                                                                                   - p[:, 0, 1])
    assert np.all(a2 > 0)


def test_exit_grading_refines_near_exits(load_shipped):
    room = load_shipped("example2.json")
    uniform = triangulate(room, max_area=2.0)
    graded = triangulate(room, max_area=2.0, exit_size=0.3)
    near = lambda m: np.hypot(m.centroids[:, 0] - 100, m.centroids[:, 1] - 25) < 6  # noqa: E731
    assert graded.areas[near(graded)].mean() < 0.25 * uniform.areas[near(uniform)].mean()
    assert graded.min_angle >= 28
    assert graded.total_area == pytest.approx(5000.0, rel=1e-12)
    from pedmesh.mesh import exit_size_field

    target = np.minimum(exit_size_field(room, 0.3)(graded.centroids), 2.0)
    assert np.all(graded.areas <= target * 1.0001)


def test_mesh_arguments_are_checked(load_shipped):
    room = load_shipped("example2.json")
    with pytest.raises(MeshError, match="max_area"):
        triangulate(room, max_area=-1)
    with pytest.raises(MeshError, match="min_angle"):
        triangulate(room, min_angle=40)


def test_trimesh_rejects_bad_arrays():
    with pytest.raises(MeshError, match="degenerate"):
        TriMesh(np.array([[0, 0], [1, 0], [2, 0]], float), np.array([[0, 1, 2]]))
    with pytest.raises(MeshError, match="do not exist"):
        TriMesh(np.array([[0, 0], [1, 0], [0, 1]], float), np.array([[0, 1, 3]]))
    m = TriMesh(np.array([[0, 0], [1, 0], [0, 1]], float), np.array([[0, 2, 1]]))  # clockwise
    assert m.areas[0] == 0.5
    assert np.all(m.edge_kind[m.boundary_edges] == BoundaryKind.WALL)
