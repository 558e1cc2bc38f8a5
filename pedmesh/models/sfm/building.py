"""The social force model on a building's surface (levels and stairs).

The pedestrians walk on the building's open atlas (:mod:`pedmesh.mesh.atlas`): every level
and stair in its own chart, laid side by side in one plane, so that lengths, angles and
speeds are the true ones on the surface. A pedestrian belongs to the piece (level or
stair) they stand on. One who crosses a stair edge (an exit of the open atlas) passes to the
other side by the translation that maps the edge's two copies onto each other: position
and velocity carry over, the speed along the surface is kept. The walls are each piece's
boundary edges other than its stair edges. Two pedestrians on either side of a stair edge
interact as if the edge were not there (their distance measured across the hinge), and
never across floors stacked above each other, which lie apart in the atlas. On a stair the
desired speed is the stair's share of the level's, up or down
(:func:`~pedmesh.eikonal.surface.stair_factors`), and routes are solved on the surface
(:class:`~pedmesh.eikonal.surface.BuildingRoutes`).
"""

from __future__ import annotations

import math
import time

import numpy as np

from ...errors import ParameterError, SimulationError
from .adapter import SFMRun
from .simulation import Simulation

__all__ = ["SurfaceSimulation", "BuildingSFMRun", "building_positions",
           "building_population"]

#: [m] how far beyond a stair edge a pedestrian who crossed it is put, on the other side
HINGE_NUDGE = 1e-7
#: a pedestrian does not cross a stair edge where the route on the other side points back
#: over it at least this much (the cosine with the edge's normal): a corner cut across the
#: foot of a stair not on their way
TURN_BACK = 0.5


def building_positions(building, atlas, *, seed: int | None = None,
                       radius: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Start positions (N, 2) [m] in the atlas of every level's start areas, level by level
    (jittered with ``seed`` as :func:`~pedmesh.models.sfm.placement.seeded_positions`
    does a room's), and (N,) the piece of each."""
    from .placement import seeded_positions

    xs, pieces = [], []
    for lv in building.levels:
        if not lv.room.start_areas:
            continue
        if seed is None:
            x = lv.room.initial_positions()
        else:
            kw = {} if radius is None else {"radius": radius}
            x = seeded_positions(lv.room, int(seed), **kw)
        xs.append(x + atlas.level_shift(lv.name))
        pieces.append(np.full(len(x), atlas.surface.piece_index(lv.name)))
    if not xs:
        return np.zeros((0, 2)), np.zeros(0, np.int64)
    return np.concatenate(xs), np.concatenate(pieces)


def building_population(building, n: int, seed: int | None = None):
    """Who the levels' start areas' ``n`` people are (premovement, free speed, radius,
    exits, arrival times: :func:`pedmesh.population.draw_population` over the building's
    start areas, in the order of :func:`building_positions`, drawn with ``seed``, 0 without
    one); None if no start area says."""
    from types import SimpleNamespace

    from ...population import draw_population

    areas = [a for lv in building.levels for a in lv.room.start_areas]
    if not any(getattr(a, k) is not None for a in areas
               for k in ("premovement", "speed", "radius", "exits", "arrivals")):
        return None
    counts = [len(a.positions(lv.room.walkable))
              for lv in building.levels for a in lv.room.start_areas]
    if sum(counts) != n:
        raise SimulationError(f"the start areas hold {sum(counts)} people but {n} were "
                              "placed (an internal error)")
    return draw_population(SimpleNamespace(start_areas=areas), counts,
                           seed=0 if seed is None else int(seed))


class SurfaceSimulation(Simulation):
    """:class:`~pedmesh.models.sfm.simulation.Simulation` on a building's atlas (see the
    module docstring). ``atlas``: :func:`~pedmesh.mesh.atlas.build_atlas` of the building's
    surface; the other arguments are the room simulation's (``positions`` in the atlas)."""

    def __init__(self, atlas, positions: np.ndarray, velocities: np.ndarray | None = None,
                 **kwargs) -> None:
        if kwargs.get("desired_velocity") is not None:
            raise ParameterError("a constant desired velocity is not available on buildings")
        self.atlas = atlas
        h = atlas.hinges
        #: per exit of the open atlas: whether it is a stair edge, the shift [m] that carries
        #: a point over it, and the piece on its other side
        self._hinge_exit = np.zeros(len(atlas.open.exit_names), bool)
        self._hinge_exit[h[:, 0].astype(np.int64)] = True
        self._hinge_shift = np.zeros((len(atlas.open.exit_names), 2))
        self._hinge_shift[h[:, 0].astype(np.int64)] = h[:, 3:5]
        self._hinge_to = np.full(len(atlas.open.exit_names), -1, np.int64)
        self._hinge_to[h[:, 0].astype(np.int64)] = h[:, 2].astype(np.int64)
        self.n_crossings = 0
        super().__init__(atlas.open, positions, velocities, **kwargs)
        self._hinges = True
        #: (t [s], from piece, to piece) of every crossing of a stair edge not yet read
        #: (:class:`BuildingSFMRun` reads them into its stair use)
        self.crossing_log: list[tuple[float, int, int]] = []
        self._set_hinge_lists()

    def _entrance_place(self, a: int):
        """Start area ``a`` of the building (its levels' start areas in order, as
        :func:`building_population` draws them), its level's walkable area and that level's
        shift into the atlas: an entrance's people arrive on its level."""
        building = self.atlas.surface.building
        if building is None:
            raise SimulationError("arrival times need the surface's building (its start "
                                  "areas)")
        k = 0
        for lv in building.levels:
            areas = lv.room.start_areas
            if a < k + len(areas):
                return areas[a - k], lv.room.walkable, self.atlas.level_shift(lv.name)
            k += len(areas)
        raise SimulationError(f"no start area {a} in the building (an internal error)")

    def _set_hinge_lists(self) -> None:
        """Each stair edge once (from its piece of lower index): its end points [m] on that
        side, its two pieces and its shift, for :func:`hinge_pairs`."""
        mesh = self.mesh
        rows = [r for r in self.atlas.hinges if r[1] < r[2]]
        seg, frm, to, shift = [], [], [], []
        for r in rows:
            e = mesh.exit_edges(int(r[0]))
            v = np.unique(mesh.edges[e])
            p = mesh.points[v]
            d = p[-1] - p[0]
            along = (p - p[0]) @ d
            a, b = p[np.argmin(along)], p[np.argmax(along)]
            seg.append([a[0], a[1], b[0], b[1]])
            frm.append(int(r[1]))
            to.append(int(r[2]))
            shift.append(r[3:5])
        self._hseg = np.array(seg, float).reshape(-1, 4)
        self._hfrom = np.array(frm, np.int64)
        self._hto = np.array(to, np.int64)
        self._hshift = np.array(shift, float).reshape(-1, 2)
        # the edges by their from piece (CSR, each piece's in increasing order)
        n_pieces = len(self.atlas.surface.pieces)
        self._hptr = np.zeros(n_pieces + 1, np.int64)
        np.cumsum(np.bincount(self._hfrom, minlength=n_pieces), out=self._hptr[1:])
        self._hidx = np.argsort(self._hfrom, kind="stable").astype(np.int64)
        cap = max(64, 8 * self.n_initial // 10)
        self._hbuf = (np.empty(cap, np.int64), np.empty(cap, np.int64), np.empty((cap, 2)))
        from .simulation import PAIR_SKIN

        #: [m] the radius of the pair search across stair edges (the force and density
        #: cut-offs plus the pair list's skin)
        self._hinge_rc = max(self.rc_f, self.rc_d) + PAIR_SKIN

    def _rk3(self, n: int, dt: float, tri_stage: np.ndarray) -> int:
        """The room's step, with the pairs across stair edges listed first (within the
        force and density cut-offs plus the pair list's skin; the list serves the step's
        three stages, as the room's does unless someone moves more than half the skin)."""
        from .hinge_kernels import hinge_pairs

        if self._active is not None and self._refreshed != self.n_crossings:
            self._refresh_steering()  # (someone crossed onto another piece)
        self._build_cells()
        rc = self._hinge_rc
        while True:
            hi, hj, hs = self._hbuf
            nh = hinge_pairs(self.x, n, self.tri, self.atlas.glued.piece, self._hseg,
                             self._hptr, self._hidx, self._hto, self._hshift, rc,
                             self._cell_start, self._cell_order, self._cx0, self._cy0,
                             self._cinv, self._cnx, self._cny, hi, hj, hs)
            if nh >= 0:
                break
            cap = 2 * len(hi)
            self._hbuf = (np.empty(cap, np.int64), np.empty(cap, np.int64), np.empty((cap, 2)))
        self._hinge_pairs = (hi, hj, hs, nh)
        return super()._rk3(n, dt, tri_stage, cells_built=True)

    # ------------------------------------------------------------------ routes
    def _set_routes(self, reroute: bool, desired_velocity) -> None:
        from ...eikonal import active
        from ...eikonal.surface import BuildingRoutes

        self.reroute = bool(reroute)
        self._const_u = np.zeros(2)
        self._use_const = False
        self.surface_phi = np.zeros(self.atlas.surface.n_points)
        self._next_route = 0.0
        self._solver = BuildingRoutes(self.atlas)
        # one more solver per distinct set of target exits (pedmesh.population)
        self._group_solvers = [None] + [BuildingRoutes(self.atlas, exits=list(t))
                                        for t in self._targets[1:]]
        self._set_route_density()
        a = self.atlas
        #: the route cost's factor near walls at the surface's vertices (the nearer wall's
        #: of a stair edge's two copies), None without route_clearance
        self._wall_s = None
        if self._route_wall is not None:
            self._wall_s = np.ones(a.surface.n_points)
            np.maximum.at(self._wall_s, a.to_surface, self._route_wall)
        #: the routes re-solved where the crowd can change them (pedmesh.eikonal.active),
        #: one per route group, their steering tables stacked in _dpack; None: the whole
        #: building at every solve
        self._active = None
        if active.ACTIVE_SET:
            cost0 = self.params.speed.route_cost(np.zeros(a.surface.n_points))
            if self._wall_s is not None:
                cost0 = cost0 * self._wall_s
            groups = [self._solver] + self._group_solvers[1:]
            m = self.mesh.n_triangles
            from ...eikonal.direction import PACK_WIDTH

            self._dpack = np.empty((len(groups) * m, PACK_WIDTH))
            self._active = [active.ActiveRoutes(g, cost0, self._dpack, k * m)
                            for k, g in enumerate(groups)]
        self._route()

    @property
    def phi(self) -> np.ndarray:
        """(n,) the route potential at the atlas's vertices (each copy of a surface vertex
        at its value, :attr:`surface_phi`)."""
        return self.surface_phi[self.atlas.to_surface]

    def _route(self) -> None:
        """Re-solve the route potential on the surface with cost 1/U_e(rho) at its vertices
        (each stair at its speed up or down), and the steering table on the atlas with the
        stair speed factors: where the crowd can change them (:attr:`_active`), or the
        whole building."""
        from ...eikonal.direction import scale_packed

        t0 = time.perf_counter()
        if self.reroute or self.steps == 0:
            if self._active is not None:
                v, rho = self._route_density_near()
                cost = self.params.speed.route_cost(rho)
                if self._wall_s is not None:
                    cost = cost * self._wall_s[v]
                phis = [r.route(v, cost) for r in self._active]
                self.surface_phi = phis[0]
                self._refresh_steering()
            else:
                a = self.atlas
                rho_atlas = self.route_density()
                rho_v = np.zeros(a.surface.n_points)
                np.maximum.at(rho_v, a.to_surface, rho_atlas)  # (the denser copy)
                cost = self.params.speed.route_cost(rho_v)
                if self._wall_s is not None:
                    cost = cost * self._wall_s
                phi_s, field_, factors = self._solver.solve(cost)
                self.surface_phi = phi_s
                self._dpack = scale_packed(field_.packed, factors)
                if len(self._targets) > 1:  # a steering table per target group, stacked
                    tables = [self._dpack]
                    for g in self._group_solvers[1:]:
                        _, f_g, fac_g = g.solve(cost)
                        tables.append(scale_packed(f_g.packed, fac_g))
                    self._dpack = np.ascontiguousarray(np.concatenate(tables, axis=0))
            self.timers.routes += 1
        ri = self.numerics.route_interval
        self._next_route = self.t + ri if ri > 0 else self.t
        self.timers.routing += time.perf_counter() - t0

    def _refresh_steering(self) -> None:
        """Bring the steering table up to date (:meth:`~pedmesh.eikonal.active.
        ActiveRoutes.refresh`) where the crowd can be before the next route solve or the
        next crossing of a stair edge: on the (flat groups of) pieces people stand on and
        those across their stair edges."""
        self._refreshed = self.n_crossings
        if self._active is None or self.n == 0:
            return
        units = self._active[0].units_near(self.tri[: self.n])
        for r in self._active:
            r.refresh(units)

    def _route_density_near(self) -> tuple[np.ndarray, np.ndarray]:
        """``(vertices, rho)``: the surface vertices where the route's crowd density
        (:meth:`route_density`) may be above 0 and the density there (the denser copy of
        a vertex on a stair edge), the same numbers as :meth:`route_density`'s, which is 0
        at every other vertex; found near the crowd, not by going through the building."""
        a = self.atlas
        if self._route_grid is not None:
            pts, rho = self._route_grid.near(self.x[: self.n])
        else:  # the kernel density of width R: the points within a cell of someone's
            pts = self._points_near_crowd()
            rho = self.density_at(a.open.points[pts])
        sv = a.to_surface[pts]
        v, inv = np.unique(sv, return_inverse=True)
        out = np.zeros(len(v))
        np.maximum.at(out, inv, rho)
        return v, out

    def _points_near_crowd(self) -> np.ndarray:
        """The atlas points in the neighbour grid's cells next to or in one with someone in
        it (the cells are no smaller than the density's cut-off: the kernel density is 0 at
        every other point)."""
        if not hasattr(self, "_cell_points"):
            p = self.mesh.points
            ci = np.clip(((p[:, 0] - self._cx0) * self._cinv).astype(np.int64), 0,
                         self._cnx - 1)
            cj = np.clip(((p[:, 1] - self._cy0) * self._cinv).astype(np.int64), 0,
                         self._cny - 1)
            key = ci * self._cny + cj
            ptr = np.zeros(self._cnx * self._cny + 1, np.int64)
            np.cumsum(np.bincount(key, minlength=self._cnx * self._cny), out=ptr[1:])
            self._cell_points = (ptr, np.argsort(key, kind="stable"))
        from ...mesh.triangle_mesh import csr_ranges

        x = self.x[: self.n]
        ci = np.clip(((x[:, 0] - self._cx0) * self._cinv).astype(np.int64), 0, self._cnx - 1)
        cj = np.clip(((x[:, 1] - self._cy0) * self._cinv).astype(np.int64), 0, self._cny - 1)
        di, dj = np.meshgrid([-1, 0, 1], [-1, 0, 1])
        ni, nj = ci[:, None] + di.ravel(), cj[:, None] + dj.ravel()
        ok = (ni >= 0) & (ni < self._cnx) & (nj >= 0) & (nj < self._cny)
        cells = np.unique(ni[ok] * self._cny + nj[ok])
        ptr, order = self._cell_points
        return np.sort(order[csr_ranges(ptr[cells], ptr[cells + 1] - ptr[cells])])

    # ------------------------------------------------------------------ stair edges
    def _cross_hinges(self, n: int) -> None:
        """Pass the pedestrians whose step crossed a stair edge (``settle`` left them on it,
        as on an exit) to the other side: moved by the edge's shift, a hair beyond it, with
        their velocity; the rest of their step is dropped (at most one step, dt u)."""
        ex = self._exit_of[:n]
        cross = np.flatnonzero(ex >= 0)
        if len(cross) == 0:
            return
        cross = cross[self._hinge_exit[ex[cross]]]
        if len(cross) == 0:
            return
        mesh = self.mesh
        for i in cross:
            k = int(ex[i])
            if self._turns_back(i, k):
                continue
            p = self.x[i] + self._hinge_shift[k]
            v = self.v[i]
            sp = math.hypot(v[0], v[1])
            step = v / sp if sp > 0 else np.zeros(2)
            t = -1
            for nudge in (HINGE_NUDGE, 1e-5, 1e-3):
                q = p + nudge * step
                t = int(mesh.locate(q[None, :])[0])
                if t >= 0 and self.atlas.glued.piece[t] == self._hinge_to[k]:
                    p = q
                    break
                t = -1
            if t < 0:  # moving along the edge or back: the nearest triangle of the far side
                t = self._nearest_on(p, int(self._hinge_to[k]))
            self.crossing_log.append((self.t, int(self.atlas.glued.piece[self.tri[i]]),
                                      int(self._hinge_to[k])))
            self.x[i] = p
            self.tri[i] = t
            ex[i] = -1
            self.n_crossings += 1

    def _turns_back(self, i: int, k: int) -> bool:
        """Whether pedestrian ``i``, on stair edge ``k`` (an exit of the open atlas), would
        turn straight back on the other side (the route there points back across the
        edge: a corner cut across the foot of a stair that is not on their way). Then the
        edge is a wall for them: they stay on their side, their velocity reflected off it.
        A pedestrian steps onto a stair (or off it) only where the route goes that way."""
        from ...eikonal.direction import _interpolate

        mesh = self.mesh
        t0 = int(self.tri[i])
        le = np.flatnonzero(mesh.edge_kind[mesh.triangle_edges[t0]] == 3)
        if len(le) == 0:
            return False
        ed = int(mesh.triangle_edges[t0, le[0]])
        n_out = mesh.edge_normals[ed]  # out of this side, into the other
        p = self.x[i] + self._hinge_shift[k] + 1e-6 * n_out
        t = int(mesh.locate(p[None, :])[0])
        if t < 0:
            return False
        e = np.zeros((1, 2))
        _interpolate(self._dpack, np.array([t + int(self.toff[i])]), p[None, :], e)
        if e[0] @ n_out >= -TURN_BACK:
            return False
        q = self.x[i] - 1e-7 * n_out  # back a hair on this side
        self.x[i] = q
        vn = self.v[i] @ n_out
        if vn > 0.0:
            self.v[i] -= 2.0 * vn * n_out
        self._exit_of[i] = -1
        self.n_reflections += 1
        return True

    def _nearest_on(self, p: np.ndarray, piece: int) -> int:
        """The triangle of ``piece`` whose centroid is nearest to ``p``; ``p`` is moved
        into it (a hair towards its centroid) if it lies outside."""
        g = self.atlas.glued
        tris = self.atlas.surface.pieces[piece].triangles
        c = g.centroids[tris]
        t = int(tris[np.argmin(np.sum((c - p) ** 2, axis=1))])
        if int(self.mesh.locate(p[None, :])[0]) != t:
            p += 1e-6 * (g.centroids[t] - p)
        return t

    # ------------------------------------------------------------------ results
    def piece_of(self, tri: np.ndarray | None = None) -> np.ndarray:
        """(n,) the piece (level or stair) of each pedestrian inside."""
        return self.atlas.glued.piece[self.tri[: self.n] if tri is None else tri]

    def positions_3d(self) -> np.ndarray:
        """(n, 3) positions [m] in 3-D of the pedestrians inside."""
        return self.atlas.to_3d(self.x[: self.n], self.piece_of())

    def velocities_3d(self) -> np.ndarray:
        """(n, 3) velocities [m/s] in 3-D (along the surface) of the pedestrians inside."""
        return self.atlas.vectors_3d(self.v[: self.n], self.piece_of())

    def check_on_surface(self) -> None:
        """A :class:`~pedmesh.errors.SimulationError` if anyone stands outside the walkable
        surface (a test of the invariant)."""
        tri = self.mesh.locate(self.x[: self.n])
        if np.any(tri < 0):
            i = int(np.flatnonzero(tri < 0)[0])
            raise SimulationError(f"pedestrian {int(self.ids[i])} is off the surface at "
                                  f"{self.x[i]}")


class BuildingSFMRun(SFMRun):
    """The social force model on a building behind the run contract: as
    :class:`~pedmesh.models.sfm.adapter.SFMRun` on a room, with the pedestrians on the
    building's atlas, their trajectories in 3-D (plan x, y, the height z and the level
    or stair they stand on) and the density frames on the surface in 3-D."""

    def __init__(self, room, mesh, overrides, *, static_routes: bool = False,
                 positions: np.ndarray | None = None, trajectory_rate: float = 10.0,
                 seed: int | None = None) -> None:
        from ...mesh.atlas import build_atlas
        from .params import SFMNumerics, SocialForceParams, with_overrides

        building = room if room is not None else mesh.building
        self.params, self.numerics = with_overrides(overrides, SocialForceParams(),
                                                    SFMNumerics())
        self._check_rate(trajectory_rate)
        if positions is not None:
            raise ParameterError("start positions are not available on buildings yet: "
                                 "the crowd is the levels' start areas")
        if seed is not None and (isinstance(seed, bool)
                                 or not isinstance(seed, (int, np.integer)) or seed < 0):
            raise ParameterError(f"seed must be a non-negative integer, got {seed!r}")
        self.building = building
        self.surface = mesh
        walk = self._walking_mesh(building, mesh)
        self.atlas = build_atlas(walk)
        #: the atlas of the run's mesh, where the density frames are written
        self._out_atlas = self.atlas
        if walk is not mesh:
            self._out_atlas = build_atlas(mesh)
            if not np.allclose(self._out_atlas.offset, self.atlas.offset, rtol=0, atol=1e-6):
                raise SimulationError("the building's route mesh lies elsewhere in the atlas "
                                      "than its mesh (an internal error)")
        x, _ = building_positions(building, self.atlas, seed=seed, radius=self.params.r)
        if len(x) == 0:
            raise SimulationError("no start positions: the building's levels have no "
                                  "start areas")
        self.seed = seed
        self.population = building_population(building, len(x), seed)
        self.sim = SurfaceSimulation(self.atlas, x, params=self.params,
                                     numerics=self.numerics, reroute=not static_routes,
                                     population=self.population, seed=seed,
                                     own_mesh=walk is not mesh)
        self.mesh = mesh
        self._finish_init(static_routes, trajectory_rate, None)
        self._piece_names = [p.name for p in mesh.pieces]
        from ...analysis.stairs import StairUse

        #: the stairs' use (:mod:`pedmesh.analysis.stairs`), in summary.json's "stairs"
        self.stair_use = StairUse(mesh, building)
        self._next_stair_sample = 0.0

    # -------------------------------------------------------------- outputs
    def exit_counts(self) -> np.ndarray:
        ids = self.sim.exit_id
        return np.bincount(ids[ids >= 0], minlength=len(self.mesh.exit_names)).astype(
            float)[: len(self.mesh.exit_names)]

    def kernel_outflow(self, positions: np.ndarray | None = None,
                       velocities: np.ndarray | None = None) -> np.ndarray:
        from ...analysis import particle_outflow

        if positions is None:
            positions, velocities = self.sim.positions, self.sim.velocities
        return particle_outflow(mesh=self.atlas.open, positions=positions,
                                velocities=velocities, R=self.params.R,
                                n_exits=len(self.mesh.exit_names))

    def _trajectory_rows(self, left: np.ndarray):
        sim = self.sim
        pieces = np.concatenate([sim.piece_of(), self._exit_piece(left)])
        xyz = np.concatenate([sim.positions_3d(),
                              self.atlas.to_3d(sim.exit_point[left],
                                               self._exit_piece(left))])
        v = np.concatenate([sim.velocities_3d(), np.zeros((len(left), 3))])
        return xyz, v, pieces

    def _exit_piece(self, ids: np.ndarray) -> np.ndarray:
        """The piece of each leaver (the level of the exit they took)."""
        if len(ids) == 0:
            return np.zeros(0, np.int64)
        t = self.atlas.open.locate(self.sim.exit_point[ids])
        edge_t = self.atlas.open.edge_triangles[self.atlas.open.exit_edges(), 0]
        fallback = int(self.atlas.glued.piece[edge_t[0]]) if len(edge_t) else 0
        return np.where(t >= 0, self.atlas.glued.piece[np.maximum(t, 0)], fallback)

    def _trajectory_frame(self, writer) -> None:
        sim = self.sim
        left = np.flatnonzero(np.isfinite(sim.exit_time) & ~self._traj_out)
        if self._traj_frame > 0 and sim.t <= (self._traj_frame - 1) / \
                self.trajectory_rate + 1e-9 and len(left) == 0:
            return
        xyz, v, pieces = self._trajectory_rows(left)
        speed = np.hypot(v[:, 0], v[:, 1])
        heading = np.divide(v[:, :2], speed[:, None], out=np.zeros((len(v), 2)),
                            where=speed[:, None] > 0)
        ids = np.concatenate([sim.active_ids, left])
        writer.trajectory_frame(self._traj_frame, ids, xyz[:, :2], self.trajectory_rate,
                                f"social force model on building '{self.building.name}', "
                                f"{self.trajectory_rate:g} frames/s", orientation=heading,
                                walkable_wkt=None, z=xyz[:, 2],
                                place=[self._piece_names[k] for k in pieces])
        self._traj_out[left] = True
        self._traj_frame += 1

    def write_frame(self, writer, frame: int) -> None:
        sim = self.sim
        v = sim.velocities_3d()
        writer.pedestrian_frame(sim.t, sim.positions_3d(), {
            "id": sim.active_ids.astype(np.int64),
            "velocity": v,
            "speed": np.linalg.norm(v, axis=1) if len(v) else np.zeros(0),
            "density": sim.densities,
            "piece": sim.piece_of().astype(np.int64),
        })
        rho = np.zeros(self.surface.n_points)
        out = self._out_atlas
        np.maximum.at(rho, out.to_surface, sim.density_at(out.open.points))
        writer.density_frame(sim.t, self.surface, point_data={"density": rho})

    def record(self, writer, final: bool = False) -> None:
        """As on a room, and the stairs' use: every crossing onto a stair, and each sample
        interval the people on each stair."""
        super().record(writer, final)
        sim, use = self.sim, self.stair_use
        for t, frm, to in sim.crossing_log:
            if use.is_stair(to) and not use.is_stair(frm):
                use.enter(t, to, 1.0, frm)
        sim.crossing_log.clear()
        if sim.t >= self._next_stair_sample - 1e-9 or final:
            use.occupancy(sim.t, np.bincount(sim.piece_of(), minlength=len(self._piece_names)))
            self._next_stair_sample = sim.t + self.sample_interval

    def summary(self):
        out = super().summary()
        out["exits"] = {k: out["exits"][k] for k in self.mesh.exit_names}
        out["stair_edge_crossings"] = int(self.sim.n_crossings)
        out["stairs"] = self.stair_use.summary()
        return out

