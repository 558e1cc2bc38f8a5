"""The finite-volume core: state, solver (one residual, one SSP Runge-Kutta step) and
controller.

* :class:`FVState` holds *what* is evolved: the conserved cell averages ``Q`` (m, nv)
  (density [ped/m^2] and momentum [ped/(m s)]), the time and the cumulative outflow through
  each exit.
* :class:`FVSolver` decides *how* to take a step: CWENO3 reconstruction (or second/first
  order), a Zhang-Shu point limiter, the model's numerical fluxes at 2 Gauss points per
  edge, a flux-corrected-transport blend with the first-order fluxes that keeps the density
  non-negative after every stage (provided the stage is within the forward-Euler bound of
  its first-order fluxes, which each stage checks), the model's sources at 3 interior
  points, and Shu-Osher SSP Runge-Kutta stages (Heun's 2 or 3). For a model with a pressure
  law every stage is semi-implicit (:mod:`pedmesh.models.continuum.implicit`): the explicit stage
  without the pressure in the interior fluxes, then the implicit pressure correction. Each
  step updates the active set only: the occupied cells and two rings of neighbours. The
  desired direction is re-solved from the current density (cost ``1/U_e(rho)``, cell
  densities averaged to the vertices) at the start of a step once ``route_interval`` (1 s)
  has passed since the last solve, and frozen in between (an O(dt) splitting every step,
  like the paper's, with ``route_interval=0``). A model's stiff source
  (``has_split_source``, e.g. mac1's friction) is applied by Strang splitting: half a step
  of it alone before the Runge-Kutta step and half a step after.
* :class:`FVController` decides *when*, one step at a time: the CFL time step (a step
  refused by a stage is taken again, shorter; a step may be shortened to end on a time
  the driver asks for). Output times and stopping are the run driver's.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import threading
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ... import parameters as P
from ...errors import ParameterError, SimulationError
from ...mesh.triangle_mesh import BoundaryKind, TriMesh
from . import fv_kernels as K
from .base import MacroModel
from .reconstruction import build_reconstruction

__all__ = ["FVOptions", "FVState", "FVSolver", "FVController", "PARALLEL_MIN_CELLS",
           "PARALLEL_MIN_CELLS_TBB", "threading_layer", "threading_note",
           "parallel_min_cells"]

#: meshes with fewer cells run the kernels on one thread, under numba's OpenMP (or
#: workqueue) threading layer: measured on 2 cores (idle), Example 2 eos steps 1.6x faster on
#: 2 threads with 15,835 cells and not at all with 3,995 (the threads' start and join cost
#: what they save). And when other processes keep the cores busy (several runs at once,
#: ensembles), OpenMP threads that wait for a descheduled partner make every step tens of
#: times slower (two Example 2 eos runs at once on 2 threads each: 38.6 s each instead of
#: 5.2 s alone): one thread is the safe choice there
PARALLEL_MIN_CELLS = 12_000
#: the same under numba's TBB threading layer (the default where the ``tbb`` package is
#: installed, a dependency on x86-64): TBB's work-stealing threads tolerate busy cores (two
#: such runs at once: 5.5 s each) and start faster: 2 threads save 6-15 % on Example 1-3's
#: 5,400-5,800 cells and lose 6-14 % on pillar_hall's 2,585 (whole runs, 2 cores)
PARALLEL_MIN_CELLS_TBB = 4_000
#: the active set (FVOptions.active_set) reaches this many face neighbours beyond the occupied
#: cells: the first ring receives what the occupied cells send within a step (under the CFL
#: condition a stage moves mass by at most one cell), the second keeps the front's
#: reconstruction and fluxes as without the active set
ACTIVE_RINGS = 2
#: CFL number of the semi-implicit step: on Example 2 with eos, 0.7 / 0.9 / 1.0 give T50 and
#: T90 within 0.1 / 0.2 / 0.4 % of each other (1.0 retries steps); its wave speeds are the
#: material ones, which the positivity bound (cfl = 1) already assumes
IMEX_CFL = 0.9


@dataclass(frozen=True, kw_only=True)
class FVOptions:
    """Numerical options of the finite-volume solver (declared, with units, bounds and
    meaning, in :mod:`pedmesh.parameters`).

    ``cfl`` None: IMEX_CFL for the semi-implicit step, else the model's ``default_cfl``
    (0.7; 0.9 for rdue; 0.4 for mac1 with its friction inside the stages); stages that
    outrun their own bound are retried (see FVController.advance). ``route_interval``:
    against every step, 0.5 s and 1 s change T50/T90 by at most 0.04 % for eos and rdue
    on Example 2 and the corridor bottleneck (benchmarks/continuum_speed.py --sweep).
    ``threads`` None: numba's thread count on meshes of at least PARALLEL_MIN_CELLS_TBB
    cells under the TBB threading layer (PARALLEL_MIN_CELLS under OpenMP), else 1.
    ``implicit_pressure`` (:mod:`pedmesh.models.continuum.implicit`) None: on for every
    model with a pressure law in its flux (eos, pw, mac2-local...). ``stages`` None: 3 for
    a pressure in explicit fluxes (implicit_pressure=0), else 2, which leaves T50 and T90
    of Example 2 the same to 0.01 s for eos, rdue, mac1 and mac2-nonlocal.
    ``active_set``: update only the cells with a density above ``active_eps`` and those
    within ACTIVE_RINGS neighbours of them (the others keep their state; no flux crosses
    between two of them).
    """

    order: int = P.field("order")
    cfl: float | None = P.field("cfl")
    exit: str | None = P.field("exit")
    limiter: bool = P.field("limiter")
    rho_eps: float = P.field("rho_eps")
    eps_hat: float = P.field("eps_hat")
    route_every_step: bool = P.field("route_every_step")
    route_interval: float = P.field("route_interval")
    threads: int | None = P.field("threads")
    implicit_pressure: bool | None = P.field("implicit_pressure")
    stages: int | None = P.field("stages")
    active_set: bool = P.field("active_set")
    active_eps: float = P.field("active_eps")

    def __post_init__(self) -> None:
        P.check_fields(self)


def _blow_up_advice(model, cfl: float) -> str:
    """What to change after a non-finite state: a smaller CFL number, and first any of the
    model's parameters outside its physical range (a run refuses those before it starts;
    physics built directly may hold them), named with the range."""
    advice = f"try a smaller CFL number, e.g. --param cfl={cfl / 2:g}"
    for name, v in model.parameters().items():
        p = P.PARAMETERS.get(name)
        if p is None or p.range is None or isinstance(v, bool) \
                or not isinstance(v, (int, float)):
            continue
        if not p.range[0] <= v <= p.range[1]:
            unit = "" if p.unit in ("", "-") else f" {p.unit}"
            return (f"parameter '{name}' = {v:g}{unit} is outside its physical range "
                    f"[{p.range[0]:g}, {p.range[1]:g}]{unit} (or {advice})")
    return advice


@dataclass
class FVState:
    """Conserved cell averages and bookkeeping of a finite-volume run."""

    Q: np.ndarray  #: (m, nv) cell averages
    t: float = 0.0  #: time [s]
    outflow: np.ndarray = field(default_factory=lambda: np.zeros(0))  #: cumulative per exit [ped]
    last_exit_flux: np.ndarray = field(default_factory=lambda: np.zeros(0))  #: [ped/s] per exit
    steps: int = 0

    def copy(self) -> "FVState":
        return FVState(self.Q.copy(), self.t, self.outflow.copy(), self.last_exit_flux.copy(),
                       self.steps)


class StageTooLong(Exception):
    """A stage's wave speeds put its forward-Euler positivity bound ``dt_fe`` [s] below the
    step length; the controller retries the step with a shorter one."""

    def __init__(self, dt_fe: float) -> None:
        super().__init__(f"stage forward-Euler bound {dt_fe:.3g} s")
        self.dt_fe = dt_fe


class FVSolver:
    """One residual and one SSP-RK3 step of a :class:`MacroModel` on a mesh.

    Parameters
    ----------
    mesh
        The triangle mesh (cells = triangles).
    model
        The continuum model (fluxes, sources, exit conditions).
    options
        Numerical options.
    boundary_state
        Verification only: ``fn(x, y, t) -> (k, nv)`` exterior states at every boundary
        Gauss point (exact Dirichlet data), replacing walls and exits.
    direction
        Verification only: a fixed desired direction ``fn(x, y) -> (k, 2)`` instead of the
        eikonal route.
    """

    def __init__(self, mesh: TriMesh, model: MacroModel, options: FVOptions | None = None, *,
                 boundary_state: Callable | None = None,
                 direction: Callable | None = None) -> None:
        self.mesh = mesh
        self.model = model
        self.options = options or FVOptions()
        self.exit_kind = model.check_exit(self.options.exit)
        #: threads the kernels run on (see FVOptions.threads)
        self.threads = _threads(self.options.threads, mesh.n_triangles)
        self.recon = build_reconstruction(mesh)
        model.bind(mesh)
        self._set_pressure_treatment(boundary_state)
        self._set_cfl_and_stages()
        self.boundary_state = boundary_state
        self._set_edges()
        self._set_full_active_set()
        self._set_geometry()
        self._set_directions(direction)

    # ------------------------------------------------------------------ set-up
    def _set_pressure_treatment(self, boundary_state: Callable | None) -> None:
        """Explicit or semi-implicit pressure (``implicit``, ``xmodel``): implicit by default
        for a model with a pressure law, unless ``boundary_state`` (verification) is given."""
        model = self.model
        #: the implicit pressure correction of the semi-implicit step (None: explicit), and
        #: the model whose fluxes and sources the explicit stages evaluate (the model itself,
        #: or its part without the pressure)
        self.implicit = None
        self.xmodel = model
        want = self.options.implicit_pressure
        able = bool(getattr(model, "supports_implicit_pressure", False))
        if want and not able:
            raise ParameterError(f"model '{model.name}' has no pressure law to treat "
                                 "implicitly (implicit_pressure=1)")
        if (want is None and able and boundary_state is None) or (want and able):
            from .implicit import ImplicitPressure

            self.xmodel = model.explicit_part()
            self.implicit = ImplicitPressure(self.mesh, model)

    def _set_cfl_and_stages(self) -> None:
        """The CFL number and the Runge-Kutta stages (``cfl``, ``stages``)."""
        model = self.model
        #: the CFL number and the Runge-Kutta stages in use (the options, else the defaults
        #: of the scheme and model: see FVOptions)
        cfl = self.options.cfl
        if cfl is None:
            cfl = (getattr(model, "imex_cfl", IMEX_CFL) if self.implicit is not None
                   else model.default_cfl)
        self.cfl = float(cfl)
        stages = self.options.stages
        if stages is None:  # 3 only for a pressure in explicit fluxes (the reference scheme)
            law = getattr(model, "law", None)
            explicit_pressure = self.implicit is None and law is not None and law.pressured
            stages = 3 if explicit_pressure else 2
        self.stages = int(stages)

    def _set_edges(self) -> None:
        """The mesh's edge connectivity as the kernels read it: the cells on each edge
        (``e2t``), each cell's edges (``t2e``), each edge's kind, and the interior, wall
        (and obstacle) and exit edges with each exit edge's exit number."""
        mesh = self.mesh
        e2t = mesh.edge_triangles
        self.e2t = e2t
        self.t2e = K.cell_edges(mesh)  # (m, 3) each cell's edges, for the gathering kernels
        self.kind = mesh.edge_kind
        self.interior = np.flatnonzero(e2t[:, 1] >= 0)
        self.walls = np.flatnonzero((self.kind == BoundaryKind.WALL)
                                    | (self.kind == BoundaryKind.OBSTACLE))
        self.exits = np.flatnonzero(self.kind == BoundaryKind.EXIT)
        self.exit_owner = mesh.edge_owner[self.exits]
        self.n_exits = len(mesh.exit_names)

    def _set_full_active_set(self) -> None:
        """The active set before the first step: every cell updated and every edge with a
        flux (as without FVOptions.active_set)."""
        mesh = self.mesh
        #: the active set of the current step: cells updated, edges with a flux (both cells
        #: active); all of them without FVOptions.active_set
        self.cact = np.ones(mesh.n_triangles, np.bool_)
        self.live = np.ones(mesh.n_edges, np.bool_)
        self.n_active = mesh.n_triangles
        self._live_faces = None  # (the live edges in the implicit correction's numbering)
        self._lo_key = None  # (max_dt's state: Q, t, sum of Q; see residual)

    def _set_geometry(self) -> None:
        """Cell areas [m^2] and their inverses, edge lengths [m], the unit edge normals per
        edge and Gauss point, the 3 interior quadrature points [m] of each cell, and the
        reference scale of the conserved variables for the reconstruction."""
        from .reconstruction import INTERIOR_BARY

        mesh = self.mesh
        self.areas = mesh.areas
        self.inv_areas = 1.0 / mesh.areas
        self.lengths = mesh.edge_lengths
        n = mesh.edge_normals
        self.nx2 = np.repeat(n[:, 0], 2).reshape(-1, 2)  # per edge and Gauss point
        self.ny2 = np.repeat(n[:, 1], 2).reshape(-1, 2)
        corners = mesh.points[mesh.triangles]
        self.int_pts = np.einsum("pb,mbd->mpd", INTERIOR_BARY, corners)  # (m, 3, 2)
        self.qref = np.ones(self.model.n_vars)

    def _set_directions(self, direction: Callable | None) -> None:
        """The desired direction at the edge Gauss points, the interior points and the
        centroids: from the fixed ``direction`` (verification), else zero until the first
        route solve (with an eikonal solver if the model needs routes)."""
        mesh = self.mesh
        self._fixed_direction = direction
        self.e_edge = np.zeros((mesh.n_edges, 2, 2))
        self.e_int = np.zeros((mesh.n_triangles, 3, 2))
        self.e_cell = np.zeros((mesh.n_triangles, 2))
        self.phi = np.zeros(mesh.n_points)
        self._eikonal = None
        if direction is not None:
            self.e_edge = np.asarray(direction(self.recon.edge_pt[..., 0],
                                               self.recon.edge_pt[..., 1]), float)
            self.e_int = np.asarray(direction(self.int_pts[..., 0], self.int_pts[..., 1]), float)
            self.e_cell = np.asarray(direction(mesh.centroids[:, 0], mesh.centroids[:, 1]), float)
        elif self.model.needs_route:
            from ...eikonal import EikonalSolver

            atlas = mesh._cache.get("atlas")  # a building's glued atlas: routes on its surface
            if atlas is not None:
                from ...eikonal.surface import BuildingRoutes

                self._eikonal = BuildingRoutes(atlas)
                self.phi = np.zeros(atlas.surface.n_points)  # (on the surface's vertices)
            else:
                self._eikonal = EikonalSolver(mesh)
        self._route_done = False
        self._route_t = -math.inf  # time of the last route solve [s]
        self._sample_directions()

    # ------------------------------------------------------------------ routes
    def set_direction(self, direction: Callable) -> None:
        """Steer by the fixed field ``direction(x, y) -> (..., 2)`` from now on (the
        constructor's ``direction``; e.g. a hybrid model's route, solved elsewhere),
        sampled anew at every point the solver reads directions at."""
        self._set_directions(direction)

    def update_route(self, Q: np.ndarray, t: float | None = None) -> None:
        """Re-solve the route potential with cost 1/U_e(rho) and sample the direction.
        With the time ``t`` [s], not before ``route_interval`` has passed since the last
        solve."""
        if self._eikonal is None:
            return
        if self._route_done and not self.options.route_every_step:
            return
        if (self._route_done and t is not None
                and t < self._route_t + self.options.route_interval * (1 - 1e-9)):
            return
        self._route_t = -math.inf if t is None else t
        from ...eikonal import EikonalSolver
        from ...eikonal.direction import DirectionField, _vertex_averaging

        factors = None
        if isinstance(self._eikonal, EikonalSolver):
            rho_v = _vertex_averaging(self.mesh) @ np.maximum(Q[:, 0], 0.0)
            self.phi = self._eikonal.solve(self.model.route_cost(rho_v))
            df = DirectionField(self.mesh, self.phi)
        else:  # a building (BuildingRoutes): the potential on its surface
            surface = self._eikonal.surface
            rho_v = _vertex_averaging(surface) @ np.maximum(Q[:, 0], 0.0)
            self.phi, df, factors = self._eikonal.solve(self.model.route_cost(rho_v))
        m = self.mesh.n_triangles
        if self.model.direction_dependent_flux:  # (else no flux reads it)
            self.e_edge = df.at(self.recon.edge_pt.reshape(-1, 2),
                                np.repeat(self.e2t[:, 0], 2)).reshape(-1, 2, 2)
            near, normals = self._edge_wall_normals()
            self.e_edge[near] = _slide_along_walls(self.e_edge[near], normals)
        self.e_int = df.at(self.int_pts.reshape(-1, 2), np.repeat(np.arange(m), 3)).reshape(m, 3, 2)
        self.e_cell = df.triangle_directions
        if factors is not None and np.any(factors != 1.0):
            # on a stair the desired velocity is the stair's share of the level's: the
            # direction scaled by it (at a stair edge the slower side's)
            fe = np.minimum(factors[self.e2t[:, 0]],
                            np.where(self.e2t[:, 1] >= 0, factors[np.maximum(self.e2t[:, 1], 0)],
                                     np.inf))
            if self.model.direction_dependent_flux:  # (else e_edge is never re-sampled)
                self.e_edge = self.e_edge * fe[:, None, None]
            self.e_int = self.e_int * factors[:, None, None]
            self.e_cell = self.e_cell * factors[:, None]
        self._sample_directions()
        self._route_done = True

    def _edge_wall_normals(self) -> tuple[np.ndarray, np.ndarray]:
        """The edges of the cells against a wall or obstacle (k,), and (k, 4, 2) the outward
        normals of the walls and obstacle sides of the (one or two) cells on each, up to two
        per cell, zero rows where there are fewer."""
        if getattr(self, "_ewn", None) is None:
            mesh = self.mesh
            m = mesh.n_triangles
            tw = np.zeros((m, 2, 2))
            used = np.zeros(m, np.int64)
            for w in self.walls:  # (a boundary edge's normal points out of its one cell)
                cell = self.e2t[w, 0]
                if used[cell] < 2:
                    tw[cell, used[cell]] = mesh.edge_normals[w]
                    used[cell] += 1
            L, R = self.e2t[:, 0], self.e2t[:, 1]
            ewn = np.concatenate([tw[L], np.where((R >= 0)[:, None, None],
                                                  tw[np.maximum(R, 0)], 0.0)], axis=1)
            near = np.flatnonzero(np.abs(ewn).sum(axis=(1, 2)) > 0)
            self._ewn = (near, np.ascontiguousarray(ewn[near]))
        return self._ewn

    # ------------------------------------------------------------------ residual
    def _buffers(self, nv: int):
        """Per-category work arrays (allocated once)."""
        if getattr(self, "_buf_nv", None) == nv:
            return
        self._buf_nv = nv
        m = self.mesh.n_triangles
        # edge states in the order the fluxes read them: Es[side, position, gauss point],
        # positions = interior edges, then walls, then exits; the reconstruction writes point
        # p of cell i straight into row slot[i, p] of Es (no gathering)
        ne = self.mesh.n_edges
        self._Es = np.zeros((2, ne, 2, nv))  # (the outer side of boundary edges stays unused)
        self._Vi = np.empty((m, 3, nv))  # reconstructed values at the interior points
        self._slot = self._edge_slots()
        self._cat = {}
        start = 0
        for name, idx in (("interior", self.interior), ("wall", self.walls), ("exit", self.exits)):
            k = len(idx)
            self._cat[name] = dict(
                idx=idx, qL=self._Es[0, start:start + k], qR=self._Es[1, start:start + k],
                qL1=np.empty((k, 1, nv)), qR1=np.empty((k, 1, nv)),  # one state per edge
                nx=np.ascontiguousarray(self.nx2[idx].ravel()),
                ny=np.ascontiguousarray(self.ny2[idx].ravel()),
                nx1=np.ascontiguousarray(self.nx2[idx, 0]),
                ny1=np.ascontiguousarray(self.ny2[idx, 0]),
                pts=np.ascontiguousarray(self.recon.edge_pt[idx].reshape(-1, 2)),
            )
            start += k
        self._F = np.empty((self.mesh.n_edges, nv))
        self._FL = np.empty((self.mesh.n_edges, nv))
        self._Fb = np.empty((self.mesh.n_edges, nv))
        self._theta = np.empty(self.mesh.n_edges)
        self._alpha = np.zeros(self.mesh.n_edges)
        self._vlo = np.zeros((m, 2))
        self._vhi = np.zeros((m, 2))
        self._vact = np.zeros(m, np.bool_)
        self._fct_work = (np.empty((nv, m)), np.empty((5, m)), np.empty((5, m)))
        self._sample_directions()

    def _edge_slots(self) -> np.ndarray:
        """(m, 6) row of ``Es.reshape(-1, nv)`` for edge Gauss point p of cell i."""
        ne = self.mesh.n_edges
        order = np.concatenate([self.interior, self.walls, self.exits])
        pos = np.empty(ne, np.int64)
        pos[order] = np.arange(ne)
        slot = np.full((self.mesh.n_triangles, 6), -1, np.int64)
        ecp = self.recon.edge_cell_pt
        for side in range(2):
            t = self.e2t[:, side]
            ok = np.flatnonzero(t >= 0)
            for g in range(2):
                slot[t[ok], ecp[ok, side, g]] = (side * ne + pos[ok]) * 2 + g
        assert (slot >= 0).all()
        return slot

    def _sample_directions(self) -> None:
        """The route directions as the kernels read them: at the edges' Gauss points per
        edge category (``ex``, ``ey``, ``ex1``, ``ey1``; sampled once for a model whose flux
        does not read them) and at the cells' interior points."""
        for c in getattr(self, "_cat", {}).values():
            if "ex" in c and not self.model.direction_dependent_flux:
                continue  # (e_edge is not re-sampled either: no flux reads it)
            c["ex"] = np.ascontiguousarray(self.e_edge[c["idx"], :, 0].ravel())
            c["ey"] = np.ascontiguousarray(self.e_edge[c["idx"], :, 1].ravel())
            c["ex1"] = np.ascontiguousarray(self.e_edge[c["idx"], 0, 0])
            c["ey1"] = np.ascontiguousarray(self.e_edge[c["idx"], 0, 1])
        self._e_int_x = np.ascontiguousarray(self.e_int[..., 0].ravel())
        self._e_int_y = np.ascontiguousarray(self.e_int[..., 1].ravel())

    def _fluxes(self, t: float, F: np.ndarray, constant: bool = False,
                alpha: np.ndarray | None = None, skip_interior: bool = False) -> None:
        """Edge fluxes (integrated over the edges, L -> R) from the edge states.
        ``constant``: first-order states, the same at both Gauss points; models whose flux
        does not depend on the direction then evaluate one point per edge (the ``*1``
        arrays: ``qL1``, ``nx1``, ...), the others both (``qL``, ``nx``, ...).
        ``alpha`` (n_edges,): receives each edge's largest wave speed [m/s] (at walls and
        exits that of the inner state, as in :meth:`max_dt`). ``skip_interior``: the
        interior edges are done elsewhere (:meth:`_low_order`)."""
        model = self.xmodel
        nv = model.n_vars
        one = self._one_point_low_order(constant)
        sfx = "1" if one else ""
        for name, c in self._cat.items():
            idx = c["idx"]
            if len(idx) == 0 or (skip_interior and name == "interior"):
                continue
            qL = c["qL" + sfx].reshape(-1, nv)
            geo = (c["nx" + sfx], c["ny" + sfx], c["ex" + sfx], c["ey" + sfx])
            a = None
            if (name == "interior" and not one and alpha is None and model.edge_flux is not None
                    and self.boundary_state is None):
                model.edge_flux(c["qL"], c["qR"], c["nx1"], c["ny1"], c["ex"], c["ey"], idx,
                                self.lengths, F, self.live)
                continue
            if (name != "interior" and model.boundary_flux is not None
                    and self.boundary_state is None
                    and model.boundary_flux(name, qL, geo[0], geo[1], c["qL" + sfx].shape[1],
                                            idx, self.lengths, F, alpha, self.live,
                                            self.exit_kind)):
                continue
            if name == "interior":
                Fp, a = model.flux(qL, c["qR" + sfx].reshape(-1, nv), *geo)
            elif self.boundary_state is not None:  # (never with one point per edge)
                g = np.asarray(self.boundary_state(c["pts"][:, 0], c["pts"][:, 1], t),
                               float).reshape(-1, nv)
                Fp, a = model.flux(qL, g, *geo)
            elif name == "wall":
                Fp = model.wall_flux(qL, *geo)
            else:
                Fp = model.exit_flux(qL, *geo, self.exit_kind)
            if alpha is not None:
                if a is None and name == "exit":
                    a = model.exit_wave_speed(qL, Fp, geo[0], geo[1])
                if a is None:
                    _, a = model.flux(qL, qL, *geo)
                K.edge_max(np.ascontiguousarray(a, dtype=np.float64).reshape(len(idx), -1), idx,
                           alpha, self.live)
            K.integrate_edges(np.ascontiguousarray(Fp).reshape(len(idx), -1, nv), self.lengths,
                              idx, F, self.live)

    def _low_order(self, Q: np.ndarray, t: float, F: np.ndarray, alpha: np.ndarray) -> None:
        """First-order edge fluxes ``F`` of cell averages ``Q`` and every edge's largest wave
        speed ``alpha`` [m/s]. A model's ``cell_flux`` reads the interior edges' cell
        averages in place (no gathered edge states)."""
        one = self._one_point_low_order(True)
        sfx = "1" if one else ""
        fused = self.xmodel.cell_flux is not None and self.boundary_state is None
        for name, c in self._cat.items():
            if not (fused and name == "interior"):
                K.gather_cells(Q, self.e2t, c["idx"], c["qL" + sfx], c["qR" + sfx], self.live)
        alpha[:] = 0.0
        self._fluxes(t, F, constant=True, alpha=alpha, skip_interior=fused)
        if fused:
            c = self._cat["interior"]
            self.xmodel.cell_flux(Q, self.e2t, c["idx"], c["nx1"], c["ny1"], c["ex"], c["ey"],
                                  self.lengths, F, alpha, self.live)

    def _one_point_low_order(self, constant: bool) -> bool:
        return (constant and not self.model.direction_dependent_flux
                and self.boundary_state is None)

    def residual(self, Q: np.ndarray, t: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """dQ/dt of a forward-Euler stage of length ``dt`` (which the flux limiter needs) and
        the exit mass flux per exit [ped/s]."""
        opt, model, R = self.options, self.xmodel, self.recon
        m, nv = Q.shape
        self._buffers(nv)
        Es, Vi = self._Es.reshape(-1, nv), self._Vi
        R.apply(Q, Es, Vi, order=opt.order, eps_hat=opt.eps_hat, qref=self.qref,
                slot=self._slot,
                positivity=(opt.rho_eps, model_rho_cut(model)) if opt.limiter else None,
                cact=self.cact)
        F = self._F
        fct = opt.limiter and opt.order > 1
        FH = self._Fb if fct else F  # the high-order fluxes
        self._fluxes(t, FH)
        dQ = np.empty_like(Q)
        if fct:
            FL, alpha = self._FL, self._alpha
            key, self._lo_key = self._lo_key, None
            if not (key is not None and key[0] is Q and key[1] == t
                    and key[2] == K.fingerprint(Q)):
                self._low_order(Q, t, FL, alpha)
            # (else max_dt's, of these very cell averages: its wave speeds floored, which
            # only makes the check below stricter)
            # the flux limiter keeps rho >= 0 only if the first-order stage does: dt within
            # the forward-Euler bound of this stage's wave speeds (which can exceed those of
            # the step start, from which the step was sized)
            dt_fe = K.cfl_dt(alpha, self.lengths, self.e2t, self.t2e, self.areas, 1.0, self.cact)
            if dt > dt_fe:
                raise StageTooLong(dt_fe)
            use_vel = bool(getattr(model, "pressureless", False)) and nv == 3
            if use_vel:
                K.velocity_bounds(Q, self.mesh.triangle_neighbors, model_rho_cut(model),
                                  self._vlo, self._vhi, self._vact, self.cact)
            K.fct_blend(FH, FL, self.e2t, self.t2e, self.inv_areas, Q, dt, opt.rho_eps, F,
                        self._theta, use_vel, self._vlo, self._vhi, self._vact, *self._fct_work, dQ,
                        self.cact, self.live)
        else:
            K.divergence(F, self.e2t, self.t2e, self.inv_areas, dQ, self.cact)
        if model.source_mean is not None:
            model.source_mean(Vi, self._e_int_x, self._e_int_y, dQ, self.cact)
        else:
            S = model.source(Vi.reshape(-1, nv), self._e_int_x, self._e_int_y)
            K.add_point_mean(np.ascontiguousarray(S), dQ, self.cact)
        C = model.cell_source(Q)
        if C is not None:
            if self.n_active < len(Q):
                C = C * self.cact[:, None]
            dQ += C
        out = np.bincount(self.exit_owner, weights=F[self.exits, 0], minlength=self.n_exits)
        return dQ, out

    # ------------------------------------------------------------------ stepping
    def max_dt(self, Q: np.ndarray, t: float = 0.0) -> float:
        """The CFL time step [s] of the state at time ``t`` [s]: ``cfl`` times the
        forward-Euler positivity bound of the first-order fluxes at the cell averages (the
        bound every stage checks, see :class:`StageTooLong`), and the model's source limit."""
        self._buffers(Q.shape[1])
        alpha = self._alpha
        self._low_order(Q, t, self._FL, alpha)
        self._lo_key = (Q, t, K.fingerprint(Q))  # the first stage of a step from Q reuses them
        floor = float(getattr(self.model, "speed_floor", 0.0))
        if floor > 0:
            np.maximum(alpha, floor, out=alpha)
        dt = K.cfl_dt(alpha, self.lengths, self.e2t, self.t2e, self.areas, self.cfl, self.cact)
        return min(dt, self.model.source_dt(Q))

    def step(self, state: FVState, dt: float) -> None:
        """One Shu-Osher SSP Runge-Kutta step (:attr:`stages`) of length ``dt`` [s], in
        place."""
        Q, t = state.Q, state.t
        split = self.model.has_split_source
        if split:  # Strang: half the stiff source, the SSP-RK3 step, the other half
            Q = self.model.split_source(Q, 0.5 * dt)
        Q1, o0 = self._stage(Q, t, dt)
        S1, o1 = self._stage(Q1, t + dt, dt)
        if self.stages == 2:  # Heun (one pass on the threads: the sum, its range, finite)
            Qn = np.empty_like(Q)
            rho_lo, rho_hi, finite = K.heun_combine(Q, S1, Qn)
            flow = 0.5 * (o0 + o1)
        else:
            Q2 = 0.75 * Q + 0.25 * S1
            S2, o2 = self._stage(Q2, t + 0.5 * dt, dt)
            Qn = Q / 3.0 + 2.0 / 3.0 * S2
            flow = (o0 + o1 + 4.0 * o2) / 6.0
            rho_lo, rho_hi, finite = float(Qn[:, 0].min()), float(Qn[:, 0].max()), None
        # the stages keep rho >= 0 exactly; their convex combination can leave round-off
        # negatives (1e-40) in emptied cells: set those to zero (mass change ~1e-40)
        if rho_lo < 0.0:
            neg = Qn[:, 0] < 0.0
            tiny = neg & (Qn[:, 0] > -1e-12 * max(float(rho_hi), 1.0))
            Qn[tiny] = 0.0
        if split:
            Qn = self.model.split_source(Qn, 0.5 * dt)
            finite = None
        state.Q = Qn
        state.outflow = state.outflow + dt * flow
        state.last_exit_flux = flow
        state.t = t + dt
        state.steps += 1
        if not (finite if finite is not None else np.all(np.isfinite(state.Q))):
            raise SimulationError(f"non-finite state at t = {state.t:.3f} s; "
                                  + _blow_up_advice(self.model, self.cfl))

    def _stage(self, Q: np.ndarray, t: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """A forward-Euler stage of length ``dt`` [s] from ``Q`` at time ``t`` [s] (the
        explicit stage, then the implicit pressure correction of a semi-implicit step) and
        the exit mass flux per exit [ped/s]."""
        L, out = self.residual(Q, t, dt)
        V = np.empty_like(Q)
        K.stage_update(Q, dt, L, V)
        if self.implicit is not None:
            if self._live_faces is None:
                self._live_faces = self.implicit.live_faces(self.live)
            V = self.implicit.correct(V, L[:, 1:3], dt, self.cact, self._live_faces)
        return V, out

    def update_active_set(self, Q: np.ndarray) -> int:
        """The active set of the next step from the state ``Q`` (FVOptions.active_set;
        else every cell and edge stays active); returns the number of active cells."""
        if self.options.active_set and self.boundary_state is None:
            self.n_active = int(K.active_set(Q, self.mesh.triangle_neighbors, self.e2t,
                                             self.options.active_eps, ACTIVE_RINGS, self.cact,
                                             self.live))
            self._live_faces = None
            self.model.active = self.cact
        return self.n_active

    def mass(self, Q: np.ndarray) -> float:
        """Number of pedestrians inside [ped]."""
        return float(K.cell_total(self.areas, Q))


def threading_layer() -> str:
    """The threading layer numba runs the kernels' parallel loops on: ``'tbb'``, ``'omp'``
    or ``'workqueue'`` (numba picks the first it can load, TBB first; started here by a
    trivial parallel loop if it has not been yet)."""
    import numba

    try:
        return numba.threading_layer()
    except ValueError:  # no parallel loop has run yet in this process
        K.launch_threads(np.zeros(1))
        return numba.threading_layer()


def threading_note() -> str:
    """One line on the threading layer (for ``pedmesh --version`` and the run warnings):
    which layer numba runs the parallel kernels on, and what it means when it is not TBB."""
    from ..._threads import tbb_load_status

    layer = threading_layer()
    if layer == "tbb":
        return "parallel kernels on numba's TBB threading layer"
    return (f"parallel kernels on numba's '{layer}' threading layer, not TBB (oneTBB "
            f"{tbb_load_status()}): several runs at once may slow each other down many "
            "times; `pip install tbb` to fix")


def parallel_min_cells() -> int:
    """The smallest mesh [cells] whose kernels run on more than one thread by default:
    :data:`PARALLEL_MIN_CELLS_TBB` under TBB, else :data:`PARALLEL_MIN_CELLS`."""
    return PARALLEL_MIN_CELLS_TBB if threading_layer() == "tbb" else PARALLEL_MIN_CELLS


def _slide_along_walls(e: np.ndarray, wall_normals: np.ndarray) -> np.ndarray:
    """The directions ``e`` (n_edges, 2, 2) at the edges' Gauss points without their
    components into the walls of the cells on each edge (``wall_normals`` (n_edges, 4, 2),
    outward, zero rows ignored), renormalised.

    For a flux ``f(rho) e.n`` (rdue) a cell against a wall whose route direction points into
    the wall is otherwise a trap: the interpolated directions (:mod:`pedmesh.eikonal.direction`)
    are tangent on the wall itself but still point into it at the cell's other two edges
    (their correction fades across the triangle), so mass flows in there and cannot leave,
    where pedestrians would slide along the wall. It happens on the ridge of the route in
    front of an obstacle face (the middle of a pillar's face towards the crowd): on the
    10,000-person venue two people's worth stayed in such cells for ever. In the cells
    against a wall the direction is now turned along it at all their edges."""
    out = e.copy()
    for k in range(wall_normals.shape[1]):
        n = wall_normals[:, k]  # (n_edges, 2)
        into = np.maximum(np.einsum("egd,ed->eg", out, n), 0.0)
        out -= into[..., None] * n[:, None, :]
    norm = np.hypot(out[..., 0], out[..., 1])
    changed = norm < 1.0 - 1e-12
    big = changed & (norm > 1e-9)
    out[big] /= norm[big][:, None]
    out[changed & ~big] = 0.0
    return out


def _threads(wanted: int | None, cells: int) -> int:
    import numba

    most = numba.get_num_threads()
    if wanted is None:
        return most if most > 1 and cells >= parallel_min_cells() else 1
    return min(wanted, numba.config.NUMBA_NUM_THREADS)


_BLAS = None


def _one_blas_thread():
    """A context in which BLAS (OpenBLAS under numpy and scipy) runs on one thread: the
    conjugate gradients of the implicit step take dot products of 10^4 numbers, which
    OpenBLAS splits over a second thread that then spins against numba's threads (measured:
    every parallel kernel of the step 5-40 times slower). The caller's setting is back
    afterwards. (Entering and leaving it costs 0.02-0.1 ms: a run enters it once, for all
    its steps, through :meth:`FVController.stepping`.)"""
    global _BLAS
    if _BLAS is None:
        # scipy's BLAS loaded before the libraries are listed (scipy.linalg loads the
        # OpenBLAS of scipy.sparse.linalg too, and numba has imported it already)
        import scipy.linalg  # noqa: F401
        from threadpoolctl import ThreadpoolController

        _BLAS = ThreadpoolController()
    return _BLAS.limit(limits=1, user_api="blas")


def model_rho_cut(model: MacroModel) -> float:
    return getattr(model, "rho_cut", 1e-8)


class FVController:
    """Takes the steps of a finite-volume run, one per :meth:`advance`: the route update,
    the CFL step (shortened to end on a given time, never lengthened), and a stage that
    outruns its own stability bound taken again with a shorter step. Output times and
    stopping are the run driver's (:mod:`pedmesh.run.driver`).

    Parameters
    ----------
    solver
        The solver.
    state
        Initial state (modified in place).
    """

    def __init__(self, solver: FVSolver, state: FVState) -> None:
        self.solver = solver
        self.state = state
        if len(state.outflow) == 0:
            state.outflow = np.zeros(solver.n_exits)
            state.last_exit_flux = np.zeros(solver.n_exits)
        self.mass0 = solver.mass(state.Q) + float(state.outflow.sum())
        self.dt_last = 0.0
        self.retried = 0  #: steps taken again with a shorter dt (see :class:`StageTooLong`)
        self._held: int | None = None  # (the thread within :meth:`stepping`, if any)

    @contextlib.contextmanager
    def stepping(self):
        """A context for many :meth:`advance` calls on this thread: numba's thread count set
        to the solver's and BLAS limited to one thread (:func:`_one_blas_thread`) once for
        all of them instead of at every step (threadpoolctl's limit costs 0.02-0.1 ms each
        time it is entered and left); the caller's settings are back afterwards. Nested on
        the same thread it does nothing (the outer one restores them)."""
        import numba

        me = threading.get_ident()
        if self._held == me:
            yield
            return
        before = numba.get_num_threads()  # (numba's count is the calling thread's own)
        if before != self.solver.threads:
            numba.set_num_threads(self.solver.threads)
        try:
            with _one_blas_thread():
                outer = self._held is None  # (else another thread's: its steps as before)
                if outer:
                    self._held = me
                try:
                    yield
                finally:
                    if outer:
                        self._held = None
        finally:
            if before != self.solver.threads:
                numba.set_num_threads(before)

    def advance(self, t_stop: float | None = None) -> float:
        """One step (no further than ``t_stop`` [s]); returns the step length [s].

        Without ``t_stop`` (or with ``math.inf``) the step is the CFL step, exactly as
        before ``t_stop`` existed. With it the step is only ever shortened, never stretched:

        * one that would pass ``t_stop`` ends on it exactly (``state.t == t_stop``
          afterwards, even where ``t + (t_stop - t)`` would round off by an ulp);
        * one that would stop short of it by less than a tenth of itself is replaced by half
          the remaining time, so that the next step lands on ``t_stop`` and no sliver of a
          step is taken (both halves are over 0.5 and under 0.55 of the CFL step).

        A step whose stage outruns its forward-Euler bound is taken again with ``cfl`` times
        that bound (and at most 0.9 of the rejected length), and then does not land; since
        that is at most 0.9 of the time left, the gap it leaves is over a tenth of it. The
        state is only replaced by a completed step.

        Raises ValueError if ``t_stop`` is NaN or not after the current time.

        The step runs on the solver's threads and with BLAS on one thread (see
        :meth:`stepping`, which sets both once for many steps); the caller's settings are
        back afterwards."""
        if self._held == threading.get_ident():
            return self._advance(t_stop)
        with self.stepping():
            return self._advance(t_stop)

    def _advance(self, t_stop: float | None) -> float:
        s = self.solver
        t0 = self.state.t
        limited = t_stop is not None and t_stop != math.inf  # NaN is limited, and refused
        if limited and not (float(t_stop) > t0):  # NaN fails too
            raise ValueError(f"t_stop must be later than the current time {t0!r} s, "
                             f"got {t_stop!r}")
        s.update_route(self.state.Q, t0)
        s.update_active_set(self.state.Q)
        dt = s.max_dt(self.state.Q, t0)
        if not np.isfinite(dt) or dt <= 0:
            dt = 1e-2
        land = False
        if limited:
            rest = float(t_stop) - t0
            if rest <= dt:
                dt, land = rest, True
            elif rest < 1.1 * dt:
                dt = 0.5 * rest
        for _ in range(40):
            try:
                s.step(self.state, dt)
                break
            except StageTooLong as e:
                self.retried += 1
                dt = min(s.cfl * e.dt_fe, 0.9 * dt)
                land = False
        else:
            raise SimulationError(
                f"no stable time step found at t = {self.state.t:.3f} s (last tried {dt:.3g} s)")
        if land:
            self.state.t = float(t_stop)  # t + (t_stop - t) can miss t_stop by an ulp
        self.dt_last = dt
        return dt

    @property
    def mass_error(self) -> float:
        """``|inside + out - initial| / initial``."""
        inside = self.solver.mass(self.state.Q)
        return abs(inside + float(self.state.outflow.sum()) - self.mass0) / max(self.mass0, 1e-300)
