"""Fast marching against exact solutions, symmetry, scikit-fmm and a plain-Python reference."""

from __future__ import annotations

import numpy as np
import pytest

from pedmesh import Exit, ParameterError, Room, TriMesh
from pedmesh.eikonal import EikonalSolver, geodesic_distance, solve_eikonal
from pedmesh.mesh import BoundaryKind

from reference_fmm import reference_fmm
from pedmesh.mesh import triangulate

AREAS = [2.0, 0.5, 0.125, 0.03125]  # nested: each mesh has about 4x the vertices


@pytest.fixture(scope="module")
def example3_sequence(load_shipped):
    room = load_shipped("example3.json")
    meshes = [triangulate(room, max_area=a) for a in AREAS]
    exact = [geodesic_distance(room, m.points) for m in meshes]
    return room, meshes, exact


def test_exact_solution_itself(load_shipped):
    room = load_shipped("example3.json")
    # on the obstacle face, behind the obstacle, in front of an exit, far corner
    pts = np.array([[70, 25], [81, 25], [99, 15], [0, 0], [60, 25]])
    d = geodesic_distance(room, pts)
    assert d[0] == pytest.approx(40.0)  # up the face to (70, 35), then straight along y = 35
    assert d[1] == pytest.approx(np.hypot(19, 5))  # from (81,25) straight to (100,20)
    assert d[2] == pytest.approx(1.0)
    assert d[3] == pytest.approx(np.hypot(100, 10))
    assert d[4] == pytest.approx(np.hypot(10, 10) + 30.0)  # around the corner (70, 35)


def test_accuracy_at_30k_vertices(example3_sequence):
    room, meshes, exact = example3_sequence
    mesh, ex = meshes[2], exact[2]
    assert 25_000 < mesh.n_points < 40_000
    phi = solve_eikonal(mesh)
    err = np.abs(phi - ex)
    assert err.mean() <= 0.10
    assert err.max() <= 0.21
    # the corner-ray seeding is worth having: plain fast marching is 2.5x worse in L1
    plain = EikonalSolver(mesh, corner_radius=0).solve(1.0)
    assert np.abs(plain - ex).mean() <= 0.10
    assert np.abs(plain - ex).max() <= 0.21
    assert err.mean() < 0.5 * np.abs(plain - ex).mean()


@pytest.mark.parametrize("corner_radius", [None, 0.0])
def test_observed_order(example3_sequence, corner_radius):
    room, meshes, exact = example3_sequence
    hs, l1 = [], []
    for mesh, ex in zip(meshes, exact):
        s = (EikonalSolver(mesh) if corner_radius is None
             else EikonalSolver(mesh, corner_radius=corner_radius))
        phi = s.solve(1.0)
        hs.append(mesh.h)
        l1.append(np.abs(phi - ex).mean())
    order = np.polyfit(np.log(hs), np.log(l1), 1)[0]
    assert order >= 0.7, (l1, order)
    assert all(a > b for a, b in zip(l1, l1[1:]))


def test_exits_are_exact(load_shipped):
    room = load_shipped("example3.json")
    mesh = triangulate(room, max_area=1.0)
    phi = solve_eikonal(mesh, exit_values=[0.0, 7.5])
    ev = mesh.exit_vertices
    assert np.all(phi[ev == 0] == 0.0)
    assert np.all(phi[ev == 1] == 7.5)
    # exit end points are vertices with exactly these values
    for k, val in enumerate([0.0, 7.5]):
        for q in room.exit_polyline(k):
            v = int(np.argmin(np.hypot(*(mesh.points - q).T)))
            assert phi[v] == val


def test_exit_selection_and_values(load_shipped):
    room = load_shipped("example3.json")
    mesh = triangulate(room, max_area=1.0)
    north = solve_eikonal(mesh, exits=["exit-north"])
    d_north = geodesic_distance(room, mesh.points, exits=[1])
    assert np.abs(north - d_north).mean() < 0.15
    both = solve_eikonal(mesh, exit_values=[10.0, 0.0])
    d_south = geodesic_distance(room, mesh.points, exits=[0])
    expect = np.minimum(d_south + 10.0, d_north)
    assert np.abs(both - expect).mean() < 0.15
    with pytest.raises(ParameterError, match="unknown exit 'nope'"):
        solve_eikonal(mesh, exits=["nope"])
    with pytest.raises(ParameterError, match="one value per target exit"):
        solve_eikonal(mesh, exit_values=[1.0, 2.0, 3.0])


def _jittered(room, max_area, min_angle, amount, seed=0):
    mesh = triangulate(room, max_area=max_area, min_angle=min_angle)
    rng = np.random.default_rng(seed)
    p = mesh.points.copy()
    inner = ~mesh.boundary_vertices
    p[inner] += amount * mesh.h * rng.uniform(-1, 1, (inner.sum(), 2))
    return TriMesh(p, mesh.triangles, mesh.segments, mesh.segment_kind, mesh.segment_owner,
                   mesh.exit_names, mesh.obstacle_names, room)


@pytest.mark.parametrize("angle_deg", [0.0, 30.0, -65.0])
def test_plane_wave_is_exact_on_an_irregular_mesh(angle_deg):
    a = np.radians(angle_deg)
    R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    box = np.array([[0, 0], [20, 0], [20, 10], [0, 10]], float) @ R.T + [3, -2]
    room = Room(box, exits=[Exit("wall", [box[3], box[0]])])
    mesh = _jittered(room, 0.3, 10.0, 0.25)
    obtuse = np.degrees(mesh.angles).max(axis=1) > 90
    assert obtuse.mean() > 0.2  # many obtuse triangles
    assert np.degrees(mesh.angles).max() > 130
    phi = solve_eikonal(mesh)
    n = np.array([np.cos(a), np.sin(a)])  # the exit normal, into the room
    exact = (mesh.points - box[0]) @ n
    assert np.abs(phi - exact).max() < 1e-10


def test_mirror_symmetric_room_gives_symmetric_phi(mirrored_mesh):
    mesh, mirror, upper, _ = mirrored_mesh
    assert mesh.exit_lengths[0] == pytest.approx(10.0)
    phi = solve_eikonal(mesh)
    np.testing.assert_allclose(phi[upper], phi[mirror], rtol=0, atol=1e-12)
    plain = EikonalSolver(mesh, corner_radius=0).solve(1.0)
    np.testing.assert_allclose(plain[upper], plain[mirror], rtol=0, atol=1e-12)
    cost = 1.0 + 0.3 * np.cos(mesh.points[:, 0] / 7.0) * np.cos((mesh.points[:, 1] - 25) / 4.0)
    varc = solve_eikonal(mesh, cost=cost)
    np.testing.assert_allclose(varc[upper], varc[mirror], rtol=0, atol=1e-12)


def _skfmm_reference(cost_fn, dx):
    import skfmm
    from scipy.interpolate import RegularGridInterpolator

    x = np.arange(0, 40 + dx / 2, dx)
    y = np.arange(0, 20 + dx / 2, dx)
    X, Y = np.meshgrid(x, y, indexing="ij")
    phi0 = np.ones_like(X)
    phi0[(np.abs(X - 40) < 1e-9) & (Y >= 8 - 1e-9) & (Y <= 12 + 1e-9)] = 0.0
    T = skfmm.travel_time(phi0, 1.0 / cost_fn(X, Y), dx=dx, order=2)
    return RegularGridInterpolator((x, y), np.asarray(T))


def test_variable_cost_agrees_with_scikit_fmm():
    room = Room([(0, 0), (40, 0), (40, 20), (0, 20)], exits=[Exit("e", [(40, 8), (40, 12)])])

    def cost_fn(x, y):
        return 1.0 + 0.5 * np.sin(x / 5.0) * np.cos(y / 4.0)

    ref = _skfmm_reference(cost_fn, 0.05)  # order 2 on 801 x 401 nodes: L1 0.002 m for c = 1
    errs, first_order, hs = [], [], []
    for a in (0.4, 0.1):
        mesh = triangulate(room, max_area=a)
        cost = cost_fn(*mesh.points.T)
        phi = solve_eikonal(mesh, cost=cost)
        errs.append(np.abs(phi - ref(mesh.points)).mean())
        # the scheme's first-order error: plain fast marching, unit cost, exact solution
        unit = EikonalSolver(mesh, corner_radius=0).solve(1.0)
        first_order.append(np.abs(unit - geodesic_distance(room, mesh.points)).mean())
        hs.append(mesh.h)
        # per-triangle costs (centroid values) agree to first order too
        phi_t = solve_eikonal(mesh, cost=cost_fn(*mesh.centroids.T))
        assert np.abs(phi_t - phi).mean() < first_order[-1]
    # within the first-order error (scaled by the largest cost, 1.5) ...
    for e, u in zip(errs, first_order):
        assert e <= 1.5 * u
    # ... and converging
    assert np.log(errs[0] / errs[1]) / np.log(hs[0] / hs[1]) >= 0.7


def test_unreachable_vertices_are_inf():
    # two separate squares; only the left one has an exit
    pts = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [3, 0], [4, 0], [4, 1], [3, 1]], float)
    tri = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]])
    mesh = TriMesh(pts, tri, segments=[[3, 0]], segment_kind=[BoundaryKind.EXIT],
                   segment_owner=[0], exit_names=("left",))
    phi = solve_eikonal(mesh)
    np.testing.assert_allclose(phi[:4], [0, 1, 1, 0])
    assert np.all(np.isinf(phi[4:]))


def test_bad_costs_are_named(load_shipped):
    mesh = triangulate(load_shipped("l_shaped.json"), max_area=2.0)
    with pytest.raises(ParameterError, match="cost must be positive"):
        solve_eikonal(mesh, cost=-1.0)
    bad = np.ones(mesh.n_points)
    bad[5] = np.nan
    with pytest.raises(ParameterError, match="entry 5"):
        solve_eikonal(mesh, cost=bad)
    with pytest.raises(ParameterError, match="one value per vertex"):
        solve_eikonal(mesh, cost=np.ones(7))


@pytest.mark.parametrize("corner_radius", [0.0, 10.0])
def test_compiled_kernel_matches_plain_python(load_shipped, corner_radius):
    room = load_shipped("example3.json")
    # (a uniform mesh: on the graded default mesh the plain-Python reference handles some
    # obtuse triangles differently; the compiled kernel is then the closer of the two to
    # the exact distance, mean error 0.25 m against 0.29 m at max_area 4)
    mesh = triangulate(room, max_area=4.0, feature_area=None)
    s = EikonalSolver(mesh, corner_radius=corner_radius)
    rng = np.random.default_rng(3)
    f_tri = 0.5 + rng.random(mesh.n_triangles)
    phi = s.solve(f_tri, exit_values=[0.0, 3.0])
    _, ray_cost = s._costs(f_tri)
    rays = {}
    for v in range(mesh.n_points):
        for k in range(s.ray_ptr[v], s.ray_ptr[v + 1]):
            rays.setdefault(v, []).append((int(s.ray_idx[k]), float(ray_cost[k])))
    fixed = {int(v): (0.0 if mesh.exit_vertices[v] == 0 else 3.0) for v in s.fixed_vertices}
    ref = reference_fmm(mesh, f_tri, fixed, rays)
    np.testing.assert_allclose(phi, ref, rtol=1e-13, atol=1e-12)
    assert s.n_obtuse > 0


def test_vertex_costs_average_onto_triangles_as_numpy_does(load_shipped):
    """Per-vertex costs become per-triangle ones as the mean of the three corners, in
    numpy's summation order: the same bits as ``c[triangles].mean(axis=1)`` (the paper's
    runs stay bit for bit)."""
    mesh = triangulate(load_shipped("example3.json"), max_area=1.0)
    s = EikonalSolver(mesh)
    rng = np.random.default_rng(5)
    c = 0.3 + rng.random(mesh.n_points) * rng.choice([1e-3, 1.0, 1e3], mesh.n_points)
    f_tri, _ = s._costs(c)
    assert np.array_equal(f_tri, c[mesh.triangles].mean(axis=1))
