"""Terms of the social force model for dense crowds, off in the paper's model: the
speed-dependent space requirement (``shrink``, ``t_space``: a person who wants to stand
keeps less space than a walker, Seyfried et al. 2005) and the field of vision (``vision``,
Helbing's lambda)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pedmesh import Exit, ParameterError, Room, SimulationError
from pedmesh.models.sfm import SFMNumerics, Simulation, SocialForceParams
from pedmesh.models.sfm import kernels as K
from pedmesh.population import Population
from pedmesh.mesh import triangulate


def test_social_radii_follow_the_formula():
    """min(r_i, r_i - shrink + t_space U_e / 2) with U_e the desired speed."""
    rng = np.random.default_rng(3)
    n = 200
    rad = rng.uniform(0.14, 0.2, n)
    ue = rng.uniform(0.0, 0.3, n)
    rs = np.empty(n)
    K.social_radii(n, rad, ue, 0.06, 1.06, False, rad, rs)
    assert np.allclose(rs, np.minimum(rad, rad - 0.06 + 0.53 * ue), rtol=0, atol=1e-15)
    assert (rs < rad).any() and (rs == rad).any()
    K.social_radii(n, rad, np.zeros(n), 0.06, 1.06, False, rad, rs)
    assert np.array_equal(rs, rad - 0.06)  # wanting to stand: the body radius less the shrink
    K.social_radii(n, rad, np.full(n, 2 * 0.06 / 1.06 + 1e-9), 0.06, 1.06, False, rad,
                    rs)
    assert np.array_equal(rs, rad)  # from 2 shrink / t_space on: the body radius


def test_desired_speeds_follow_the_law_and_the_crowding_stretch():
    rng = np.random.default_rng(4)
    n = 300
    law = SocialForceParams(speed_law="weidmann").speed
    u0 = rng.uniform(0.8, 1.6, n)
    rho = rng.uniform(0.0, 8.0, n)
    cf = rng.uniform(0.0, 1.0, n)
    ue = np.empty(n)
    K.desired_speeds(n, u0, law.array, rho, -1.0, False, cf, 2.7, 2.0, ue)
    assert np.allclose(ue, u0 * law(rho) / law.U_f, rtol=1e-13, atol=0)
    K.desired_speeds(n, u0, law.array, rho, -1.0, True, cf, 2.7, 2.0, ue)
    eff = np.where(rho <= 2.7, rho, 2.7 + (rho - 2.7) / (1.0 + cf))
    assert np.allclose(ue, u0 * law(eff) / law.U_f, rtol=1e-13, atol=0)
    K.desired_speeds(n, u0, law.array, rho, 0.7, True, cf, 2.7, 2.0, ue)
    assert np.all(ue == 0.7)


def _wall_room():
    """A 20 x 6 m room; the exit is on the left wall, the right wall (x = 20) is solid."""
    return Room([(0, 0), (20, 0), (20, 6), (0, 6)], exits=[Exit("west", [(0, 2), (0, 4)])])


@pytest.mark.parametrize("shrink", [0.0, 0.05])
@pytest.mark.parametrize("u", [0.02, 0.5])
def test_pressed_against_a_wall_the_gap_is_the_force_balance(shrink, u):
    """One person pushed into a wall by a constant desired velocity u comes to rest where the
    social repulsion of the wall balances the drive: A exp((r_s - d)/B) = m u / tau, with
    r_s = min(r, r - shrink + t_space u / 2): slow, the gap shrinks; fast, it does not."""
    mesh = triangulate(_wall_room(), max_area=4.0)
    p = SocialForceParams(shrink=shrink)
    sim = Simulation(mesh, np.array([[18.0, 3.0]]), params=p,
                     desired_velocity=np.array([u, 0.0]), numerics=SFMNumerics(dt=0.005))
    sim.run(30.0 if u > 0.1 else 150.0)
    d = 20.0 - sim.positions[0, 0]
    r_s = min(p.r, p.r - shrink + 0.5 * p.t_space * u)
    expect = r_s + p.B * math.log(p.A * p.tau / (p.m * u))
    assert abs(float(np.hypot(*sim.velocities[0]))) < 1e-6
    assert d == pytest.approx(expect, abs=1e-6)


def _pressed_crowd(shrink, positions, velocity, t_end=50.0):
    mesh = triangulate(_wall_room(), max_area=4.0)
    p = SocialForceParams(shrink=shrink, A=962.0, tau=0.3, t_space=0.5)
    sim = Simulation(mesh, positions, np.tile(velocity, (len(positions), 1)), params=p,
                     desired_velocity=np.asarray(velocity, float),
                     numerics=SFMNumerics(dt=0.005))
    sim.run(t_end)
    return sim


def _lattice(nx=6, ny=8, spacing=0.6, x0=16.5, y0=0.9):
    g = np.stack(np.meshgrid(x0 + spacing * np.arange(nx), y0 + spacing * np.arange(ny)), -1)
    return g.reshape(-1, 2)


def _nearest(x):
    from scipy.spatial import cKDTree

    d, _ = cKDTree(x).query(x, k=2)
    return d[:, 1]


def test_a_standing_crowd_packs_denser_than_without_the_shrink():
    """A crowd pushed into a wall comes to rest; with the space requirement its people stand
    closer (their social radii are ``shrink`` smaller at rest)."""
    x = _lattice()
    plain = _pressed_crowd(0.0, x, [0.1, 0.0])
    shrunk = _pressed_crowd(0.05, x, [0.1, 0.0])
    for sim in (plain, shrunk):
        assert sim.n == len(x)
        assert np.hypot(*sim.velocities.T).mean() < 0.02  # at rest against the wall
    d0, d1 = np.median(_nearest(plain.positions)), np.median(_nearest(shrunk.positions))
    assert d1 < d0 - 0.03  # r_s = r - 0.025: two partners' radii less (tail aside)
    # the occupied strip at the wall is narrower: the standing crowd is denser
    depth0 = 20.0 - plain.positions[:, 0].min()
    depth1 = 20.0 - shrunk.positions[:, 0].min()
    assert depth1 < 0.9 * depth0


def test_a_walking_crowd_is_the_paper_model_bit_for_bit():
    """Everyone wanting to walk faster than 2 shrink / t_space has social radius r: the run
    is the same, bit for bit, as without the space requirement."""
    x = _lattice(spacing=0.7, x0=3.0)
    v = [1.2, 0.0]
    a = _pressed_crowd(0.0, x, v, t_end=3.0)
    b = _pressed_crowd(0.05, x, v, t_end=3.0)
    assert np.array_equal(a.positions, b.positions)
    assert np.array_equal(a.velocities, b.velocities)


@pytest.mark.parametrize("bad", [-0.01, 0.15, 0.2, float("nan"), float("inf")])
def test_bad_shrink_is_a_clear_error(bad):
    with pytest.raises(ParameterError, match="parameter 'shrink'"):
        SocialForceParams(shrink=bad)


def test_bad_t_space_is_a_clear_error():
    with pytest.raises(ParameterError, match="parameter 't_space'"):
        SocialForceParams(t_space=0.0)


def test_shrink_larger_than_a_population_radius_is_a_clear_error():
    mesh = triangulate(_wall_room(), max_area=4.0)
    x = np.array([[5.0, 3.0], [8.0, 3.0]])
    pop = Population(area=np.zeros(2, np.int64), premovement=np.zeros(2),
                     speed=np.full(2, np.nan), radius=np.array([0.2, 0.05]),
                     target=np.zeros(2, np.int64), targets=[()])
    with pytest.raises(SimulationError, match="shrink"):
        Simulation(mesh, x, params=SocialForceParams(shrink=0.08), population=pop)


def _two(lam, e, A=2000.0, d=0.5):
    """Accelerations of two pedestrians d apart on the x axis (0 behind 1), facing ``e``."""
    p = SocialForceParams()
    x = np.array([[0.0, 0.0], [d, 0.0]])
    v = np.zeros((2, 2))
    pi, pj = np.array([0, 0], np.int64), np.array([1, 0], np.int64)
    F, rho = np.zeros((2, 2)), np.zeros(2)
    rad = np.full(2, p.r)
    K.pair_accel_list(x, v, 2, pi, pj, 1, 0, 1.2, 2.1, rad, A, p.B, p.k, p.kappa, p.m, p.R, F,
                      rho, False, rad, lam, np.asarray(e, float))
    return F, A * math.exp((2 * p.r - d) / p.B) / p.m


def test_vision_weights_the_repulsion_by_where_the_other_is():
    """Both face +x: the one behind (0) sees the other straight ahead (full repulsion), the
    one ahead (1) has the other straight behind (lambda of it); facing each other, both
    feel it fully; side by side, (1 + lambda)/2; lambda 1 is the isotropic force."""
    F, f = _two(0.3, [[1.0, 0.0], [1.0, 0.0]])
    assert F[0] == pytest.approx([-f, 0.0], rel=1e-12)
    assert F[1] == pytest.approx([0.3 * f, 0.0], rel=1e-12)
    F, f = _two(0.3, [[1.0, 0.0], [-1.0, 0.0]])
    assert F[0] == pytest.approx([-f, 0.0], rel=1e-12)
    assert F[1] == pytest.approx([f, 0.0], rel=1e-12)
    F, f = _two(0.3, [[0.0, 1.0], [0.0, 1.0]])
    assert F[0] == pytest.approx([-0.65 * f, 0.0], rel=1e-12)
    F1, _ = _two(1.0, [[1.0, 0.0], [1.0, 0.0]])
    assert np.array_equal(F1, -F1[::-1]) and F1[0, 0] == pytest.approx(-f, rel=1e-12)


def test_vision_leaves_body_contact_isotropic():
    """Overlapping bodies: the contact force k (r_ij - d) acts on both alike whatever they
    see; only the social part is weighted."""
    p = SocialForceParams()
    d = 0.25
    F, f = _two(0.0, [[1.0, 0.0], [1.0, 0.0]], d=d)
    contact = p.k * (2 * p.r - d) / p.m
    assert F[0, 0] == pytest.approx(-(f + contact), rel=1e-12)
    assert F[1, 0] == pytest.approx(contact, rel=1e-12)  # the social part: lambda 0


@pytest.mark.parametrize("bad", [-0.1, 1.5, float("nan")])
def test_bad_vision_is_a_clear_error(bad):
    with pytest.raises(ParameterError, match="parameter 'vision'"):
        SocialForceParams(vision=bad)


# ----------------------------------------------------------------- queueing or crowding
def test_free_width_is_a_corridors_width_and_wide_in_a_hall():
    from shapely.geometry import Polygon

    from pedmesh.models.sfm.crowding import WIDTH_REACH_M, crowd_factors, width_map

    # a 20 x 10 m hall with a 1.5 m wide, 6 m long corridor leaving it on the right
    hall = Polygon([(0, 0), (20, 0), (20, 4.25), (26, 4.25), (26, 5.75), (20, 5.75),
                    (20, 10), (0, 10)])
    wm = width_map(hall)
    corridor = np.column_stack([np.linspace(21.5, 25.5, 9), np.full(9, 5.0)])
    assert np.allclose(wm.at(corridor), 1.5, atol=2 * wm.cell)
    across = np.column_stack([np.full(5, 23.0), np.linspace(4.35, 5.65, 5)])
    assert np.allclose(wm.at(across), 1.5, atol=2 * wm.cell)  # at its walls too
    inner = np.array([[10.0, 5.0], [3.0, 3.0], [5.0, 0.2], [12.0, 9.8]])  # (not corners)
    assert np.all(wm.at(inner) >= 2 * WIDTH_REACH_M - 2 * wm.cell)
    c = np.empty(4)
    pts = np.array([[23.0, 5.0], [10.0, 5.0], [23.0, 5.0], [10.0, 5.0]])
    crowd_factors(pts, 2, wm.width, wm.x0, wm.y0, 1.0 / wm.cell, 1.2, 2.3, c)
    assert c[0] == pytest.approx((1.5 - 1.2) / 1.1, abs=0.05) and c[1] == 1.0
    crowd_factors(pts, 2, wm.width, wm.x0, wm.y0, 1.0 / wm.cell, 1.6, 2.3, c)
    assert c[0] == 0.0  # narrower than the queue width: queueing


def test_crowding_stretch_is_inert_where_everyone_queues():
    """In a corridor narrower than queue_width every crowding factor is 0: the run is the
    same, bit for bit, as without crowding; where people crowd, the stretched law lets
    the dense part walk faster."""
    room = Room([(0, 0), (30, 0), (30, 1.1), (0, 1.1)],
                exits=[Exit("east", [(30, 0), (30, 1.1)])])
    mesh = triangulate(room, max_area=1.0)
    x = np.column_stack([np.linspace(1.0, 8.0, 20), 0.55 + 0.2 * np.sin(np.arange(20))])
    runs = []
    for stretch in (1.0, 3.0):
        p = SocialForceParams(speed_law="weidmann", U_f=1.34, crowd_stretch=stretch,
                              crowd_knee=1.0)
        sim = Simulation(mesh, x, params=p, numerics=SFMNumerics(dt=0.01))
        sim.run(4.0)
        runs.append(sim)
    assert runs[1].width_map is not None and runs[0].width_map is None
    assert np.array_equal(runs[0].positions, runs[1].positions)
    assert np.array_equal(runs[0].velocities, runs[1].velocities)


def test_crowding_people_press_on_where_queueing_ones_stand():
    """The same dense block of people in a wide hall (crowding) and with a queue width
    above the hall's (queueing): crowding, the block moves towards the exit faster."""
    room = Room([(0, 0), (12, 0), (12, 8), (0, 8)], exits=[Exit("east", [(12, 3.5), (12, 4.5)])])
    mesh = triangulate(room, max_area=1.0)
    g = np.stack(np.meshgrid(6.0 + 0.42 * np.arange(10), 2.0 + 0.42 * np.arange(10)), -1)
    x = g.reshape(-1, 2)
    gone = []
    for queue_width in (1.2, 20.0):
        p = SocialForceParams(speed_law="weidmann", U_f=1.34, rho_jam=5.4, crowd_stretch=3.0,
                              crowd_knee=2.0, queue_width=queue_width,
                              crowd_width=queue_width + 1.1, density_self=0)
        sim = Simulation(mesh, x, params=p)
        sim.run(20.0)
        gone.append(sim.n_evacuated)
    assert gone[0] > gone[1] + 5


def test_bad_crowding_parameters_are_clear_errors():
    with pytest.raises(ParameterError, match="parameter 'crowd_stretch'"):
        SocialForceParams(crowd_stretch=0.5)
    with pytest.raises(ParameterError, match="parameter 'crowd_width'"):
        SocialForceParams(queue_width=2.0, crowd_width=1.5)
    with pytest.raises(ParameterError, match="parameter 'queue_width'"):
        SocialForceParams(queue_width=-1.0)


def test_the_equation_of_state_sees_the_standing_crowds_social_radii():
    """pedmesh calibrate measures a standing crowd (desired speed 0, in the open: crowding):
    its social radii are r - shrink, so at a given density it pushes less; a periodic box's
    virial equals the lattice formula with those radii."""
    from pedmesh.calibration import lattice_virial, periodic_virial, standing_social_rij

    plain, shrunk = SocialForceParams(), SocialForceParams(shrink=0.05)
    assert standing_social_rij(plain) == 2 * plain.r
    assert standing_social_rij(shrunk) == pytest.approx(0.2)
    rho = 6.0
    a = math.sqrt(2.0 / (math.sqrt(3.0) * rho))
    nx, ny = 12, 14  # a periodic triangular lattice: ny rows a sqrt(3)/2 apart
    x = np.array([((i + 0.5 * (j % 2)) * a, j * a * math.sqrt(3.0) / 2.0)
                  for j in range(ny) for i in range(nx)])
    L = (nx * a, ny * a * math.sqrt(3.0) / 2.0)
    for p in (plain, shrunk):
        assert periodic_virial(x, L, p) == pytest.approx(lattice_virial(rho, p), rel=1e-9)
    assert lattice_virial(rho, shrunk) < 0.6 * lattice_virial(rho, plain)


def test_two_bodies_at_rest_come_closer_than_at_speed():
    """The distance at which two people's social repulsion balances a given push is smaller
    when they want to stand than when they want to walk: A exp((s_ij - d)/B) = F gives
    d = s_ij + B ln(A/F), with s_ij the sum of their social radii."""
    p = SocialForceParams(shrink=0.05, t_space=0.5)
    rad = np.full(2, p.r)
    dist = {}
    for name, u in (("rest", 0.0), ("walking", 1.3)):
        rs = np.empty(2)
        K.social_radii(2, rad, np.full(2, u), p.shrink, p.t_space, False, rad, rs)
        push = 100.0  # [N]
        lo, hi = 0.05, 1.0  # bisect the distance where the pair force equals the push
        for _ in range(80):
            d = 0.5 * (lo + hi)
            fx, _ = K.pair_force(d, 0.0, d, 0.0, 0.0, 2 * p.r, p.A, 1.0 / p.B, p.k, p.kappa,
                                 rs[0] + rs[1])
            lo, hi = (d, hi) if fx > push else (lo, d)
        dist[name] = d
    assert dist["rest"] == pytest.approx(dist["walking"] - 2 * 0.05, abs=1e-9)


def test_crowding_on_a_bare_mesh_uses_its_triangles():
    """A mesh without its room (built from arrays) still gets a free width map: the union
    of its triangles."""
    import dataclasses

    room = Room([(0, 0), (12, 0), (12, 1.5), (0, 1.5)], exits=[Exit("e", [(12, 0), (12, 1.5)])])
    mesh = triangulate(room, max_area=1.0)
    bare = dataclasses.replace(mesh, room=None) if dataclasses.is_dataclass(mesh) else None
    if bare is None:
        pytest.skip("TriMesh is not a dataclass")
    x = np.array([[2.0, 0.75], [4.0, 0.75]])
    p = SocialForceParams(crowd_stretch=2.0)
    a = Simulation(mesh, x, params=p)
    b = Simulation(bare, x, params=p)
    assert np.array_equal(a.width_map.at(x), b.width_map.at(x))
    assert a.width_map.at(x) == pytest.approx([1.5, 1.5], abs=0.11)
