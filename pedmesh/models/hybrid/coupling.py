"""A first coupled run of agents and a continuum (issue 47, a prototype from Python: not
in the model registry, no output folder).

:class:`HybridRun` keeps the social force model's :class:`~pedmesh.models.sfm.Simulation`
on the whole mesh for the people in the agent zone, and ``eos`` on the rest
(:func:`~pedmesh.models.hybrid.interface.split_mesh`). Every ``sync_dt`` [s] the two meet:

1. the continuum advances to the meeting time; what it passed through each interface edge
   is added to that edge's account (:attr:`HybridRun.accounts`, people);
2. the agents step to the meeting time;
3. agents who stand outside the zone are withdrawn from the agents and their mass and
   momentum added to the continuum cell they stand in
   (:func:`~pedmesh.models.hybrid.interface.deposit`);
4. when the continuum's cells count as empty, its last film goes to an interface account;
5. each connected line of interface edges gives whole people to the agents when its
   accounts hold one: a person held by the continuum enters on the zone's side of one of
   its edges (where most crossed first, the first with room) with the continuum's
   velocity there (:meth:`~pedmesh.models.sfm.Simulation.enter`); where there is no room
   they stay in the account.

So every person is in one place at every meeting: a continuum cell (a fraction of a
person per cell), an agent, an interface account, or out through an exit of either model
(:meth:`HybridRun.count`, to round-off).

One crowd for the routes of both: the agents' route cost reads the continuum's crowd as
well (its cell densities averaged to the mesh's vertices), and at each of the agents'
route solves the continuum's potential is solved from the same density and cost law
(before the first: the empty room's). It leaves out the agents' wall clearance
(``route_clearance``: a route for a body's centre; a continuum fills the passage's width):
with it the continuum, squeezed off the walls, reached the corridor bottleneck's T50 / T90
/ T100 3-4 % late (``benchmarks/hybrid.py``; without it within 1 %).

Open (issue 47), which makes this a prototype: the agents do not see the continuum's
crowd in their desired speed and forces; the continuum's flux into the zone is not limited
by the room the agents have (what does not fit waits in the accounts); no density trigger;
no output folder.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ... import parameters as P
from ...errors import ParameterError
from ...mesh.triangle_mesh import TriMesh
from .interface import deposit, split_mesh

__all__ = ["HybridRun", "HybridCount"]

#: [ped] the continuum's cells count as empty below this (the continuum runs' empty_below)
EMPTY_BELOW = P.get("empty_below").default
#: [ped] an account this close below a whole person gives one (round-off of the sums)
WHOLE_TOL = 1e-9
#: [m] how far into its agent triangle a person entering from an interface edge starts,
#: from the edge's midpoint towards the triangle's centroid (at most the whole way)
ENTRY_DEPTH = 0.3


@dataclass(frozen=True)
class HybridCount:
    """Where the people of a hybrid run are [ped]: in the continuum's cells, as agents, in
    the interface accounts, out through the continuum's exits and out through the agents'
    exits; ``total`` their sum (the initial crowd, to round-off)."""

    cells: float
    agents: int
    accounts: float
    out_continuum: float
    out_agents: int

    @property
    def total(self) -> float:
        return self.cells + self.agents + self.accounts + self.out_continuum + self.out_agents


class HybridRun:
    """Agents in ``zone`` ((m,) bool over the triangles of ``mesh``, a room's mesh with its
    start areas), ``eos`` elsewhere; meeting every ``sync_dt`` [s] (see the module
    docstring). ``preset``: both models' parameters from that preset (:mod:`pedmesh.presets`;
    None: the models' defaults, the paper's; the agents walk on the run's mesh, without the
    route mesh a preset's ``route_resolution`` asks for); ``seed``: the start lattice's
    jitter (:func:`~pedmesh.models.sfm.placement.seeded_positions`). Everyone is alike (the
    start areas' premovement, speeds, radii and exits are not read yet)."""

    def __init__(self, mesh: TriMesh, zone: np.ndarray, *, sync_dt: float = 0.1,
                 preset: str | None = None, seed: int | None = None) -> None:
        from ...eikonal import EikonalSolver
        from ...eikonal.direction import DirectionField
        from ...presets import preset_overrides
        from ..continuum.adapter import ContinuumEntry
        from ..continuum.solver import FVController, FVOptions, FVSolver, FVState
        from ..registry import get_model
        from ..sfm import Simulation
        from ..sfm.params import SFMNumerics, SocialForceParams, with_overrides

        if not (np.isfinite(sync_dt) and sync_dt > 0):
            raise ParameterError(f"sync_dt must be a time > 0 [s], got {sync_dt!r}")
        self.mesh = mesh
        self.zone = np.asarray(zone, bool).ravel()
        self.sync_dt = float(sync_dt)
        self.part = split_mesh(mesh, self.zone)
        sub = self.part.mesh
        self._sub_of = np.full(mesh.n_triangles, -1, np.int64)
        self._sub_of[self.part.cells] = np.arange(len(self.part.cells))
        # the continuum's directions: the empty room's routes on the whole mesh
        self._eikonal = EikonalSolver(mesh)
        self._routes = DirectionField(mesh, self._eikonal.solve(1.0))
        # each model with the preset's values (default: the models' own, the paper's);
        # the agents walk on the run's mesh (no route mesh of their own yet)
        sfm = preset_overrides(preset, get_model("sfm").parameter_names) if preset else {}
        params, numerics = with_overrides(sfm, SocialForceParams(), SFMNumerics())
        numerics = dataclasses.replace(numerics, route_resolution=None)
        positions = None
        if seed is not None:
            from ..sfm.placement import seeded_positions

            positions = seeded_positions(mesh.room, int(seed), radius=params.r)
        self.sim = Simulation(mesh, positions, params=params, numerics=numerics)
        self.n_initial = self.sim.n_initial
        entry = get_model("eos")
        assert isinstance(entry, ContinuumEntry)
        own = {p.name for p in entry.model_parameters}
        cont = preset_overrides(preset, entry.parameter_names, continuum=True) if preset \
            else {}
        model = entry.physics(**P.check_values({k: v for k, v in cont.items() if k in own},
                                                entry.model_parameters))
        self.solver = FVSolver(sub, model, FVOptions(), direction=self._direction)
        self.state = FVState(np.zeros((sub.n_triangles, self.solver.model.n_vars)))
        self.controller = FVController(self.solver, self.state)
        self.accounts = np.zeros(self.part.n_interface)
        #: (k,) the group of each interface edge: the edges of one connected line along
        #: the zone's edge pool their accounts (a person enters when the group holds one,
        #: where its edges hold the most), else fractions below one person per edge stay
        self.groups = self._groups()
        self._through = np.zeros(self.part.n_interface)  # interface outflow already booked
        self._held: list[int] = []  # ids the continuum holds (they enter first in, first out)
        self._entry_points = self._entries()
        self._routes_seen = -1
        self._to_continuum()
        self._share_routes()

    # ------------------------------------------------------------------ set-up
    def _direction(self, x, y) -> np.ndarray:
        """The desired direction (..., 2) of the empty room's routes at points (x, y) [m]."""
        x = np.asarray(x, float)
        pts = np.stack([x.ravel(), np.asarray(y, float).ravel()], axis=1)
        tri = self.mesh.locate(pts)
        e = np.zeros_like(pts)
        ok = tri >= 0
        e[ok] = self._routes.at(pts[ok], tri[ok])
        return e.reshape(x.shape + (2,))

    def _groups(self) -> np.ndarray:
        """(k,) the connected line (0, 1, ...) each interface edge belongs to (edges that
        share a vertex are connected)."""
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components

        k = self.part.n_interface
        if k == 0:
            return np.zeros(0, np.int64)
        ends = self.mesh.edges[self.part.interface]  # (k, 2) parent vertices
        rows = np.repeat(np.arange(k), 2)
        inc = coo_matrix((np.ones(2 * k), (rows, ends.ravel())),
                         shape=(k, self.mesh.n_points)).tocsr()
        _, labels = connected_components(inc @ inc.T, directed=False)
        return labels.astype(np.int64)

    def _entries(self) -> np.ndarray:
        """(k, 2) [m] where a person given by interface edge j enters: ENTRY_DEPTH from the
        edge's midpoint towards the centroid of its agent triangle."""
        mid = self.mesh.edge_midpoints[self.part.interface]
        cen = self.mesh.centroids[self.part.interface_agent_cell]
        d = cen - mid
        dist = np.hypot(d[:, 0], d[:, 1])
        step = np.minimum(ENTRY_DEPTH, dist) / np.maximum(dist, 1e-12)
        return mid + d * step[:, None]

    # ------------------------------------------------------------------ hand-over
    def _to_continuum(self) -> None:
        """Agents outside the zone to the continuum cell they stand in."""
        sim = self.sim
        n = sim.n
        if n == 0:
            return
        tri = sim.tri[:n]
        out = ~self.zone[tri]
        if not out.any():
            return
        cells = self._sub_of[tri[out]]
        ids, _, v = sim.withdraw(out)
        Q = self.state.Q
        for i, c, vel in zip(ids, cells, v):
            deposit(Q, self.solver.areas, int(c), 1.0, vel)
            self._held.append(int(i))
        self.controller.mass0 += len(ids)

    def _to_agents(self) -> int:
        """Whole people of the interface accounts to the agents, where there is room;
        returns how many entered."""
        through = self.part.interface_outflow(self.state.outflow)
        self.accounts += through - self._through
        self._through = through.copy()
        entered = 0
        Q = self.state.Q
        for g in range(int(self.groups.max(initial=-1)) + 1):
            edges = np.flatnonzero(self.groups == g)
            while self._held and self.accounts[edges].sum() >= 1.0 - WHOLE_TOL:
                # the line's edges where most crossed first, the first with room
                for j in edges[np.argsort(-self.accounts[edges], kind="stable")]:
                    vel = self._velocity(Q, self.part.interface_cell[j])
                    if self.sim.enter(np.array([self._held[0]]),
                                      self._entry_points[j][None, :], vel[None, :])[0]:
                        break
                else:
                    break  # no room anywhere on the line now: they wait in the account
                self._held.pop(0)
                self._take_one(edges)
                entered += 1
        return entered

    def _velocity(self, Q: np.ndarray, c: int) -> np.ndarray:
        """The continuum's velocity [m/s] (2,) in cell ``c``, as the model reads it (its
        vacuum density and largest speed: a film's momentum over its density is not a
        walking speed)."""
        if Q.shape[1] < 3:
            return np.zeros(2)
        return np.asarray(self.solver.model.velocity(Q[c][None, :]), float)[0]

    def _take_one(self, edges: np.ndarray) -> None:
        """One person less in the accounts of ``edges`` (which hold at least one together):
        from the fullest edge first, so that no account goes below zero."""
        need = 1.0
        for j in edges[np.argsort(-self.accounts[edges], kind="stable")]:
            take = min(need, self.accounts[j])
            self.accounts[j] -= take
            need -= take
            if need <= 0.0:
                break
        # (what is missing of a whole person, at most WHOLE_TOL, is round-off)

    # ------------------------------------------------------------------ running
    def step(self) -> None:
        """One meeting interval: the continuum, then the agents, then the hand-overs."""
        t1 = self.state.t + self.sync_dt
        self.controller.advance(t1)
        sim = self.sim
        while sim.t < t1 - 1e-9 and (sim.n or sim.n_waiting or sim.n_withdrawn):
            sim.step()
        self._to_continuum()
        self._sweep()
        self._to_agents()
        self._share_routes()

    def _share_routes(self) -> None:
        """One crowd for both routes: the agents' route cost reads the continuum's crowd too
        (its cell densities averaged to the mesh's vertices, :attr:`Simulation.
        extra_route_density <pedmesh.models.sfm.Simulation.extra_route_density>`), and
        after each of the agents' route solves the continuum's potential is solved from
        the same density (see the module docstring)."""
        from ...eikonal.direction import DirectionField, _vertex_averaging

        rho = self.part.to_parent(np.maximum(self.state.Q[:, 0], 0.0))
        self.sim.extra_route_density = _vertex_averaging(self.mesh) @ rho
        solves = self.sim.timers.routes
        if solves != self._routes_seen and solves > 0:
            # the same crowd and cost law as the agents' solve, without their walls'
            # clearance (a route for a body's centre; the continuum fills the width)
            cost = self.sim.params.speed.route_cost(self.sim.route_rho)
            self._routes = DirectionField(self.mesh, self._eikonal.solve(cost))
            self.solver.set_direction(self._direction)
            self._routes_seen = solves

    def _sweep(self) -> None:
        """When the continuum's cells count as empty (fewer than EMPTY_BELOW people: their
        last film does not move) but its people are not all out, the film's mass goes to
        the account of the interface line holding the most, exactly (cells emptied, the
        account raised by what they held), so that the last people still become agents."""
        if not len(self.groups) or not self._held:
            return
        cells = self.solver.mass(self.state.Q)
        if not 0.0 < cells < EMPTY_BELOW:
            return
        sums = self._group_sums()
        if sums.max() <= 0.0:
            return  # (nothing crossed anywhere yet: the film waits)
        edges = np.flatnonzero(self.groups == int(np.argmax(sums)))
        j = int(edges[np.argmax(self.accounts[edges])])
        self.state.Q[:] = 0.0
        self.accounts[j] += cells
        self.controller.mass0 -= cells

    @property
    def t(self) -> float:
        return self.state.t

    def count(self) -> HybridCount:
        """Where everyone is now (:class:`HybridCount`)."""
        out = self.state.outflow
        return HybridCount(cells=self.solver.mass(self.state.Q), agents=int(self.sim.n),
                           accounts=float(self.accounts.sum()),
                           out_continuum=float(self.part.exit_outflow(out).sum()),
                           out_agents=int(self.sim.n_evacuated))

    @property
    def finished(self) -> bool:
        """Nothing is left to happen: no agents, the continuum's cells empty as a continuum
        run counts a room empty (fewer than ``empty_below``, 0.5 people: its last film does
        not move) and less than one person in each interface group's account (a fraction
        that will never make a person; :meth:`count` keeps it)."""
        c = self.count()
        if c.agents or c.cells >= EMPTY_BELOW:
            return False
        return bool(np.all(self._group_sums() < 1.0))

    def _group_sums(self) -> np.ndarray:
        """The people in each interface line's accounts (one value per group)."""
        return np.bincount(self.groups, weights=self.accounts)
