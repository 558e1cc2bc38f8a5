"""Groundwork of the hybrid model (issue 47): the agent zone, the continuum's sub-mesh with
each interface edge an exit of its own, and the exact count of what crosses (the solver's
per-exit outflow), with the deposit of agents back into the continuum."""

from __future__ import annotations

import numpy as np
import pytest

from pedmesh import Exit, Obstacle, Room
from pedmesh.errors import ParameterError
from pedmesh.mesh import triangulate
from pedmesh.mesh.triangle_mesh import BoundaryKind
from pedmesh.models.continuum import macro_model
from pedmesh.models.continuum.quadrature import cell_averages
from pedmesh.models.continuum.solver import FVController, FVOptions, FVSolver, FVState
from pedmesh.models.hybrid import deposit, split_mesh, zone_cells
from pedmesh.models.hybrid.interface import INTERFACE_PREFIX

ZONE = [(8.0, -1.0), (12.0, -1.0), (12.0, 5.0), (8.0, 5.0)]  # [m] across the corridor


@pytest.fixture(scope="module")
def corridor():
    room = Room([(0, 0), (20, 0), (20, 4), (0, 4)], exits=[Exit("out", [(20, 0), (20, 4)])],
                obstacles=[Obstacle("pillar", [(15, 1.5), (16, 1.5), (16, 2.5), (15, 2.5)])])
    return triangulate(room, max_area=0.2)


def _east(x, y):
    e = np.zeros(np.shape(x) + (2,))
    e[..., 0] = 1.0
    return e


def test_zone_cells(corridor):
    mesh = corridor
    c = mesh.centroids
    z = zone_cells(mesh, [ZONE])
    np.testing.assert_array_equal(z, (c[:, 0] >= 8.0) & (c[:, 0] <= 12.0))
    near = zone_cells(mesh, near_exits=2.0)
    assert near.any() and np.all(c[near, 0] >= 18.0 - 1e-9)
    assert not zone_cells(mesh).any()
    for bad in ([[(0, 0), (1, 1)]], [[(0, 0), (1, 1), (1, 0), (0, 1)]]):
        with pytest.raises(ParameterError, match="agent zone 0"):
            zone_cells(mesh, bad)
    with pytest.raises(ParameterError, match="near_exits"):
        zone_cells(mesh, near_exits=-1.0)


def test_split_keeps_the_boundary_and_makes_each_interface_edge_an_exit(corridor):
    mesh = corridor
    z = zone_cells(mesh, [ZONE])
    part = split_mesh(mesh, z)
    sub = part.mesh
    assert sub.n_triangles == (~z).sum()
    np.testing.assert_allclose(sub.areas, mesh.areas[part.cells])
    assert sub.total_area == pytest.approx(mesh.total_area - mesh.areas[z].sum(), rel=1e-12)
    # two jagged lines across the 4 m corridor, along the zone's sides (centroids decide)
    assert 8.0 <= mesh.edge_lengths[part.interface].sum() < 12.0
    x = mesh.edge_midpoints[part.interface, 0]
    assert np.all((np.abs(x - 8.0) < 1.0) | (np.abs(x - 12.0) < 1.0))
    assert sub.exit_names[:part.n_exits] == mesh.exit_names
    assert sub.exit_names[part.n_exits:] == tuple(
        f"{INTERFACE_PREFIX}{j}" for j in range(part.n_interface))
    for j in range(part.n_interface):  # one edge per interface exit, the parent's edge
        (e,) = sub.exit_edges(part.n_exits + j)
        pts = np.sort(sub.points[sub.edges[e]], axis=0)
        np.testing.assert_allclose(pts, np.sort(mesh.points[mesh.edges[part.interface[j]]],
                                                axis=0))
        assert sub.edge_triangles[e, 0] == part.interface_cell[j]
        assert z[part.interface_agent_cell[j]]
    # the room's exit, walls and obstacle as they were
    assert sub.exit_lengths[0] == pytest.approx(4.0)
    kinds = sub.edge_kind[sub.boundary_edges]
    obstacle = mesh.edge_lengths[mesh.edge_kind == BoundaryKind.OBSTACLE].sum()
    assert sub.edge_lengths[sub.edge_kind == BoundaryKind.OBSTACLE].sum() == \
        pytest.approx(obstacle)
    assert set(np.unique(kinds)) <= {BoundaryKind.WALL, BoundaryKind.OBSTACLE,
                                     BoundaryKind.EXIT}
    field = part.to_parent(np.arange(sub.n_triangles, dtype=float), fill=-1.0)
    assert np.all(field[z] == -1.0) and np.all(field[~z] >= 0)
    with pytest.raises(ParameterError, match="whole mesh"):
        split_mesh(mesh, np.ones(mesh.n_triangles, bool))
    with pytest.raises(ParameterError, match="one flag per triangle"):
        split_mesh(mesh, z[:-1])


def test_split_refuses_a_building():
    from pedmesh.mesh.atlas import GluedMesh

    class Glued(GluedMesh):  # (its type is what is checked, not its contents)
        def __init__(self):
            pass

    with pytest.raises(ParameterError, match="room's mesh only"):
        split_mesh(Glued(), np.zeros(3, bool))


def test_the_interface_counts_every_person_exactly(corridor):
    """eos on the continuum's part, a crowd walking east into the agent zone: the mass
    inside plus what left through the room's exit and through each interface edge is the
    initial crowd to round-off; handing what crossed straight back to the cells beyond the
    zone (as agents would, walking through it) keeps the count, and those people then
    leave through the room's exit. (The interface edges are exits into empty space here:
    the people handed back next to the zone's far side partly expand back into it, which
    the coupling will have to stop by limiting the flux to what the agents take.)"""
    mesh = corridor
    part = split_mesh(mesh, zone_cells(mesh, [ZONE]))
    sub = part.mesh

    def init(x, y):
        return np.stack([np.where(x < 6, 2.0, 0.0), 0 * x, 0 * x], -1)

    s = FVSolver(sub, macro_model("eos"), FVOptions(), direction=_east)
    st = FVState(cell_averages(sub, init, subdivisions=2))
    c = FVController(s, st)
    n0 = s.mass(st.Q)
    # the continuum cells just beyond the zone, where agents would hand people back
    beyond = part.interface_cell[sub.centroids[part.interface_cell, 0] > 10.0]
    handed = np.zeros(part.n_interface)
    returned = 0.0
    while st.t < 40.0 - 1e-9:
        c.advance(min(st.t + 1.0, 40.0))
        inside, out = s.mass(st.Q), st.outflow
        through = part.interface_outflow(out)
        assert np.all(through >= -1e-12)
        assert abs(inside + out.sum() - returned - n0) < 1e-12 * n0
        new = through - handed  # crossed since the last hand-back: give it back beyond
        for k, cell in enumerate(np.resize(beyond, len(new))):
            if new[k] > 0:
                deposit(st.Q, sub.areas, int(cell), float(new[k]), (1.0, 0.0))
        returned += new.sum()
        handed = through.copy()
        assert abs(s.mass(st.Q) + out.sum() - returned - n0) < 1e-12 * n0
    # every edge of the zone's near side took people; some have left by the real exit
    near = sub.centroids[part.interface_cell, 0] < 10.0
    assert np.all(handed[near] > 0) and handed[~near].sum() < handed[near].sum()
    assert part.exit_outflow(st.outflow)[0] > 0.1 * n0
    assert st.Q[:, 0].min() >= 0.0


def test_deposit_adds_exactly_the_agent():
    Q = np.zeros((3, 3))
    areas = np.array([0.5, 2.0, 1.0])
    deposit(Q, areas, 1, 1.0, (0.8, -0.2))
    assert Q[1, 0] * areas[1] == pytest.approx(1.0, rel=1e-15)
    np.testing.assert_allclose(Q[1, 1:] * areas[1], [0.8, -0.2], rtol=1e-15)
    assert np.all(Q[[0, 2]] == 0)
    with pytest.raises(ParameterError, match="mass"):
        deposit(Q, areas, 0, -1.0)


def test_a_coupled_run_keeps_every_person():
    """HybridRun (the prototype): a crowd walks through a corridor whose middle is the
    agent zone. At every meeting the continuum's cells, the agents, the interface accounts
    and who left through either model's exit add up to the initial crowd to round-off;
    people cross into the zone as agents and out of it into the continuum again, and
    everyone leaves."""
    from pedmesh import StartArea
    from pedmesh.models.hybrid import HybridRun

    room = Room([(0, 0), (30, 0), (30, 4), (0, 4)], exits=[Exit("out", [(30, 0), (30, 4)])],
                start_areas=[StartArea("crowd", [(1, 0.5), (9, 0.5), (9, 3.5), (1, 3.5)],
                                       count=60)])
    mesh = triangulate(room, max_area=0.3)
    zone = zone_cells(mesh, [[(12, -1), (16, -1), (16, 5), (12, 5)]])
    run = HybridRun(mesh, zone, seed=1)
    N = run.n_initial
    c = run.count()
    assert c.agents == 0 and c.cells == pytest.approx(N, rel=1e-12)  # (no start in the zone)
    most_agents = 0
    while not run.finished and run.t < 120.0:
        run.step()
        c = run.count()
        assert abs(c.total - N) < 1e-9 * N, c
        assert c.accounts >= -1e-9 and c.cells >= -1e-9
        most_agents = max(most_agents, c.agents)
        # one crowd for both routes: the agents' route reads the continuum's density
        assert run.sim.extra_route_density is not None
        if c.cells > 1.0:
            assert run.sim.extra_route_density.max() > 0.0
        assert run._routes_seen == run.sim.timers.routes
    assert run.finished, run.count()
    assert most_agents >= 5  # (people did cross into the zone as agents)
    c = run.count()
    # the exit lies in the continuum; what is left is less than a person per interface line
    groups = run.groups.max() + 1
    assert groups == 2 and c.accounts < groups and c.cells < 0.5
    assert c.out_continuum > N - groups - 0.5


def test_a_passing_crowd_switches_each_cell_twice_despite_a_flickering_density():
    """A bump of density [ped/m^2] walks along a line of cells at 1 m/s, its density
    flickering by +-0.3 ped/m^2 each step: every cell it passes joins the zone once and
    leaves it once; a fixed cell never leaves; a thin crowd never joins."""
    from pedmesh.models.hybrid import DensityTrigger

    x = np.arange(60) * 0.5  # [m] cell centres
    fixed = np.zeros(len(x), bool)
    fixed[:3] = True
    trig = DensityTrigger(fixed, rho_on=3.0, rho_off=2.0, dwell=1.0)
    rng = np.random.default_rng(1)
    for k in range(400):
        t = 0.1 * k
        rho = 4.0 * np.exp(-0.5 * ((x - (t - 5.0)) / 2.0) ** 2)
        rho += rng.uniform(-0.3, 0.3, len(x))
        trig.update(np.maximum(rho, 0.0), t)
        assert trig.zone[:3].all()
    passed = (x > 2.0) & (x < 30.0)
    assert np.all(trig.switches[passed] <= 2) and np.all(trig.switches[10:50] == 2)
    assert trig.switches[:3].sum() == 0
    thin = DensityTrigger(np.zeros(5, bool), rho_on=3.0, rho_off=2.0, dwell=0.0)
    assert len(thin.update(np.full(5, 2.9), 0.0)[0]) == 0 and not thin.zone.any()


def test_density_trigger_refuses_bad_thresholds():
    from pedmesh.errors import ParameterError
    from pedmesh.models.hybrid import DensityTrigger

    for kw, match in (({"rho_on": 2.0, "rho_off": 2.0, "dwell": 1.0}, "must be below"),
                      ({"rho_on": -1.0, "rho_off": 0.5, "dwell": 1.0}, "rho_on"),
                      ({"rho_on": 3.0, "rho_off": 2.0, "dwell": -1.0}, "dwell")):
        with pytest.raises(ParameterError, match=match):
            DensityTrigger(np.zeros(3, bool), **kw)
    trig = DensityTrigger(np.zeros(3, bool), rho_on=3.0, rho_off=2.0, dwell=1.0)
    with pytest.raises(ParameterError, match="2 densities for 3 cells"):
        trig.update(np.zeros(2), 0.0)
