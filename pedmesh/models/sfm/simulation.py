"""The social force model on a triangle mesh (paper eq. sf, with the eikonal route choice).

.. math::

    \\frac{dx_i}{dt} = v_i, \\qquad
    m\\frac{dv_i}{dt} = m\\frac{U_e(\\rho_i) e(x_i) - v_i}{\\tau}
        + \\sum_{j \\ne i} f_{ij} + \\sum_{\\text{walls}} f_i^{wall}

* ``f_ij = [A exp((r_ij - d)/B) + k g(r_ij - d)] n_ij + kappa g(r_ij - d) <v_j - v_i, t_ij> t_ij``
  (evaluated once per pair, cut off at ``force_cutoff``);
* walls: the same form for every wall and obstacle edge of the mesh (distance to the
  segment, a shared corner counted once), with friction ``-kappa g(r_i - d) <v_i, t> t``
  against the resting wall. The paper prints ``+kappa ...`` for the wall friction, which
  would accelerate a pedestrian sliding along a wall; the pair term with v_wall = 0 gives
  the minus sign used here. Exit edges exert no force;
* ``U_e = U_f g(rho)`` (the speed law of :mod:`pedmesh.speed`, the paper's ``exp(-beta
  rho)`` by default) with ``rho`` the Gaussian kernel density (eq3, eq4, the
  pedestrian itself included), ``e = -grad(phi)/|grad(phi)|`` with ``|grad phi| = 1/U_e``
  solved on the mesh from the kernel density at the vertices, every ``route_interval`` s;
* Shu-Osher SSP-RK3 in time; after each step a pedestrian whose step crossed a wall is
  reflected (displacement and velocity), and one whose step crossed an exit is removed
  with its exit time (interpolated within the step) and exit.
"""

from __future__ import annotations

import math
import time
from collections import deque
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..._arrays import readonly
from ...errors import ParameterError, SimulationError
from ...mesh.triangle_mesh import TriMesh
from .forces import unit_rows
from .params import SFMNumerics, SocialForceParams
from .walls import WallSet

__all__ = ["Simulation", "PAIR_SKIN", "PARALLEL_MIN_PEOPLE", "PARALLEL_MIN_PEOPLE_TBB"]

#: crowds smaller than this take their steps on one thread (with ``threads`` None) under
#: numba's OpenMP or workqueue threading layer, whose threads cost more to start and, on
#: busy cores, wait for each other (see :data:`pedmesh.models.continuum.solver.
#: PARALLEL_MIN_CELLS`); the steps give the same results on any number of threads
PARALLEL_MIN_PEOPLE = 5_000
#: the same under numba's TBB threading layer. A step launches about 20 parallel loops;
#: measured on 2 cores, a launch costs 1-1.5 us under TBB, and a step of 2,400 people
#: (Example 2) 0.8-1.3 ms on one thread: from about 1,000 people the launches cost a few
#: per cent of a step. (Not a measured break-even: the shared development machine gave
#: the second thread too little of a core to measure one.)
PARALLEL_MIN_PEOPLE_TBB = 1_000
#: Verlet skin [m] of the per-step pair list (rebuilt within a step if anyone moves more
#: than half of it)
PAIR_SKIN = 0.2
#: [m] free gap between an arriving pedestrian's body and everyone else's (entrances)
ENTRANCE_GAP = 0.05


@dataclass
class _Timers:
    forces: float = 0.0
    settle: float = 0.0
    routing: float = 0.0
    steps: int = 0
    routes: int = 0
    extra: dict = field(default_factory=dict)


class Simulation:
    """A social force simulation on a mesh.

    Parameters
    ----------
    mesh
        The room's triangle mesh (``mesh.room`` supplies the start areas if ``positions`` is
        not given).
    positions
        (N, 2) initial positions [m]; default: the room's start areas.
    velocities
        (N, 2) initial velocities [m/s]; default: at rest.
    params
        Physical parameters (paper Table 1 by default).
    numerics
        Time step, routing interval, cut-offs, output intervals.
    desired_velocity
        A constant desired velocity (2,) [m/s] replacing ``U_e e`` (e.g. for the paper's
        Proposition on moments); default: the eikonal route choice.
    reroute
        Re-solve the route potential from the current density (default). ``False`` keeps
        the routes of the initial crowd (static routes).
    population
        Per-pedestrian attributes (:class:`pedmesh.population.Population`, in the order of
        the positions): free speed, body radius (NaN: ``params.U_f``, ``params.r``),
        premovement time (a pedestrian wants no speed before it), the exits each heads
        for (one route potential per distinct set of exits) and the arrival times of an
        entrance's people (:attr:`Population.arrival`; they enter in their start area, on
        the free spot farthest from everyone, once their time has come and there is room;
        those of one area in the order of their times). Default: everyone alike, in the
        room from the start.
    own_mesh
        The mesh is the model's own route mesh (:mod:`pedmesh.mesh.route_mesh`), fine at
        doors and walls: each straight wall piece is one wall segment
        (:meth:`WallSet.from_mesh`, the same forces), and at every route solve the crowd's
        rows are put in the order of their triangles (the mesh's space-filling order), so
        that the kernels read the large mesh tables from nearby memory.
    seed
        With a seed, each entering person's spot is moved by a uniform random offset of
        up to ``ENTRANCE_GAP / 2`` in x and y (so that seeds give different realisations
        of a run with entrances, as jittered start positions do for start areas); None:
        the lattice spots.

    Raises
    ------
    SimulationError
        A start position is outside the walkable area or two pedestrians overlap by more
        than ``numerics.overlap_tolerance``.
    """

    model_name = "sfm"
    #: a building's stair edges (:class:`~pedmesh.models.sfm.building.SurfaceSimulation`)
    _hinges = None

    def __init__(self, mesh: TriMesh, positions: np.ndarray | None = None,
                 velocities: np.ndarray | None = None, *,
                 params: SocialForceParams | None = None,
                 numerics: SFMNumerics | None = None,
                 desired_velocity: np.ndarray | None = None,
                 reroute: bool = True, population=None, seed: int | None = None,
                 own_mesh: bool = False) -> None:
        self.mesh = mesh
        self._rng = None if seed is None else np.random.default_rng(seed)
        self.params = params or SocialForceParams()
        self.numerics = numerics or SFMNumerics()
        x, tri = self._start_positions(positions)
        N = len(x)
        self._set_population(population, N)
        v = self._start_velocities(velocities, x)
        self.n_initial = N
        self.ids = np.arange(N, dtype=np.int64)
        present = ~np.isfinite(self.arrival)
        self._check_overlaps(x[present], self.ids[present])
        self._place_crowd(x, v, tri, present)
        self._init_records(N)
        self._allocate_work(N)
        self._set_cutoffs()
        self._set_neighbour_grid(N)
        #: the mesh is the model's own route mesh (not the run's): its walls merged into
        #: straight pieces, the crowd's rows kept in the neighbour grid's order (_sort_rows)
        self.own_mesh = bool(own_mesh)
        self.walls = WallSet.from_mesh(mesh, self.rc_w, merge=self.own_mesh)
        self._set_space_requirement(N)
        self._set_ghosts()
        self._law = self.params.kernel_law()  # the desired-speed law (pedmesh.speed)
        self._set_routes(reroute, desired_velocity)
        if self.params.density_cone > 0 and self.n:  # the cone looks along the route
            self._e[: self.n] = unit_rows(self._directions(0, self.n))
        from .hinge_kernels import empty_pairs

        #: the pairs across a building's stair edges (none in a room)
        self._hinge_pairs = (*empty_pairs(), 0)

    # ------------------------------------------------------------------ set-up
    def _start_positions(self, positions: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """The (N, 2) start positions [m] (default: the room's start areas), checked to be
        finite and in the walkable area, and the (N,) triangle of each."""
        mesh = self.mesh
        if positions is None:
            if mesh.room is None or not mesh.room.start_areas:
                raise SimulationError("no start positions: give positions or a room with "
                                      "start areas")
            positions = mesh.room.initial_positions()
        x = np.array(positions, dtype=np.float64).reshape(-1, 2)
        N = len(x)
        if N == 0:
            raise SimulationError("no pedestrians to simulate")
        if not np.all(np.isfinite(x)):
            raise SimulationError("start positions contain non-finite coordinates")
        tri = mesh.locate(x)
        if np.any(tri < 0):
            i = int(np.flatnonzero(tri < 0)[0])
            raise SimulationError(
                f"pedestrian {i} starts at ({x[i, 0]:.3f}, {x[i, 1]:.3f}) m, outside the walkable "
                "area (outside the room or inside an obstacle)"
            )
        return x, tri

    @staticmethod
    def _start_velocities(velocities: np.ndarray | None, x: np.ndarray) -> np.ndarray:
        """The (N, 2) initial velocities [m/s] (default: at rest), checked to be finite."""
        N = len(x)
        v = (np.zeros_like(x) if velocities is None
             else np.array(velocities, np.float64).reshape(N, 2))
        if not np.all(np.isfinite(v)):
            raise SimulationError("initial velocities contain non-finite values")
        return v

    def _place_crowd(self, x: np.ndarray, v: np.ndarray, tri: np.ndarray,
                     present: np.ndarray) -> None:
        """Store the crowd as state ``x``, ``v``, ``tri`` with the ``n`` people present from
        the start in the first rows. The entrances' people wait outside: their attributes
        are kept by id (``rad_of``, ``u0_of``, ``toff_of``) and rows ``n..`` are unused."""
        self.n_waiting = 0
        if not present.all():
            self.rad_of, self.u0_of, self.toff_of = (self.rad.copy(), self.u0.copy(),
                                                     self.toff.copy())
            self._set_entrances(x)
            for arr in (x, v, self.rad, self.u0, self._u_eff, self.tpre, self.toff, tri,
                        self.ids):
                arr[: int(present.sum())] = arr[present]
        self.x = x
        self.v = v
        self.tri = tri
        self.n = int(present.sum())
        #: people taken out by :meth:`withdraw` and not back (a hybrid model's continuum
        #: holds them), and whether each id is one of them
        self.n_withdrawn = 0
        self._withdrawn = None
        #: (n_points,) [ped/m^2] a density at the mesh's vertices the route cost adds to
        #: the crowd's (a hybrid model's continuum), None: none
        self.extra_route_density = None
        #: (n_points,) [ped/m^2] the density the last route solve read (set by the first
        #: solve, in the constructor)
        self.route_rho = None

    def _init_records(self, N: int) -> None:
        """The clock (``t`` [s], ``steps``), the densities at the pedestrians [ped/m^2], the
        exit records by id, the reflection count and the timers, for ``N`` pedestrians."""
        self.rho = np.zeros(N)
        self.t = 0.0
        self.steps = 0
        #: exit time [s] of each pedestrian (by id), NaN while inside
        self.exit_time = np.full(N, np.nan)
        #: exit number of each pedestrian (by id), -1 while inside
        self.exit_id = np.full(N, -1, np.int64)
        #: point [m] on the exit where each pedestrian (by id) crossed it, NaN while inside
        self.exit_point = np.full((N, 2), np.nan)
        self.n_reflections = 0
        self.timers = _Timers()

    def _allocate_work(self, N: int) -> None:
        """Work arrays of the step for ``N`` pedestrians: Runge-Kutta stage states, forces,
        densities, desired directions, exit crossings and the pair list (enlarged by
        :meth:`step` when full)."""
        x = self.x
        self._xs = np.empty_like(x)
        self._vs = np.empty_like(x)
        self._F = np.empty_like(x)
        self._rho_w = np.empty(N)
        self._e = np.zeros_like(x)  # desired directions (of the last stage)
        self._exit_of = np.empty(N, np.int64)
        self._exit_frac = np.empty(N)
        self._pi = np.empty(max(32 * N, 1024), np.int64)
        self._pj = np.empty(max(32 * N, 1024), np.int64)
        self.last_pair_count = 0

    def _set_cutoffs(self) -> None:
        """The cut-off radii [m] of the pair forces (``rc_f``), the kernel density
        (``rc_d``) and the wall forces (``rc_w``). Bodies larger than ``params.r`` widen
        the force cut-offs by the excess, so that the cut force stays the same."""
        p, nm = self.params, self.numerics
        extra = max(float(self.rad.max()) - p.r, 0.0)
        self.rc_f = nm.force_cutoff + 2.0 * extra
        self.rc_d = nm.density_cutoff * p.R
        self.rc_w = max(nm.force_cutoff - p.r, 1e-6) + extra

    def _set_neighbour_grid(self, N: int) -> None:
        """The neighbour grid over the room (origin, inverse cell size [1/m], cell counts
        and the cell lists for ``N`` pedestrians): cells at least as large as the pair-list
        radius (the force cut-off plus the skin; the density cut-off, plus the skin if the
        density is re-evaluated at later stages from the same list)."""
        cell = max(self.rc_f + PAIR_SKIN,
                   self.rc_d + (PAIR_SKIN if self.numerics.density_stages == 3 else 0.0))
        x0, y0, x1, y1 = self.mesh.bounds
        self._cx0, self._cy0 = x0 - cell, y0 - cell
        self._cinv = 1.0 / cell
        self._cnx = int((x1 - x0 + 2 * cell) * self._cinv) + 1
        self._cny = int((y1 - y0 + 2 * cell) * self._cinv) + 1
        self._cell_start = np.zeros(self._cnx * self._cny + 1, np.int64)
        self._cell_order = np.zeros(N, np.int64)

    def _set_space_requirement(self, N: int) -> None:
        """The speed-dependent space requirement (shrink [m], t_space [s], vision, crowd
        stretch and knee; shrink 0: off), its work arrays for ``N`` pedestrians and the
        free-width map it reads (see :meth:`_set_width_map`); ``shrink`` must stay below
        every body radius."""
        p = self.params
        from ...speed import cone_norm

        cone = float(p.density_cone)
        self._space = np.array([p.shrink, p.t_space, p.vision, p.crowd_stretch, p.crowd_knee,
                                p.wall_repulsion, cone, cone_norm(cone) if cone > 0 else 1.0],
                               np.float64)
        self._rs = np.empty(N)
        self._cf = np.zeros(N)
        self._ue = np.empty(N)
        self._set_width_map()
        if p.shrink > 0 and p.shrink >= float(self.rad.min()):
            raise SimulationError(f"parameter 'shrink' ({p.shrink:g} m) must be less than every "
                                  f"body radius (smallest {float(self.rad.min()):g} m)")

    def _set_ghosts(self) -> None:
        """The table of people beyond the exits (``exit_ghosts``; rows of
        :data:`~pedmesh.models.sfm.kernels.GHOST_COLUMNS`, grown as needed): each walks
        twice the density cut-off before it is dropped, out of reach of all inside."""
        from .kernels import GHOST_COLUMNS

        self.exit_ghosts = bool(self.params.exit_ghosts)
        if self.exit_ghosts and int(self.numerics.density_stages) != 1:
            raise ParameterError("exit_ghosts needs density_stages 1 (the densities read at "
                                 "the start of each step)")
        self._ghosts = np.zeros((64 if self.exit_ghosts else 1, GHOST_COLUMNS))
        #: people beyond the exits still counted in the densities (``exit_ghosts``)
        self.n_ghosts = 0
        self._ghost_reach = 2.0 * self.rc_d
        self._ghost_rho = np.empty(len(self._ghosts))

    def _add_ghosts(self, gone: np.ndarray, n: int) -> None:
        """Walk the people beyond the exits one step on, then add those who left in it
        (rows ``gone`` of the first ``n``), heading on along their desired direction (or
        their velocity's where they have none), never to want less than the speed they
        left with (at most their free speed)."""
        from . import kernels as K

        if self.n_ghosts:
            if len(self._ghost_rho) < self.n_ghosts:
                self._ghost_rho = np.empty(len(self._ghosts))
            self.n_ghosts = K.walk_ghosts(self._ghosts, self.n_ghosts, self.numerics.dt,
                                          self.params.tau, self._ghost_reach, self._law,
                                          self._space, self.params.R, self.rc_d,
                                          self._ghost_rho)
        if gone is None:
            return
        k = int(gone.sum())
        need = self.n_ghosts + k
        if need > len(self._ghosts):
            grown = np.zeros((max(need, 2 * len(self._ghosts)), self._ghosts.shape[1]))
            grown[: self.n_ghosts] = self._ghosts[: self.n_ghosts]
            self._ghosts = grown
        v = self.v[:n][gone]
        e = self._e[:n][gone].copy()
        norm = np.hypot(e[:, 0], e[:, 1])
        speed = np.hypot(v[:, 0], v[:, 1])
        none = norm < 1e-12
        e[none] = v[none] / np.maximum(speed[none], 1e-300)[:, None]
        e[none & (speed <= 0)] = 0.0
        e[~none] /= norm[~none][:, None]
        rows = self._ghosts[self.n_ghosts: need]
        rows[:, 0:2] = self.x[:n][gone]
        rows[:, 2:4] = v
        rows[:, 4:6] = e
        rows[:, 6] = self.u0[:n][gone]
        rows[:, 7] = 0.0
        rows[:, 8] = np.minimum(speed, rows[:, 6])
        self.n_ghosts = need

    def _set_width_map(self) -> None:
        """The free width [m] of queueing or crowding over the walkable area (``width_map``
        and its packed form ``_wmap``, ``_wgeo`` for the kernels), only with
        ``crowd_stretch > 1``; else None and placeholders."""
        p, mesh = self.params, self.mesh
        self.width_map = None
        self._wmap, self._wgeo = np.zeros((1, 1)), np.zeros(5)
        if p.crowd_stretch > 1.0:
            from .crowding import width_map

            if mesh.room is not None:
                walkable = mesh.room.walkable
            else:  # a bare mesh: the area its boundary edges enclose (the triangles'
                # union, built from the boundary alone)
                import shapely

                walkable = shapely.build_area(shapely.multilinestrings(
                    mesh.points[mesh.edges[mesh.boundary_edges]]))
            self.width_map = width_map(walkable)
            wm = self.width_map
            self._wmap = wm.width
            self._wgeo = np.array([wm.x0, wm.y0, 1.0 / wm.cell, p.queue_width, p.crowd_width])

    def _set_routes(self, reroute: bool, desired_velocity: np.ndarray | None) -> None:
        """The route choice: a constant desired velocity [m/s] if one is given, else the
        eikonal route potential (one solver per distinct set of target exits), solved here
        for the initial crowd; sets the packed steering table ``_dpack`` either way."""
        mesh = self.mesh
        self.reroute = bool(reroute)
        if desired_velocity is not None:
            self._const_u = np.asarray(desired_velocity, np.float64).reshape(2)
            self._use_const = True
        else:
            self._const_u = np.zeros(2)
            self._use_const = False
        self.phi = np.zeros(mesh.n_points)
        self._next_route = 0.0
        self._set_route_density()
        if not self._use_const:
            from ...eikonal import EikonalSolver

            self._solver = EikonalSolver(mesh)
            # one more solver per distinct set of target exits (pedmesh.population)
            self._group_solvers = [None] + [EikonalSolver(mesh, exits=list(t))
                                            for t in self._targets[1:]]
            self._route()  # sets the packed steering table self._dpack
        else:
            from ...eikonal.direction import pack_directions

            # no routes: the packed table only serves its point-in-triangle maps
            self._dpack = pack_directions(mesh, np.zeros((mesh.n_points, 2)),
                                          np.zeros((mesh.n_triangles, 2)))

    # ------------------------------------------------------------------ helpers
    def _set_population(self, pop, N: int) -> None:
        """Per-pedestrian radius ``rad``, free speed ``u0``, premovement ``tpre`` and route
        group (``toff``: the group's row offset in the stacked steering tables)."""
        p = self.params
        self.rad = np.full(N, p.r)
        self.u0 = np.full(N, p.U_f)
        self.tpre = np.zeros(N)
        self.arrival = np.full(N, np.nan)
        group = np.zeros(N, np.int64)
        self._targets: list[tuple[str, ...]] = [()]
        if pop is not None:
            for name in ("speed", "radius", "premovement", "target"):
                if len(getattr(pop, name)) != N:
                    raise SimulationError(f"the population has {len(getattr(pop, name))} "
                                          f"{name} values for {N} pedestrians")
            self.rad = np.where(np.isnan(pop.radius), p.r, pop.radius).astype(float)
            self.u0 = np.where(np.isnan(pop.speed), p.U_f, pop.speed).astype(float)
            self.tpre = np.asarray(pop.premovement, float).copy()
            self.arrival = np.asarray(pop.arrival, float).copy()
            self._area = np.asarray(pop.area, np.int64)
            if np.any(self.arrival < 0):
                raise SimulationError("arrival times must be >= 0")
            if np.any(self.rad <= 0) or np.any(self.u0 < 0) or np.any(self.tpre < 0):
                raise SimulationError("body radii must be positive, free speeds and "
                                      "premovement times >= 0")
            used = np.unique(pop.target)
            self._targets = [()] + [pop.targets[g] for g in used if len(pop.targets[g])]
            remap = {g: (self._targets.index(pop.targets[g]) if len(pop.targets[g]) else 0)
                     for g in used}
            group = np.array([remap[g] for g in pop.target], np.int64)
        self._premovement = bool(np.any(self.tpre > 0))
        self._u_eff = self.u0.copy()
        self.toff = group * self.mesh.n_triangles
        self._tbuf = np.empty(N, np.int64)

    def _check_overlaps(self, x: np.ndarray, ids: np.ndarray) -> None:
        from scipy.spatial import cKDTree

        tol = self.numerics.overlap_tolerance
        rmax = float(self.rad.max())
        lim = 2 * rmax - tol
        if lim <= 0 or len(x) < 2:
            return
        pairs = cKDTree(x).query_pairs(lim, output_type="ndarray")
        if len(pairs):
            rad = self.rad[ids]
            need = rad[pairs[:, 0]] + rad[pairs[:, 1]]
            d = np.hypot(*(x[pairs[:, 0]] - x[pairs[:, 1]]).T)
            bad = np.flatnonzero(d < need - tol)
            if len(bad):
                k = int(bad[0])
                i, j = (int(ids[a]) for a in pairs[k])
                raise SimulationError(
                    f"pedestrians {i} and {j} overlap: {d[k]:.3f} m apart, bodies need "
                    f"{need[k]:.3f} m (tolerance {tol} m)"
                )

    def _set_entrances(self, x: np.ndarray) -> None:
        """The waiting lines of the entrances and their free spots (a lattice of the start
        area one body diameter plus ENTRANCE_GAP apart, a radius plus ENTRANCE_GAP off the
        walls)."""
        wait = np.flatnonzero(np.isfinite(self.arrival))
        self._pending = {}  # area -> ids in the order of arrival
        self._spots = {}  # area -> (spots (k, 2) [m], their triangles, box corners [m])
        for a in np.unique(self._area[wait]):
            ids = wait[self._area[wait] == a]
            ids = ids[np.argsort(self.arrival[ids], kind="stable")]
            self._pending[int(a)] = deque(int(i) for i in ids)
            area, walkable, shift = self._entrance_place(int(a))
            rmax = float(self.rad[ids].max())
            region = walkable.buffer(-(rmax + ENTRANCE_GAP))
            spots = area.lattice(2 * rmax + ENTRANCE_GAP, region) + shift
            if len(spots) == 0:
                raise SimulationError(f"entrance '{area.name}' has no room for a body of radius "
                                      f"{rmax:g} m away from the walls")
            tri = self.mesh.locate(spots)
            keep = tri >= 0
            spots = spots[keep]
            # (who can be in the way: everyone within 3 m of the spots' bounding box)
            self._spots[int(a)] = (spots, tri[keep], spots.min(axis=0) - 3.0,
                                   spots.max(axis=0) + 3.0)
        self.n_waiting = len(wait)

    def _entrance_place(self, a: int):
        """Start area ``a`` (the population's index), the walkable area it lies in and the
        shift [m] (2,) from that area's coordinates to the mesh's."""
        room = self.mesh.room
        if room is None:
            raise SimulationError("arrival times need the mesh's room (its start areas)")
        return room.start_areas[a], room.walkable, np.zeros(2)

    def _admit(self) -> None:
        """Let in the entrances' people whose time has come, where there is room."""
        from ...speed import shape

        R = self.params.R
        w0 = 1.0 / (math.pi * R * R)
        for a, queue in self._pending.items():
            spots, stri, lo, hi = self._spots[a]
            while queue and self.arrival[queue[0]] <= self.t + 1e-9:
                i = queue[0]
                n = self.n
                ri = self.rad_of[i]
                xs = self.x[:n]
                near = np.flatnonzero(np.all((xs >= lo) & (xs <= hi), axis=1))
                if len(near):
                    d = np.hypot(spots[:, None, 0] - xs[near][None, :, 0],
                                 spots[:, None, 1] - xs[near][None, :, 1])
                    gap = (d - self.rad[near][None, :]).min(axis=1) - ri
                    k = int(np.argmax(gap))
                    if gap[k] < ENTRANCE_GAP:
                        break  # no room yet: this one (and those after it) wait
                    rho = w0 + w0 * float(np.exp(-(d[k] / R) ** 2).sum())
                else:
                    k = int(np.argmin(np.hypot(*(spots - spots.mean(axis=0)).T)))
                    rho = w0
                queue.popleft()
                self.x[n] = spots[k]
                self.tri[n] = stri[k]
                if self._rng is not None:  # (|offset| < ENTRANCE_GAP: still clear of all)
                    p = spots[k] + self._rng.uniform(-0.5, 0.5, 2) * ENTRANCE_GAP
                    t = int(self.mesh.locate(p[None, :])[0])
                    if t >= 0:
                        self.x[n], self.tri[n] = p, t
                self.rad[n], self.u0[n], self.tpre[n] = ri, self.u0_of[i], 0.0
                self._u_eff[n] = self.u0_of[i]
                self.toff[n] = self.toff_of[i]
                self.ids[n] = i
                self.rho[n] = rho
                self.n = n + 1
                e = self._directions(n, n + 1)[0]
                self._e[n] = unit_rows(e[None, :])[0]
                self.v[n] = e * self.u0_of[i] * shape(self._law, rho)
                self.n_waiting -= 1

    def _rows(self) -> tuple:
        """The per-pedestrian arrays, in the order :func:`~pedmesh.models.sfm.kernels.compact`
        takes them (what compact moves, :meth:`_sort_rows` sorts)."""
        return (self.x, self.v, self.rad, self.u0, self._u_eff, self.tpre, self.toff, self._e,
                self.ids, self.tri, self.rho)

    def _sort_rows(self) -> None:
        """Put the rows of the pedestrians inside in the order of the neighbour grid's cells
        they are in (stable), every per-pedestrian array alike: the pair kernels walk the
        cells in that order, so the rows they read follow one another in memory
        (benchmarks/sfm.py ``--converged-ab``: about 8 % of a step on Example 2 against the
        order of the route mesh's triangles)."""
        from . import kernels as K

        n = self.n
        if n < 2:
            return
        # the cell list's own stable counting sort, into arrays of its own (the run's cell
        # list stays as the kernels left it)
        order = np.empty(n, np.int64)
        K.build_cells(self.x, n, self._cx0, self._cy0, self._cinv, self._cnx, self._cny,
                      np.empty_like(self._cell_start), order)
        for a in self._rows():
            a[:n] = a[:n][order]

    def _directions(self, lo: int, hi: int) -> np.ndarray:
        """(hi - lo, 2) desired directions of rows ``lo:hi`` (each towards their own exits:
        a route group's rows of the steering table are the triangle plus its offset)."""
        out = np.zeros((hi - lo, 2))
        if self._use_const:
            out[:] = self._const_u / max(float(np.hypot(*self._const_u)), 1e-300)
            return out
        from ...eikonal.direction import _interpolate

        _interpolate(self._dpack, self.tri[lo:hi] + self.toff[lo:hi], self.x[lo:hi], out)
        return out

    def _build_cells(self) -> None:
        from . import kernels as K

        K.update_cells(self.x, self.n, self._cx0, self._cy0, self._cinv, self._cnx, self._cny,
                       self._cell_start, self._cell_order)

    def vertex_density(self) -> np.ndarray:
        """Gaussian kernel density (eq3, eq4) of the crowd at the mesh vertices [ped/m^2]."""
        return self.density_at(self.mesh.points)

    def density_at(self, points: np.ndarray) -> np.ndarray:
        """Gaussian kernel density (eq3, eq4) of the crowd at arbitrary points [ped/m^2]."""
        from . import kernels as K

        q = readonly(np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 2))
        out = np.zeros(len(q))
        if self.n == 0:
            return out
        with self._on_threads(self.n):
            self._build_cells()
            K.density_at(q, len(q), self.x, self.n, self._cell_start, self._cell_order,
                         self._cx0, self._cy0, self._cinv, self._cnx, self._cny, self.params.R,
                         self.rc_d, out)
        return out

    def _set_route_density(self) -> None:
        """The grid of the route's crowd density (``route_kernel`` set), else None; and the
        factor of the route cost at the vertices near walls (``route_clearance`` set, else
        None)."""
        from .walls import clearance_factor

        self._route_wall = None
        if self.params.route_clearance > 0 and not self._use_const:
            self._route_wall = clearance_factor(self.mesh, self.params.route_clearance)
        self._route_grid = None
        if self.params.route_kernel is not None and not self._use_const:
            from ...analysis.fields import GridKernelDensity

            self._route_grid = GridKernelDensity(self.mesh.points, self.params.route_kernel)

    def route_density(self) -> np.ndarray:
        """The crowd density [ped/m^2] the route cost reads, at the mesh's vertices: the
        Gaussian kernel density of width ``route_kernel`` (on a grid,
        :class:`~pedmesh.analysis.fields.GridKernelDensity`), or without one the kernel
        density of width R (eq3, eq4) as the paper has it; plus
        :attr:`extra_route_density` where set (a crowd the simulation does not hold)."""
        rho = self.vertex_density() if self._route_grid is None \
            else self._route_grid(self.x[: self.n])
        if self.extra_route_density is not None:  # (a hybrid model's continuum crowd)
            rho = rho + self.extra_route_density
        return rho

    def _route(self) -> None:
        """Re-solve the route potential with cost 1/U_e(rho) at the vertices, rho the
        crowd's :meth:`route_density`."""
        from ...eikonal.direction import DirectionField

        t0 = time.perf_counter()
        if self.reroute or self.steps == 0:
            rho_v = self.route_density()
            self.route_rho = rho_v
            cost = self.params.speed.route_cost(rho_v)
            if self._route_wall is not None:
                cost = cost * self._route_wall
            self.phi = self._solver.solve(cost)
            one = len(self._targets) == 1  # (then the table is refilled in place)
            field_ = DirectionField(self.mesh, self.phi, self._dpack if one and
                                    self.steps > 0 else None)
            if one:
                self._dpack = field_.packed
            else:  # a steering table per target group, stacked (rows t + g m)
                tables = [field_.packed] + [
                    DirectionField(self.mesh, s.solve(cost)).packed
                    for s in self._group_solvers[1:]]
                self._dpack = np.ascontiguousarray(np.concatenate(tables, axis=0))
            self.timers.routes += 1
        ri = self.numerics.route_interval
        self._next_route = self.t + ri if ri > 0 else self.t
        self.timers.routing += time.perf_counter() - t0

    # ------------------------------------------------------------------ stepping
    def threads_for(self, n: int) -> int:
        """The threads a step of ``n`` pedestrians runs its kernels on: ``numerics.threads``
        if set (at most numba's ``NUMBA_NUM_THREADS``), else numba's current count for a
        crowd of at least :data:`PARALLEL_MIN_PEOPLE_TBB` under TBB
        (:data:`PARALLEL_MIN_PEOPLE` under another threading layer), else 1."""
        import numba

        wanted = self.numerics.threads
        if wanted is not None:
            return max(1, min(int(wanted), numba.config.NUMBA_NUM_THREADS))
        most = numba.get_num_threads()
        if most <= 1:
            return 1
        try:
            layer = numba.threading_layer()
        except ValueError:  # no parallel loop has run yet
            layer = "?"
        least = PARALLEL_MIN_PEOPLE_TBB if layer == "tbb" else PARALLEL_MIN_PEOPLE
        return most if n >= least else 1

    def _rk3(self, n: int, dt: float, tri_stage: np.ndarray, cells_built: bool = False) -> int:
        """One step of the kernels (:func:`~pedmesh.models.sfm.kernels.rk3_step`);
        ``cells_built``: the cell list holds the positions already."""
        import numba

        from . import kernels as K

        p, mesh, w = self.params, self.mesh, self.walls
        return K.rk3_step(
            self.x, self.v, n, dt, tri_stage, mesh.points, mesh.triangles,
            mesh.triangle_neighbors, self._dpack,
            self._cell_start, self._cell_order, self._cx0, self._cy0, self._cinv,
            self._cnx, self._cny, w.piece, w.next_seg, w.x0, w.y0,
            w.inv_cell, w.nx, w.ny, w.cell_ptr, w.cell_seg, self.rc_f, self.rc_d, self.rc_w,
            self.rad, p.A, p.B, p.k, p.kappa, p.m, p.R, p.tau, self._u_eff, self._law,
            self._const_u, self._use_const, self._xs, self._vs, self._F, self._rho_w, self.rho,
            self._e, self._pi, self._pj, PAIR_SKIN, int(self.numerics.density_stages),
            self.toff, self._tbuf, self._space, self._rs, self._wmap, self._wgeo, self._cf,
            self._ue, self._hinge_pairs, self._ghosts, self.n_ghosts, numba.get_num_threads(),
            cells_built,
        )

    def step(self) -> int:
        """Advance one time step; returns the number of pedestrians that left. The kernels
        run on :meth:`threads_for` threads (numba's count is set back afterwards); the
        result is the same on any number."""
        with self._on_threads(self.n):
            return self._step()

    @contextmanager
    def _on_threads(self, n: int):
        """numba's thread count set to :meth:`threads_for` ``n`` pedestrians, and back."""
        import numba

        threads = self.threads_for(n)
        before = numba.get_num_threads()
        if threads != before:
            numba.set_num_threads(threads)
        try:
            yield threads
        finally:
            if threads != before:
                numba.set_num_threads(before)

    def _step(self) -> int:
        from . import kernels as K

        nm = self.numerics
        if self.n_waiting:
            self._admit()
        if self.n == 0:
            if self.n_waiting or self.n_withdrawn:  # nobody inside, people still to arrive
                # or to come back (withdraw): the clock moves
                if self.n_ghosts:  # (and those beyond the exits walk on)
                    self._add_ghosts(None, 0)
                self.steps += 1
                self.t = self.steps * nm.dt
            return 0
        if not self._use_const and self.steps > 0 and self.t >= self._next_route - 1e-9:
            self._route()
            if self.own_mesh:
                self._sort_rows()
        n, dt, mesh = self.n, nm.dt, self.mesh
        if self._premovement:  # no desired speed before one's premovement time
            np.copyto(self._u_eff[:n], np.where(self.tpre[:n] <= self.t, self.u0[:n], 0.0))
        t0 = time.perf_counter()
        x_old = self.x[:n].copy()
        while True:
            tri_stage = self.tri[:n].copy()
            npairs = self._rk3(n, dt, tri_stage)
            if npairs >= 0:
                break
            self._pi = np.empty(2 * len(self._pi), np.int64)  # pair list full: enlarge
            self._pj = np.empty(2 * len(self._pj), np.int64)
        self.last_pair_count = npairs
        t1 = time.perf_counter()
        i = K.first_bad(self.x, self.v, n, nm.max_speed**2)
        if i >= 0:
            speed = float(np.hypot(*self.v[i]))
            raise SimulationError(
                f"blow-up at t = {self.t + dt:.3f} s: pedestrian {int(self.ids[i])} has speed "
                f"{speed:.3g} m/s (bound {nm.max_speed} m/s); try a smaller time step, "
                f"e.g. --param dt={dt / 2:g}"
            )
        self.n_reflections += K.settle(
            x_old, self.x, self.v, self.tri, n, mesh.points, mesh.triangles,
            mesh.triangle_neighbors, mesh.triangle_edges, mesh.edge_kind, mesh.edge_owner,
            mesh.edge_normals, self._exit_of, self._exit_frac, self._dpack,
        )
        if self._hinges is not None:  # a building: those on a stair edge pass over it
            self._cross_hinges(n)
        gone = self._exit_of[:n] >= 0
        n_gone = int(gone.sum())
        if self.exit_ghosts and (n_gone or self.n_ghosts):
            self._add_ghosts(gone if n_gone else None, n)
        if n_gone:
            ids = self.ids[:n][gone]
            self.exit_time[ids] = self.t + self._exit_frac[:n][gone] * dt
            self.exit_id[ids] = self._exit_of[:n][gone]
            self.exit_point[ids] = self.x[:n][gone]
            self.n = K.compact(self._exit_of, n, *self._rows())
        self.steps += 1
        self.t = self.steps * dt  # no drift from summing dt
        self.timers.forces += t1 - t0
        self.timers.settle += time.perf_counter() - t1
        self.timers.steps += 1
        return n_gone

    def run(self, t_end: float, callback: Callable[["Simulation"], None] | None = None) -> None:
        """Step until everyone has left (and every entrance's people arrived) or ``t >=
        t_end`` [s]; ``callback(self)`` after each step."""
        while (self.n > 0 or self.n_waiting > 0) and self.t < t_end - 1e-9:
            self.step()
            if callback is not None:
                callback(self)

    # ------------------------------------------------------------------ results
    @property
    def positions(self) -> np.ndarray:
        """(n, 2) positions [m] of the pedestrians still inside."""
        return self.x[: self.n].copy()

    @property
    def velocities(self) -> np.ndarray:
        """(n, 2) velocities [m/s] of the pedestrians still inside."""
        return self.v[: self.n].copy()

    @property
    def densities(self) -> np.ndarray:
        """(n,) kernel density [ped/m^2] at each pedestrian at the start of the last step."""
        return self.rho[: self.n].copy()

    @property
    def active_ids(self) -> np.ndarray:
        """(n,) ids of the pedestrians still inside."""
        return self.ids[: self.n].copy()

    @property
    def n_evacuated(self) -> int:
        return self.n_initial - self.n - self.n_waiting - self.n_withdrawn

    # ------------------------------------------------------------------ hand-over
    def _by_id(self) -> None:
        """Keep each person's radius, free speed and route group by id (``rad_of``,
        ``u0_of``, ``toff_of``), as for the entrances' people, so that who leaves the rows
        can come back with them."""
        if not hasattr(self, "rad_of"):
            N = self.n_initial
            self.rad_of = np.full(N, self.params.r)
            self.u0_of = np.full(N, self.params.U_f)
            self.toff_of = np.zeros(N, np.int64)
        n = self.n
        ids = self.ids[:n]
        self.rad_of[ids] = self.rad[:n]
        self.u0_of[ids] = self.u0[:n]
        self.toff_of[ids] = self.toff[:n]
        if self._withdrawn is None:
            self._withdrawn = np.zeros(self.n_initial, bool)

    def withdraw(self, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Take the people of the rows ``mask`` ((n,) bool over the people inside, in the
        order of :attr:`active_ids`) out of the simulation, not through an exit (a hybrid
        model hands them to its continuum). Returns their ids, positions [m] (k, 2) and
        velocities [m/s] (k, 2). They count neither as inside nor as evacuated until
        :meth:`enter` brings them back; the simulation keeps their radius, free speed and
        route by id."""
        from . import kernels as K

        mask = np.asarray(mask, bool).ravel()
        n = self.n
        if mask.shape != (n,):
            raise SimulationError(f"withdraw needs one flag per person inside ({n}), got "
                                  f"{mask.shape}")
        self._by_id()
        ids = self.ids[:n][mask].copy()
        x = self.x[:n][mask].copy()
        v = self.v[:n][mask].copy()
        if len(ids):
            flag = np.where(mask, 0, -1).astype(np.int64)
            self.n = K.compact(flag, n, *self._rows())
            self._withdrawn[ids] = True
            self.n_withdrawn += len(ids)
        return ids, x, v

    def enter(self, ids: np.ndarray, positions: np.ndarray,
              velocities: np.ndarray) -> np.ndarray:
        """Bring withdrawn people (``ids``, see :meth:`withdraw`) back at ``positions`` [m]
        (k, 2) with ``velocities`` [m/s] (k, 2), in the order given, each only where its
        centre is inside the mesh and its body clear of everyone else's by ENTRANCE_GAP
        [m] (walls are not checked: their forces push a body off them). Returns (k,) bool:
        who entered (the others stay withdrawn; a hybrid model keeps them in its interface
        account)."""
        ids = np.asarray(ids, np.int64).ravel()
        pos = np.asarray(positions, float).reshape(-1, 2)
        vel = np.asarray(velocities, float).reshape(-1, 2)
        if not (len(ids) == len(pos) == len(vel)):
            raise SimulationError(f"enter: {len(ids)} ids, {len(pos)} positions and "
                                  f"{len(vel)} velocities")
        if len(ids) and (self._withdrawn is None or not np.all(self._withdrawn[ids])):
            raise SimulationError("enter: only people taken out by withdraw can enter")
        if len(np.unique(ids)) != len(ids):
            raise SimulationError("enter: an id is given twice")
        if not (np.all(np.isfinite(pos)) and np.all(np.isfinite(vel))):
            raise SimulationError("enter: positions and velocities must be finite")
        tri = self.mesh.locate(pos) if len(pos) else np.zeros(0, np.int64)
        R = self.params.R
        w0 = 1.0 / (math.pi * R * R)
        reach = 2.0 * R
        entered = np.zeros(len(ids), bool)
        for k in range(len(ids)):
            i = int(ids[k])
            if tri[k] < 0:
                continue
            n = self.n
            ri = self.rad_of[i]
            d = np.hypot(self.x[:n, 0] - pos[k, 0], self.x[:n, 1] - pos[k, 1])
            if n and float((d - self.rad[:n]).min()) - ri < ENTRANCE_GAP:
                continue  # no room there
            near = d[d < reach]
            self.x[n] = pos[k]
            self.v[n] = vel[k]
            self.tri[n] = tri[k]
            self.rad[n], self.u0[n], self.tpre[n] = ri, self.u0_of[i], 0.0
            self._u_eff[n] = self.u0_of[i]
            self.toff[n] = self.toff_of[i]
            self.ids[n] = i
            self.rho[n] = w0 + w0 * float(np.exp(-(near / R) ** 2).sum())
            self.n = n + 1
            e = self._directions(n, n + 1)[0]
            self._e[n] = unit_rows(e[None, :])[0]
            self._withdrawn[i] = False
            self.n_withdrawn -= 1
            entered[k] = True
        return entered

    @property
    def finished(self) -> bool:
        """Everyone has left (nobody inside, nobody still to arrive; people taken out by
        :meth:`withdraw` are not the simulation's to wait for)."""
        return self.n == 0 and self.n_waiting == 0

    def desired_directions(self) -> np.ndarray:
        """(n, 2) current desired directions of the pedestrians still inside (each towards
        their own exits)."""
        return self._directions(0, self.n)
