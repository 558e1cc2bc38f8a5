"""The interface every continuum model implements (registered with
:func:`pedmesh.models.continuum.adapter.register_continuum_model`)."""

from __future__ import annotations

import dataclasses

import numpy as np

from ...errors import ParameterError

__all__ = ["MacroModel"]

#: [m/s] the lowest speed the default route cost assumes of a model's own speed
ROUTE_SPEED_FLOOR_M_S = 0.05
#: the optional one-pass hooks and the methods whose work each does
ONE_PASS_HOOKS = {"cell_flux": ("flux",), "edge_flux": ("flux",), "source_mean": ("source",),
                  "boundary_flux": ("flux", "wall_flux", "exit_flux", "exit_wave_speed")}


class MacroModel:
    """A continuum model for the finite-volume core.

    The core reconstructs point values and calls these vectorised methods; it knows nothing
    model-specific. Arrays are over k points: states ``q`` (k, nv), unit normals ``nx``,
    ``ny`` (k,) and the desired direction ``ex``, ``ey`` (k,) at the same points.
    """

    name: str = "model"
    #: number of conserved variables: 1 (density) or 3 (density, x- and y-momentum)
    n_vars: int = 3
    #: exit conditions this model offers; the first is the default
    exit_conditions: tuple[str, ...] = ("vacuum", "transmissive")
    #: the model needs the desired direction e (eikonal) at the quadrature points
    needs_route: bool = True
    #: the numerical fluxes (interior, wall and exit) depend on the direction e (so they
    #: differ between Gauss points even for equal states); if not, the solver does not
    #: sample e at the edges
    direction_dependent_flux: bool = True
    #: CFL number when the options do not set one (see
    #: :class:`~pedmesh.models.continuum.solver.FVOptions`)
    default_cfl: float = 0.7

    def __init_subclass__(cls, **kwargs) -> None:
        """A subclass that overrides a method (:meth:`flux`, :meth:`source`, ...) below the
        class that supplies a one-pass hook doing its work (``ONE_PASS_HOOKS``) loses the
        hook: the hook computes its owner's methods, so the solver takes the generic path
        instead."""
        super().__init_subclass__(**kwargs)
        mro = cls.__mro__
        for hook, methods in ONE_PASS_HOOKS.items():
            owner = next(k for k in mro if hook in vars(k))
            if vars(owner)[hook] is None:
                continue
            if any(mro.index(next(k for k in mro if m in vars(k))) < mro.index(owner)
                   for m in methods):
                setattr(cls, hook, None)

    def flux(self, qL, qR, nx, ny, ex, ey):
        """Numerical flux density (k, nv) across the normal (from L to R) and the wave speed
        (k,) used for it."""
        raise NotImplementedError

    #: optional ``cell_flux(Q, e2t, edges, nx, ny, ex, ey, lengths, F, alpha, live)``: the
    #: first-order fluxes of interior ``edges`` read straight from the cell averages ``Q``,
    #: integrated over the edges into ``F`` (n_edges, nv), and each edge's largest wave speed
    #: into ``alpha``; unit normals (k,) per edge, directions (2 k,) at the 2 Gauss points of
    #: each edge; both 0 on edges that are not ``live`` (n_edges,) (the active set). None:
    #: the solver gathers the cell states and calls :meth:`flux`
    cell_flux = None
    #: optional ``edge_flux(qL, qR, nx, ny, ex, ey, edges, lengths, F, live)``: :meth:`flux`
    #: at the 2 Gauss points of interior ``edges`` (states (k, 2, nv), unit normals (k,) per
    #: edge, directions (2 k,) per point), integrated over the edges into ``F`` in one pass
    #: (0 on edges not ``live``); None: the solver calls :meth:`flux` and integrates
    edge_flux = None
    #: optional ``boundary_flux(name, q, nx, ny, g, edges, lengths, F, alpha, live,
    #: exit_kind) -> bool``: the wall ('wall') or exit ('exit') fluxes of ``edges`` (states
    #: (k g, nv) at ``g`` points per edge, unit normals (k g,)) integrated over the edges
    #: into ``F`` in one pass, with each edge's largest wave speed into ``alpha`` unless it is
    #: None (0 on edges not ``live``), as :meth:`wall_flux`, :meth:`exit_flux` and
    #: :meth:`exit_wave_speed` give them (to round-off); False where it does not cover the
    #: case. None: the solver calls those methods and integrates
    boundary_flux = None

    def wall_flux(self, q, nx, ny, ex, ey):
        """Flux density (k, nv) through a wall with outward normal n (zero mass flux)."""
        raise NotImplementedError

    def exit_flux(self, q, nx, ny, ex, ey, kind: str):
        """Flux density (k, nv) out through an exit with outward normal n."""
        raise NotImplementedError

    def exit_wave_speed(self, q, F, nx, ny):
        """The wave speed (k,) [m/s] of exit points (states ``q``, exit fluxes ``F``) for
        the time step, or None: the Rusanov speed of the state."""
        return None

    def source(self, q, ex, ey):
        """Source (k, nv) at interior quadrature points."""
        return np.zeros_like(q)

    #: optional ``source_mean(Vi, ex, ey, dQ, cact)``: adds the mean of :meth:`source` at the
    #: 3 interior points of every active cell (``cact`` (m,); states ``Vi`` (m, 3, nv),
    #: directions (3 m,)) to ``dQ`` in one pass; None: the solver calls :meth:`source` and
    #: averages
    source_mean = None

    def bind(self, mesh) -> None:
        """Prepare mesh-dependent operators (called once by the solver)."""

    def cell_source(self, Q):
        """Cell-average source (m, nv) computed from cell averages (nonlocal terms), or
        None."""
        return None

    def source_dt(self, Q) -> float:
        """Largest stable time step [s] of the sources (inf if they do not limit it)."""
        return np.inf

    #: the solver's active set of the current step (bool (m,)), or None (every cell): a
    #: model's own cell operators (nonlocal forces, split sources) may skip the other cells,
    #: whose state the step keeps
    active = None

    #: the model has a stiff source that the solver applies by Strang splitting around each
    #: SSP-RK3 step (:meth:`split_source`) instead of inside the stages
    has_split_source: bool = False

    def split_source(self, Q: np.ndarray, dt: float) -> np.ndarray:
        """The state (m, nv) after the split source acted alone for ``dt`` [s] on ``Q``
        (a new array; the density must not change)."""
        raise NotImplementedError

    #: smallest wave speed [m/s] the CFL condition assumes
    speed_floor: float = 0.0

    def velocity(self, q):
        """(k, 2) velocity [m/s] of the states (for output; a density-only model's comes
        from :meth:`speed`)."""
        raise NotImplementedError

    def route_cost(self, rho):
        """The cost [s/m] of walking through the densities ``rho`` [ped/m^2] (at the mesh
        vertices): the route potential solves ``|grad phi| = cost``. By default 1/U_e(rho)
        of the model's speed law :attr:`speed` (a :class:`pedmesh.speed.SpeedLaw`,
        unshifted: the social force model's routes see the crowd's density too), or
        1/speed(rho) (at least ``ROUTE_SPEED_FLOOR_M_S``) of a model's own speed."""
        from ...speed import SpeedLaw

        speed = self.speed
        if isinstance(speed, SpeedLaw):
            if speed.name == "exponential" and not speed.shift:
                return np.exp(speed.beta * rho) / speed.U_f
            return dataclasses.replace(speed, shift=0.0).route_cost(rho)
        return 1.0 / np.maximum(np.asarray(speed(rho), float), ROUTE_SPEED_FLOOR_M_S)

    def speed(self, rho):
        """A density-only model's (``n_vars`` 1) walking speed [m/s] at the densities
        ``rho`` (k,) [ped/m^2]: its velocity is ``speed(rho) e`` along the route."""
        raise NotImplementedError

    def initial_state(self, rho: np.ndarray) -> np.ndarray:
        """Cell averages (m, nv) of a crowd at rest with density ``rho`` (m,)."""
        q = np.zeros((len(rho), self.n_vars))
        q[:, 0] = rho
        return q

    def parameters(self) -> dict:
        return {}

    def check_exit(self, kind: str) -> str:
        if kind is None:
            return self.exit_conditions[0]
        if kind not in self.exit_conditions:
            raise ParameterError(
                f"model '{self.name}' has no exit condition '{kind}' "
                f"(choose from: {', '.join(self.exit_conditions)})"
            )
        return kind
