"""The social force model's routes on a mesh of their own (issue 44): the route mesh, the
route's crowd density on the scale ``route_kernel``, one answer whatever the run's mesh,
and convergence as the route mesh is refined."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely

import pedmesh
from pedmesh import Exit, Room, StartArea
from pedmesh.analysis import kernel_density
from pedmesh.analysis.fields import GridKernelDensity
from pedmesh.errors import MeshError
from pedmesh.mesh import triangulate
from pedmesh.mesh.route_mesh import (OPEN_EDGE_PER_KERNEL, reflex_corners, route_mesh,
                                     route_size_field)

ROUTE = {"route_kernel": 2.0, "route_resolution": 0.1}


def _door_room(people: int = 40) -> Room:
    """A 6 x 5 m waiting area, a 0.8 m door in a 0.2 m thick wall, a 4 m deep room behind
    it whose far wall is the exit."""
    outline = [(0, 0), (6, 0), (6, 5), (3.4, 5), (3.4, 5.2), (6, 5.2), (6, 9.2), (0, 9.2),
               (0, 5.2), (2.6, 5.2), (2.6, 5), (0, 5)]
    return Room(outline, exits=[Exit("out", [(6, 9.2), (0, 9.2)])],
                start_areas=[StartArea("crowd", [(0.3, 0.3), (5.7, 0.3), (5.7, 4.2),
                                                 (0.3, 4.2)], count=people)],
                name="door")


def test_reflex_corners_are_the_door_jambs():
    """The corners routes bend around: the four jamb corners of the door, not the room's
    convex corners."""
    c = reflex_corners(_door_room())
    want = {(2.6, 5.0), (3.4, 5.0), (2.6, 5.2), (3.4, 5.2)}
    assert {tuple(np.round(p, 9)) for p in c} == want
    pillar = Room([(0, 0), (10, 0), (10, 10), (0, 10)],
                  obstacles=[pedmesh.Obstacle("p", [(4, 4), (6, 4), (6, 6), (4, 6)])],
                  exits=[Exit("e", [(10, 4), (10, 6)])])
    assert {tuple(np.round(p, 9)) for p in reflex_corners(pillar)} == {
        (4, 4), (6, 4), (6, 6), (4, 6)}


def test_route_mesh_is_fine_at_the_door_and_coarse_in_the_open():
    """Edges of route_resolution at the exit and an eighth of it at the jambs, growing to
    route_kernel/3 in the open."""
    room = _door_room()
    mesh = route_mesh(room, resolution=0.1, kernel=2.0)
    lengths = mesh.edge_lengths
    mid = mesh.points[mesh.edges].mean(axis=1)
    near_jamb = np.hypot(mid[:, 0] - 2.6, mid[:, 1] - 5.0) < 0.15
    assert lengths[near_jamb].max() <= 0.05
    far = (mid[:, 1] < 2.5) & (np.abs(mid[:, 0] - 3.0) < 1.0)  # 2.5 m from any feature
    h_open = OPEN_EDGE_PER_KERNEL * 2.0
    assert 0.4 * h_open <= np.median(lengths[far]) <= 1.3 * h_open
    # the size field's edge grows by 0.1 m per metre within 0.5 m of a jamb, by 0.2 m per
    # metre beyond it and from the exit, capped in the open
    size = route_size_field(room, 0.1, h_open)
    edge = np.sqrt(4.0 * size(np.array([[2.5, 4.9], [2.6, 4.0], [3.0, 1.0], [3.0, 8.5]]))
                   / math.sqrt(3.0))
    assert edge[0] == pytest.approx(0.0125 + 0.1 * math.hypot(0.1, 0.1))
    assert edge[1] == pytest.approx(0.0125 + 0.1 * 0.5 + 0.2 * 0.5)
    assert edge[2] == pytest.approx(h_open)
    exit_d = room.exit_polyline(0)
    d_exit = shapely.LineString(exit_d).distance(shapely.Point(3.0, 8.5))
    assert edge[3] == pytest.approx(min(0.1 + 0.2 * d_exit, h_open))


def test_route_mesh_is_reused_and_carries_the_runs_room():
    room = _door_room(30)
    m1 = route_mesh(room, resolution=0.15, kernel=2.0)
    other = _door_room(50)  # the same walls and exits, another crowd
    m2 = route_mesh(other, resolution=0.15, kernel=2.0)
    assert m2.room is other and m1.room is room
    np.testing.assert_array_equal(m1.triangles, m2.triangles)


def test_route_mesh_too_large_names_the_route_parameters():
    room = Room([(0, 0), (2000, 0), (2000, 2000), (0, 2000)],
                exits=[Exit("e", [(2000, 0), (2000, 10)])])
    with pytest.raises(MeshError, match="route_resolution"):
        route_mesh(room, resolution=0.05, kernel=0.6)


@pytest.mark.parametrize("L", [0.7, 2.0])
def test_grid_density_is_the_gaussian_kernel_density(L):
    """The grid's density is the kernel density of width L (the route's length scale) to
    about 1 % of its peak, and keeps the crowd's mass."""
    rng = np.random.default_rng(3)
    pts = rng.uniform(0, 20, (3000, 2))
    grid = GridKernelDensity(pts, L)
    for crowd in (rng.uniform(6, 14, (300, 2)), rng.normal(10, 1.0, (200, 2))):
        a = grid(crowd)
        b = kernel_density(positions=crowd, points=pts, R=L, cutoff=6.0)
        assert np.abs(a - b).max() <= 0.015 * b.max()
    g = grid.grid(rng.uniform(6, 14, (300, 2)))
    assert g.sum() * grid.cell ** 2 == pytest.approx(300, rel=1e-9)
    assert np.all(grid(np.zeros((0, 2))) == 0)


def test_the_route_reads_the_crowd_on_the_route_kernels_scale():
    """The route cost's density is the kernel density of width route_kernel at the route
    mesh's vertices (not the force kernel R): honoured for 1 and 3 m, and a wider kernel
    spreads the same crowd thinner."""
    room = _door_room(40)
    peaks = []
    for L in (1.0, 3.0):
        run = pedmesh.build(room, "sfm", preset="validated",
                            params={"route_kernel": L, "route_resolution": 0.2})
        sim = run.sim
        rho = sim.route_density()
        exact = kernel_density(positions=sim.positions, points=sim.mesh.points, R=L,
                               cutoff=6.0)
        assert np.abs(rho - exact).max() <= 0.02 * exact.max()
        peaks.append(rho.max())
    assert peaks[1] < 0.6 * peaks[0]


def test_one_answer_whatever_the_runs_mesh():
    """With route_resolution the pedestrians walk on the route mesh: the run's mesh only
    carries the output, so a coarse and a fine mesh give the same evacuation, bit for bit,
    and the density frames lie on each run's own mesh."""
    room = _door_room(40)
    out = []
    for mo in ({"max_area": 2.0, "feature_area": None}, {"max_area": 0.05,
                                                           "feature_area": None}):
        res = pedmesh.simulate(room, "sfm", preset="validated", params=ROUTE, seed=1,
                               mesh_options=mo, t_end=120.0)
        assert res.finished
        mesh = triangulate(room, **mo)
        assert len(res.density[0][1]["density"]) == mesh.n_points
        assert res.summary["route_mesh"]["resolution_m"] == 0.1
        out.append((res.times, np.sort(res.exit_times)))
    assert out[0][0] == out[1][0]
    np.testing.assert_array_equal(out[0][1], out[1][1])


def test_without_route_resolution_the_run_walks_on_its_own_mesh():
    """The paper's way (no route mesh): the run's mesh is the one walked on, and nothing
    about a route mesh is reported."""
    room = _door_room(10)
    run = pedmesh.build(room, "sfm", preset="paper")
    assert run.sim.mesh is run.mesh
    assert "route_mesh" not in run.summary()


#: the realisations the convergence test averages: one run's T50 scatters by about 3 %
#: from seed to seed, so the difference of two means over 16 seeds has a standard error
#: near 1 %, a third of the test's 3 % (over four it was about 2 %: at the clearance refit's
#: best point so far, seeds 1-4 read +4.5 %, seeds 13-36 0.0 %, docs/validation/
#: door_physics.md)
CONVERGENCE_SEEDS = tuple(range(1, 17))


def _door_times(refine: float) -> np.ndarray:
    """Mean T50, T90 [s] over CONVERGENCE_SEEDS of the validated preset in the 60-person
    door room, its route mesh refined by ``refine``."""
    runs = [pedmesh.simulate(_door_room(60), "sfm", preset="validated",
                             params={"route_refine": refine}, seed=s, t_end=200.0).times
            for s in CONVERGENCE_SEEDS]
    assert all(r["T100"] is not None for r in runs)
    return np.array([np.mean([r[k] for r in runs]) for k in ("T50", "T90")])


def test_routes_converge_as_the_route_mesh_is_refined():
    """The validated preset's route mesh against one with every edge halved (route_refine
    2: the exits' and jambs' edges, their growth away from them, the walls' and the open
    area's edges), 16 seeds each: T50 and T90 within 3 % at a 0.8 m door. Measured: T50 /
    T90 21.8 / 37.1 s against 21.9 / 37.4 s (-0.4 / -0.9 %). Before the corner zone, on
    seeds 1-4, T90 was 34.3 s against 36.1 s (+5 %)."""
    t0, t2 = _door_times(1.0), _door_times(2.0)
    print({"preset": t0.round(2).tolist(), "refine 2": t2.round(2).tolist()})
    assert np.all(np.abs(t0 / t2 - 1.0) <= 0.03)


def test_route_refine_divides_every_edge_of_the_route_mesh():
    """route_refine 2 halves the edges everywhere: about four times the triangles, and the
    edges at a jamb halved."""
    room = _door_room()
    m1 = route_mesh(room, resolution=0.1, kernel=2.0, clearance=0.5)
    m2 = route_mesh(room, resolution=0.1, kernel=2.0, clearance=0.5, refine=2.0)
    assert 3.2 <= m2.n_triangles / m1.n_triangles <= 4.8

    def median_edge_near_jambs(m):
        mid = m.points[m.edges].mean(axis=1)
        near = np.hypot(mid[:, 0] - 2.6, mid[:, 1] - 5.0) < 0.15
        return np.median(np.linalg.norm(np.diff(m.points[m.edges[near]], axis=1)[:, 0],
                                         axis=1))

    assert 0.4 <= median_edge_near_jambs(m2) / median_edge_near_jambs(m1) <= 0.6
    with pytest.raises(pedmesh.MeshError, match="route_refine"):
        route_mesh(room, resolution=0.1, kernel=2.0, refine=0.0)


def test_a_building_walks_on_its_route_mesh_and_writes_on_its_own():
    """A building with route_resolution: the pedestrians walk on a route surface graded at
    the stair edges, exits and reflex corners; the density frames lie on the run's surface
    mesh; a coarse and a finer run's mesh give the same evacuation."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from building_data import TWO

    from pedmesh.geometry.formats.native import building_from_dict
    from pedmesh.mesh.building import triangulate_building

    b = building_from_dict(TWO)
    times = []
    for mo in ({"max_area": 2.0}, {"max_area": 0.5}):
        mesh = triangulate_building(b, **mo)
        res = pedmesh.simulate(b, "sfm", preset="paper", mesh=mesh, params=ROUTE,
                               t_end=200.0)
        assert res.finished
        assert len(res.density[-1][1]["density"]) == mesh.n_points
        assert res.summary["route_mesh"]["triangles"] > mesh.n_triangles
        times.append(res.times)
    assert times[0] == times[1]
