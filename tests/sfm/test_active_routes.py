"""A building's routes re-solved only where the crowd can change them (issue 45,
:mod:`pedmesh.eikonal.active`): the same numbers as the whole solve, bit for bit (the
potential, the steering table with its stair factors, the social force model's
trajectories), on the shipped office and on a tower with people on one floor and on
several; and the active set is one floor's worth when the crowd stands on one floor. The
pieces it is made of are tested against the computations they replace: the march from a
known state, the crowd's density near it, the cell list."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

import pedmesh
from pedmesh.eikonal import active
from pedmesh.eikonal import fmm_kernels as F
from pedmesh.models.sfm.building import SurfaceSimulation, building_positions

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from building_data import tower  # noqa: E402  (tests/building_data.py)

ROOT = Path(__file__).resolve().parents[2]


def _pair(path, preset: str | None = None):
    """The social force model on the building at ``path`` with the active set (a run of
    :func:`pedmesh.build`, the shipped preset or ``preset``) and the same simulation
    solving the whole building every time (the reference), from the same start."""
    run = pedmesh.build(str(path), model="sfm", seed=0, preset=preset)
    sim = run.sim
    assert sim._active is not None
    x, _ = building_positions(run.building, sim.atlas, seed=0, radius=run.params.r)
    old = active.ACTIVE_SET
    active.ACTIVE_SET = False
    try:
        ref = SurfaceSimulation(sim.atlas, x, params=run.params, numerics=run.numerics,
                                population=run.population, seed=0, own_mesh=sim.own_mesh)
    finally:
        active.ACTIVE_SET = old
    assert ref._active is None
    return sim, ref


def _same_routes(sim, ref) -> None:
    """The potential and the steering table (every row brought up to date; column 20: the
    stair factors) equal to the whole solve's, bit for bit."""
    assert np.array_equal(sim.surface_phi, ref.surface_phi)
    for r in sim._active:
        r.refresh()
    assert np.array_equal(sim._dpack, ref._dpack)


def _walk_both(sim, ref, steps: int) -> None:
    """Step both, the same states after every step; at every route solve the same routes."""
    routes = sim.timers.routes
    for _ in range(steps):
        sim.step()
        ref.step()
        n = sim.n
        assert n == ref.n
        assert np.array_equal(sim.x[:n], ref.x[:n]) and np.array_equal(sim.v[:n], ref.v[:n])
        if sim.timers.routes != routes:
            routes = sim.timers.routes
            _same_routes(sim, ref)
    assert sim.timers.routes == ref.timers.routes
    assert np.array_equal(sim.exit_time, ref.exit_time, equal_nan=True)


@pytest.fixture(scope="module")
def tower_paths(tmp_path_factory):
    d = tmp_path_factory.mktemp("towers")
    out = {}
    for key, b in (("top", tower(6)), ("several", tower(6, crowded=(1, 3, 5))),
                   ("tall", tower(8, count=10))):
        out[key] = d / f"{key}.json"
        out[key].write_text(json.dumps(b))
    return out


def test_the_office_walks_as_with_the_whole_solve_bit_for_bit():
    """geometries/office.json (300 people on five floors, the shipped preset): 15 s of the
    run, the routes solved 15 times, people over the stair edges; every state the same."""
    sim, ref = _pair(ROOT / "geometries" / "office.json")
    _same_routes(sim, ref)
    _walk_both(sim, ref, 1500)
    assert sim.n_crossings > 20 and sim.n_crossings == ref.n_crossings
    assert sim.timers.routes >= 15


@pytest.mark.parametrize("key, preset", [("top", None), ("several", None),
                                         ("several", "paper")])
def test_a_tower_walks_as_with_the_whole_solve_bit_for_bit(tower_paths, key, preset):
    """Six floors, ten people on the top one or on three of them: 8 s, nine route solves
    (the empty building's chain of solves settles on the way: into a cycle of two under
    the shipped preset, a fixed point under the paper's); also under the paper's
    parameters (the route's density the kernel density of width R at the vertices, the
    exponential law, the run's mesh)."""
    sim, ref = _pair(tower_paths[key], preset)
    _same_routes(sim, ref)
    _walk_both(sim, ref, 800)
    r = sim._active[0]
    assert len(r.phases) >= 2 and len(r._bad[-1]) == 0  # (the chain settled)
    assert (r._succ[-1] < len(r.phases) - 1) == (preset is None)  # (a cycle, or not)


def test_route_groups_walk_as_with_the_whole_solve_bit_for_bit(tmp_path):
    """People heading for chosen exits (a route and a steering table per group of exits,
    stacked): the two-storey building with a back door, the ground floor's people split
    between the doors and the first floor's all for the back door; 6 s."""
    import copy

    from building_data import TWO

    b = copy.deepcopy(TWO)
    b["levels"][0]["exits"].append({"name": "back", "polyline": [[20, 3], [20, 5]]})
    b["levels"][0]["start_areas"][0]["exits"] = {"front": 0.4, "back": 0.6}
    b["levels"][1]["start_areas"][0]["exits"] = ["back"]
    path = tmp_path / "b.json"
    path.write_text(json.dumps({"format": "pedmesh-room", "version": 1, "units": "m", **b}))
    sim, ref = _pair(path)
    assert len(sim._active) == 3
    _same_routes(sim, ref)
    _walk_both(sim, ref, 600)


def test_the_active_set_is_the_floor_the_crowd_stands_on(tower_paths):
    """Ten people on the top floor of eight: once the empty building's chain of solves has
    settled, a route solve marches about that floor (and the stair down from it), not the
    building; the steering table is brought up to date there only."""
    run = pedmesh.build(str(tower_paths["tall"]), model="sfm", seed=0)
    sim = run.sim
    s = sim.atlas.surface
    top = s.pieces[s.piece_index("L7")]
    marched, routes = [], sim.timers.routes
    while sim.t < 4.0:
        run.step()
        if sim.timers.routes != routes:
            routes = sim.timers.routes
            marched.append(sim._active[0].last_marched)
    assert len(marched) >= 3
    floor = len(top.vertices)
    assert max(marched[2:]) < 1.5 * floor < 0.25 * s.n_points
    dirty = sim._active[0].dirty
    assert not dirty[sim._active[0].units_near(sim.tri[:sim.n])].any()


def test_march_from_a_known_state_is_the_march(tower_paths):
    """The ordered march from the state after the first k of an earlier march's
    acceptances (:func:`~pedmesh.eikonal.fmm_kernels.march_from`) gives the whole march's
    numbers for costs that differ only above that march's k-th value, lower or higher, on
    triangles and on corner rays."""
    from pedmesh.eikonal.surface import BuildingRoutes

    run = pedmesh.build(str(tower_paths["top"]), model="sfm", seed=0,
                        params={"route_resolution": 0.3})
    routes = BuildingRoutes(run.sim.atlas)
    sv, s = routes.solver, routes.surface
    r = active.ActiveRoutes(routes, np.ones(s.n_points))
    p = r.phases[0]
    rng = np.random.default_rng(5)
    whole = np.empty(s.n_points)
    for k0 in (len(p.order) // 3, 2 * len(p.order) // 3, len(p.order) - 5):
        m = p.phi[p.order[k0]]
        above = np.all(p.phi[s.triangles] >= m, axis=1)
        f = p.f.copy()
        f[above] *= rng.uniform(0.5, 2.0, int(above.sum()))
        src = np.repeat(np.arange(s.n_points), np.diff(sv.ray_ptr))
        rays = p.phi[src] + np.minimum(p.r, 0.5 * p.r) >= m
        ray_cost = np.where(rays, p.r * rng.uniform(0.5, 2.0, len(p.r)), p.r)
        k = int(np.searchsorted(p.pmax, m, side="left"))
        F.march(whole, sv.fixed_vertices, sv._exit_values(None), sv.pts, sv.vt_ptr,
                sv.vt_corner, sv.ds_ptr, sv.ds_corner, sv.ray_ptr, sv.ray_idx, ray_cost, f,
                True, np.empty(0, np.int32))
        part = np.empty(s.n_points)
        pos = np.full(s.n_points, F.ACCEPTED, np.int32)
        fixed = np.zeros(s.n_points, bool)
        fixed[sv.fixed_vertices] = True
        mark = np.zeros(s.n_points, bool)
        F.march_from(part, p.phi, p.rank, p.order, k, pos, fixed, mark, r.rev_ptr, r.rev_idx,
                     sv.pts, sv.vt_ptr, sv.vt_corner, sv.ds_ptr, sv.ds_corner, sv.ray_ptr,
                     sv.ray_idx, ray_cost, f, np.empty(0, np.int32))
        assert np.array_equal(part, whole)
        assert np.all(pos == F.ACCEPTED) and not mark.any()  # (the work arrays back)
        assert not np.array_equal(whole, p.phi)


def test_the_crowds_density_near_it_is_the_grids(tower_paths):
    """:meth:`~pedmesh.analysis.fields.GridKernelDensity.near` gives the grid density's
    numbers where it is above 0, and it is 0 everywhere else: one person, a group, groups
    on floors far apart in the atlas."""
    run = pedmesh.build(str(tower_paths["top"]), model="sfm", seed=0,
                        params={"route_resolution": 0.3})
    grid, pts = run.sim._route_grid, run.sim.mesh.points
    rng = np.random.default_rng(1)
    for n_groups, size in ((1, 1), (1, 10), (3, 4), (5, 1)):
        x = np.concatenate([pts[rng.integers(len(pts))] + rng.normal(0, 1.0, (size, 2))
                            for _ in range(n_groups)])
        full = grid(x)
        where, rho = grid.near(x)
        assert len(np.unique(where)) == len(where)
        assert np.array_equal(full[where], rho)
        rest = np.ones(len(full), bool)
        rest[where] = False
        assert not np.any(full[rest] != 0.0) and np.any(rho > 0)


def test_the_cell_list_updated_in_place_is_the_cell_list():
    """:func:`~pedmesh.models.sfm.kernels.update_cells` (only the cells about the crowd)
    leaves the arrays :func:`~pedmesh.models.sfm.kernels.build_cells` makes, whatever list
    they held, people coming and going."""
    from pedmesh.models.sfm import kernels as K

    rng = np.random.default_rng(0)
    nx, ny = 40, 37
    start, order = np.zeros(nx * ny + 1, np.int64), np.zeros(60, np.int64)
    for trial in range(200):
        n = int(rng.integers(0, 50))
        x = rng.uniform(0, 40, 2) + rng.normal(0, rng.uniform(0.1, 10), (n, 2))
        want_s, want_o = np.zeros(nx * ny + 1, np.int64), np.zeros(60, np.int64)
        K.build_cells(x, n, 0.0, 0.0, 1.0, nx, ny, want_s, want_o)
        if trial % 7 == 3:
            K.build_cells(x[: n // 2], n // 2, 0.0, 0.0, 1.0, nx, ny, start, order)
        K.update_cells(x, n, 0.0, 0.0, 1.0, nx, ny, start, order)
        assert np.array_equal(start, want_s) and np.array_equal(order[:n], want_o[:n])


@pytest.mark.parametrize("law", [dict(name="exponential"), dict(name="exponential", shift=0.8),
                                 dict(name="weidmann"),
                                 dict(name="table", table="0:1 0.5:0.99 1:0.923 2:0.626 "
                                                          "3:0.296 5.6:0")])
def test_a_crowd_never_makes_a_route_cheaper(law):
    """Every speed law's route cost 1/U_e(rho) grows with the density (U_e falls), so the
    costs a crowd changes are above the empty building's and the active set stays behind
    the crowd. (Its results do not depend on it: a cost below the empty building's would
    only make the active set larger, :func:`test_march_from_a_known_state_is_the_march`.)"""
    from pedmesh.speed import SpeedLaw

    cost = SpeedLaw(**law).route_cost(np.linspace(0.0, 12.0, 4801))
    assert np.all(np.diff(cost) >= 0.0) and np.all(cost >= cost[0])
