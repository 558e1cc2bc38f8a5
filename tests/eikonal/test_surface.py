"""Fast marching on a building's surface: distances measured on the slope of a stair,
first-order convergence to the exact geodesic distance on a folded surface."""

from __future__ import annotations

import math

import numpy as np
import pytest
from shapely.geometry import LineString, Point

from pedmesh.eikonal.surface import SurfaceEikonalSolver, stair_costs
from pedmesh.geometry import Building, Exit, Level, Room, Stair
from pedmesh.mesh.building import triangulate_building


def strip(rise: float, door: tuple[float, float] = (1.5, 2.5), run: float = 4.0) -> Building:
    """A 4 m wide strip: level 'a' on x in [0, 10] at z = 0 with a door at x = 0, a stair on
    x in [10, 10 + run] and level 'b' beyond it, ``rise`` m up, 10 m long."""
    x1, x2 = 10.0, 10.0 + run
    a = Room(outline=[(0, 0), (x1, 0), (x1, 4), (0, 4)], name="a",
             exits=[Exit("door", [(0, door[1]), (0, door[0])])])
    b = Room(outline=[(x2, 0), (x2 + 10, 0), (x2 + 10, 4), (x2, 4)], name="b")
    st = Stair("ramp", [(x1, 0), (x2, 0), (x2, 4), (x1, 4)],
               {"level": "a", "edge": [(x1, 0), (x1, 4)]},
               {"level": "b", "edge": [(x2, 0), (x2, 4)]})
    return Building([Level("a", 0.0, a), Level("b", rise, b)], [st], name="strip")


def unfolded(p: np.ndarray, rise: float, run: float = 4.0) -> np.ndarray:
    """The strip unrolled into the plane: x along the surface."""
    L = math.hypot(run, rise)
    x = p[:, 0]
    u = np.where(x <= 10, x, np.where(x <= 10 + run, 10 + (x - 10) * L / run,
                                      10 + L + (x - 10 - run)))
    return np.column_stack([u, p[:, 1]])


def test_a_stair_is_walked_on_its_slope():
    """A 4 m run with a 3 m rise is 5 m on the surface (and 4 m rise: 5.66 m at 45 deg)."""
    for rise, slope_len in ((3.0, 5.0), (4.0, math.hypot(4, 4)), (0.0, 4.0)):
        m = triangulate_building(strip(rise, door=(0.0, 4.0)), max_area=0.5, feature_area=None)
        phi = SurfaceEikonalSolver(m).solve(1.0)
        top = np.isclose(m.points[:, 0], 14.0)
        foot = np.isclose(m.points[:, 0], 10.0)
        assert np.allclose(phi[top], 10.0 + slope_len, atol=1e-9)
        assert np.allclose(phi[foot], 10.0, atol=1e-9)
        # at the stair speed up: the extra slope length costs 1/speed_up s per m
        cost = stair_costs(m, None, level_cost=1.0)
        st = m.building.stairs[0]
        t = SurfaceEikonalSolver(m).solve(cost)
        # (a stair without rise is a flat connector, walked at the level's speed)
        speed = st.speed_down if rise > 0 else 1.0
        assert np.allclose(t[top], 10.0 + slope_len / speed, atol=1e-9)


def test_stairs_are_walked_up_where_the_exit_is_above():
    m = triangulate_building(strip(3.0, door=(0.0, 4.0)), max_area=0.5, feature_area=None)
    # exit on the lower level: from level b people walk down
    phi = SurfaceEikonalSolver(m).solve(1.0)
    c = stair_costs(m, phi)
    st = m.building.stairs[0]
    ramp = m.pieces[m.piece_index("ramp")].triangles
    assert np.allclose(c[ramp], 1.0 / st.speed_down)
    # the same potential with its sign turned: the exit above, walking up
    c = stair_costs(m, -phi)
    assert np.allclose(c[ramp], 1.0 / st.speed_up)


def _l1_error(area: float, rise: float = 3.0) -> tuple[float, float]:
    b = strip(rise)
    m = triangulate_building(b, max_area=area, feature_area=None)
    phi = SurfaceEikonalSolver(m).solve(1.0)
    door = LineString([(0, 1.5), (0, 2.5)])
    exact = np.array([door.distance(Point(q)) for q in unfolded(m.points, rise)])
    w = np.zeros(m.n_points)
    np.add.at(w, m.triangles.ravel(), np.repeat(m.areas / 3, 3))
    return float(np.sum(w * np.abs(phi - exact)) / np.sum(w)), math.sqrt(area)


def test_first_order_convergence_on_a_folded_surface():
    """Level, ramp, level (a developable surface): the exact geodesic distance is the
    distance in the unrolled plane. The surface solver converges at first order, with the
    room solver's accuracy: its error is that of the same strip built flat (rise 0) to
    within 15 % on every mesh."""
    areas = (1.0, 0.25, 0.0625)
    errs, hs = zip(*[_l1_error(a) for a in areas])
    flat = [_l1_error(a, rise=0.0)[0] for a in areas]
    order = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    print(f"\nfolded surface: L1 errors {errs} at h {hs}, order {order:.2f}; flat {flat}")
    assert errs[0] > errs[1] > errs[2]
    assert order > 0.9
    assert all(e < 1.15 * f for e, f in zip(errs, flat))


def test_the_surface_solver_matches_the_room_solver_on_one_level():
    """A building of one level is the room: the same vertices, the same potential."""
    from pedmesh.eikonal import solve_eikonal
    from pedmesh.mesh import triangulate

    room = Room(outline=[(0, 0), (12, 0), (12, 6), (4, 6), (4, 9), (0, 9)], name="l",
                exits=[Exit("door", [(0, 8), (0, 9)])])
    m = triangulate_building(Building([Level("l", 0.0, room)]), max_area=0.5)
    flat = triangulate(room, max_area=0.5)
    assert np.array_equal(m.points[:, :2], flat.points)
    assert np.array_equal(SurfaceEikonalSolver(m).solve(1.0), solve_eikonal(flat, 1.0))


@pytest.mark.parametrize("rise", [0.0, 3.0])
def test_hinge_vertices_are_shared(rise):
    m = triangulate_building(strip(rise), max_area=0.3)
    counts = m.edge_triangle_counts
    assert counts.max() == 2
    # only walls and the door are boundary: the stair edges are interior
    assert np.sum(counts == 1) == len(m.segments)
    assert math.isclose(m.area, 40 + 40 + 4 * math.hypot(4, rise), rel_tol=1e-12)


def test_the_walking_direction_follows_the_surface():
    """On the strip with a door across its whole width, people walk straight to the door:
    -grad(phi) is a unit vector along -x on the levels and down the slope on the stair."""
    from pedmesh.eikonal.surface import surface_gradient

    m = triangulate_building(strip(3.0, door=(0.0, 4.0)), max_area=0.5, feature_area=None)
    g = surface_gradient(m, SurfaceEikonalSolver(m).solve(1.0))
    assert np.allclose(np.linalg.norm(g, axis=1), 1.0, atol=1e-9)
    ramp = m.pieces[m.piece_index("ramp")].triangles
    assert np.allclose(g[ramp], [0.8, 0.0, 0.6], atol=1e-9)  # up the 3-4-5 slope
    assert np.allclose(np.abs(np.sum(g * m.normals, axis=1)), 0.0, atol=1e-12)  # tangent


def test_a_flat_connector_is_no_edge_bit_for_bit():
    """A stair without rise (a flat connector) between two levels at one height is no edge
    of the surface: the potential and the direction field equal the flat room's on the same
    triangles to the last bit, with the exit's corner rays and the obtuse-angle splits
    reaching across the connector (the door is 3 m from it) and a reflex corner on the far
    level."""
    from pedmesh.eikonal import DirectionField, EikonalSolver
    from pedmesh.eikonal.surface import atlas_direction_field
    from pedmesh.mesh import TriMesh
    from pedmesh.mesh.atlas import build_atlas

    door = Exit("door", [(0, 2.5), (0, 1.5)])
    a = Room(outline=[(0, 0), (3, 0), (3, 4), (0, 4)], name="a", exits=[door])
    far = [(5, 0), (12, 0), (12, 10), (8, 10), (8, 4), (5, 4)]
    b = Room(outline=far, name="b")
    st = Stair("link", [(3, 0), (5, 0), (5, 4), (3, 4)],
               {"level": "a", "edge": [(3, 0), (3, 4)]},
               {"level": "b", "edge": [(5, 0), (5, 4)]})
    bld = Building([Level("a", 2.0, a), Level("b", 2.0, b)], [st], name="flat")
    s = triangulate_building(bld, max_area=0.2, feature_area=None)
    room = Room(outline=[(0, 0), *far[:-1], (0, 4)], name="one", exits=[door])
    flat = TriMesh(points=s.points[:, :2], triangles=s.triangles, segments=s.segments,
                   segment_kind=s.segment_kind, segment_owner=s.segment_owner,
                   exit_names=s.exit_names, room=room)
    surf, plain = SurfaceEikonalSolver(s), EikonalSolver(flat)
    across = np.isin(plain.ray_idx, np.flatnonzero(flat.points[:, 0] > 5.0))
    assert across.any()  # (rays from the door's ends reach the far level)
    for name in ("ray_ptr", "ray_idx", "ray_len", "ray_samp_tri", "vt_corner", "ds_corner"):
        assert np.array_equal(getattr(surf, name), getattr(plain, name)), name
    cost = np.random.default_rng(3).uniform(0.5, 2.0, s.n_triangles)
    for c in (1.0, cost):
        phi = surf.solve(c)
        assert np.array_equal(phi, plain.solve(c))
    atlas = build_atlas(s)
    df = atlas_direction_field(atlas, phi)
    ref = DirectionField(flat, phi)
    assert np.array_equal(df.vertex_directions, ref.vertex_directions[atlas.to_surface])
    assert np.array_equal(df.packed, ref.packed)
