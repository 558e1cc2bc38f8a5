"""The paper's continuum models derived from the social force model.

``mac1`` (direct mean-field model, paper eq. mac1)::

    rho_t + div(rho u) = 0
    (rho u)_t + div(rho u (x) u) = rho (U_e e - u)/tau
        + rho int Phi(|x-y|) (x-y)/|x-y| rho(y) dy                       (repulsion)
        + rho int Psi(|x-y|)/|x-y|^2 <u(y)-u(x), (x-y)^perp> (x-y)^perp rho(y) dy   (friction)

with the SFM kernels Phi, Psi (:mod:`pedmesh.models.continuum.physics`), sparse operators
built once per mesh (:mod:`pedmesh.models.continuum.nonlocal_ops`), walls acting through
mirror images, and the stiff
friction applied by Strang splitting in sub-steps (see :class:`Mac1`). The repulsion is split
(``imex=1``, the default) into its local part, the pressure ``p = gamma1 rho^2 / 2`` of its
expansion ``-gamma1 rho grad rho``, which the semi-implicit step treats implicitly
(:mod:`pedmesh.models.continuum.implicit`), and the rest, the nonlocal repulsion minus the
force with
which that step applies p, as an explicit source: the time step is then set by the crowd's
speed, not by the sound ``sqrt(gamma1 rho)`` (7 m/s at 5 ped/m^2), and as dt -> 0 the source
is the whole nonlocal repulsion again. ``imex=0`` keeps the whole repulsion in the sources
with the Rusanov wave speed ``|u.n| + sqrt(gamma1 rho)`` (the repulsion acting as an
un-upwinded pressure): the explicit scheme, for verification.

``mac2`` family (hydrodynamic scaling, paper eq. mac2) with S1 in {local f22, nonlocal f21}
and S2 in {nonlocal friction f31, none f32}:

* ``mac2-local``: S1 local: the repulsive pressure ``p = gamma1 rho^2 / 2`` in the flux.
  The paper prints F2 = +gamma1 grad rho; the expansion of the repulsive integral gives
  -gamma1 grad rho (its substitution drops a sign), i.e. a pressure, which is implemented;
* ``mac2-local-friction``: plus the nonlocal friction f31 with the long-range kernel;
* ``mac2-nonlocal``: S1 = f21 with the paper's long-range kernel 1/(1 + r^2) (scaled by
  ``lr_strength``, default 0.01 = the paper's epsilon), by FFT convolution;
* ``mac2-nonlocal-friction``: f21 and f31, both long-range.
"""

from __future__ import annotations

import functools

import numpy as np

from ...errors import ParameterError
from .physics import LongRange, SFMFriction, SFMRepulsion, gamma1, gamma2
from .barotropic import BarotropicModel, PressureLaw
from .adapter import BASE_PARAMETERS, SFM_PARAMETERS, register_continuum_model
from ... import parameters as P
from ...parameters import DEFAULTS as D

__all__ = ["Mac1", "Mac2"]

_SFM_KEYS = ("A", "B", "k", "kappa", "m", "r")


def _sfm_kernels(A=D['A'], B=D['B'], k=D['k'], kappa=D['kappa'], m=D['m'], r=D['r']):
    for name, v in (("A", A), ("B", B), ("k", k), ("kappa", kappa), ("m", m), ("r", r)):
        P.get(name).check(v, physical=False)  # (bounds; the run checked the ranges)
    return SFMRepulsion(A=A, B=B, k=k, m=m, r_ij=2 * r), SFMFriction(kappa=kappa, m=m, r_ij=2 * r)


class Mac1(BarotropicModel):
    """The direct nonlocal continuum model (see module docstring).

    The friction is stiff: it relaxes velocity differences between neighbouring cells at a
    rate up to ``sum_j tr(K_ij) rho_j``, beyond the CFL step's reach: on Example 2 at
    2 / 4 ped/m^2 the largest rate is 64 / 128 1/s with cells of h = 1.1 m and 116 / 232 1/s
    with h = 0.56 m (the contact kernel is shorter than a cell, so the rate grows as 1/h).
    By default (``split_friction=1``) the solver applies it by Strang splitting: half a step
    of friction alone before each SSP-RK3 step of the rest and half a step after, each made
    of SSP-RK3 sub-steps with ``dt_sub * rate <= 1``. Every sub-step conserves
    momentum to round-off (the operator does) and, being within the stability interval of
    a dissipative symmetric operator, never increases the kinetic energy; the density is
    untouched. The CFL number is then the core's 0.7.

    The repulsion is split (``imex=1``, the default; module docstring): on Example 2 the
    semi-implicit run (cfl 0.8, :attr:`imex_cfl`) gives T50/T90 88.57/127.03 s in 2,602
    steps against the explicit scheme's (``imex=0``) 88.34/126.61 s in 5,324 (+0.3 %,
    +0.3 %).

    ``split_friction=0`` keeps the friction inside the stages with ``dt <= 2 / rate`` and
    cfl 0.4: larger steps resolve it poorly and the run changes. Evidence on Example 2
    (mesh h = 1.1 m), T50/T90/T100: in the stages, cfl 0.2 gives 88.03/125.53/164.08 s and
    cfl 0.4 88.04/125.56/163.84 s, while cfl 0.7 moves T90 by 1.5 s (also without the
    stability bound); split at cfl 0.2 gives 88.02/125.53/164.11 s and at cfl 0.7
    87.97/125.44/163.89 s in 2661 steps (4663 at cfl 0.4 in the stages).
    """

    #: CFL number of the semi-implicit step (imex=1): its explicit source (the nonlocal
    #: repulsion minus its local part) speeds the crowd up within a step, so at the usual 0.9
    #: many steps outrun their bound and are taken again. Whole runs, 2 interleaved repeats:
    #: Example 1 at cfl 0.7 / 0.8 / 0.9: 17.3-18.2 / 16.4-16.9 / 20.2-20.5 s (0.9: 1,791
    #: steps and 1,422 retries; 0.8: 1,811 and 454); Example 3 at 0.8 / 0.9: 20.5-22.4 /
    #: 27.2-27.9 s; Example 2 at 0.7 / 0.8 / 0.9: 21.4-21.6 / 19.5-21.2 / 18.3-18.8 s.
    #: T50/T90 move by less than 0.1 % between them
    imex_cfl = 0.8
    #: max ``dt_sub * rate`` of a friction sub-step (the rate bounds the largest eigenvalue
    #: of the friction operator to within a factor 2; SSP-RK3 is stable to 2.5)
    friction_substep = 1.0

    def __init__(self, *, U_f=D['U_f'], beta=D['beta'], tau=D['tau'], rho_cut=D['rho_cut'],
                 u_max=None, speed_law=D['speed_law'], rho_jam=D['rho_jam'],
                 gamma_w=D['gamma_w'], rho_shift=D['rho_shift'],
                 speed_table=D['speed_table'], walls: float = D['walls'],
                 friction: float = D['friction'], cutoff: float = D['cutoff'],
                 split_friction: float = D['split_friction'], imex: float = D['imex'],
                 **sfm) -> None:
        unknown = set(sfm) - set(_SFM_KEYS)
        if unknown:
            raise ParameterError(f"unknown parameter '{sorted(unknown)[0]}'")
        self.phi, self.psi = _sfm_kernels(**sfm)
        self.sfm = {k: float(v) for k, v in sfm.items()}
        self.gamma1 = gamma1(self.phi)
        self.gamma2 = gamma2(self.psi)
        #: the repulsion split into its local part, the pressure gamma1 rho^2 / 2 (in the
        #: flux, implicit in the semi-implicit step), and the rest (explicit source)
        self.imex = bool(imex)
        law = (PressureLaw.quadratic(self.gamma1) if self.imex
               else PressureLaw.speed_only(self.gamma1))
        super().__init__("mac1", law, U_f=U_f, beta=beta,
                         tau=tau, rho_cut=rho_cut, u_max=u_max, speed_law=speed_law,
                         rho_jam=rho_jam, gamma_w=gamma_w, rho_shift=rho_shift,
                         speed_table=speed_table)
        self.walls = bool(walls)
        self.use_friction = bool(friction)
        self.split_friction = bool(split_friction)
        self.has_split_source = self.use_friction and self.split_friction
        if not (np.isfinite(cutoff) and cutoff > 2 * self.phi.r_ij / 2):
            raise ParameterError(f"parameter 'cutoff' must exceed the body diameter, "
                                 f"got {cutoff!r}")
        self.cutoff = float(cutoff)
        self.ops = None

    def bind(self, mesh) -> None:
        from .nonlocal_ops import build_pair_operators

        cache = mesh._cache
        key = ("mac1-ops", self.phi, self.psi if self.use_friction else None, self.cutoff,
               self.walls)
        if key not in cache:
            cache[key] = build_pair_operators(mesh, self.phi,
                                              self.psi if self.use_friction else None,
                                              cutoff=self.cutoff, walls=self.walls)
        self.ops = cache[key]
        if self.imex:  # the force of the local part, as the implicit correction applies it
            from .implicit import ImplicitPressure

            self._pressure = ImplicitPressure(mesh, self)
        if self.use_friction:
            K = self.ops
            self._k_trace = (K.Kxx + K.Kyy).tocsr()

    @property
    def default_cfl(self) -> float:
        """The explicit scheme's (imex=0): 0.7 with the friction split off, 0.4 with it inside
        the stages (class docstring). (The semi-implicit step uses :attr:`imex_cfl`.)"""
        return 0.7 if self.has_split_source or not self.use_friction else 0.4

    def _friction_rate(self, rho: np.ndarray) -> float:
        """Largest relaxation rate [1/s] of the friction, max_i sum_j tr(K_ij) rho_j."""
        rate = self._k_trace @ rho
        return float(rate.max()) if len(rate) else 0.0

    def cell_source(self, Q):
        rho = np.maximum(Q[:, 0], 0.0)
        out = np.zeros_like(Q)
        out[:, 1:3] = self.ops.repulsion(rho, walls=self.walls, active=self.active)
        if self.imex:  # minus the local part, which the pressure in the flux applies
            self._pressure.subtract_pressure_force(rho, out, self.active)
        if self.use_friction and not self.has_split_source:
            out[:, 1:3] += self.ops.friction(rho, Q[:, 1:3], active=self.active)
        return out

    def split_source(self, Q: np.ndarray, dt: float) -> np.ndarray:
        """The friction alone for ``dt`` [s] with the density fixed: SSP-RK3 sub-steps of
        ``dt_sub <= friction_substep / rate``."""
        rho = np.ascontiguousarray(np.maximum(Q[:, 0], 0.0))
        n = max(1, int(np.ceil(dt * self._friction_rate(rho) / self.friction_substep)))
        out = Q.copy()
        # the sub-steps in one compiled pass each (the same bits as the numpy expressions
        # M1 = M + h f(M), M2 = 3/4 M + 1/4 (M1 + h f(M1)), M = M/3 + 2/3 (M2 + h f(M2)))
        out[:, 1:3] = self.ops.friction_steps(rho, Q[:, 1:3], dt / n, n, active=self.active)
        return out

    def source_dt(self, Q) -> float:
        """With the friction in the stages it relaxes velocity differences at rate ~ sum_j
        tr(K_ij) rho_j: keep dt below 2 / rate (SSP-RK3 is stable to 2.5)."""
        dt = super().source_dt(Q)
        if not self.use_friction or self.has_split_source:
            return dt
        mx = self._friction_rate(np.maximum(Q[:, 0], 0.0))
        return min(dt, 2.0 / mx) if mx > 0 else dt

    def parameters(self) -> dict:
        return {**super().parameters(), **self.sfm, "gamma1": self.gamma1, "gamma2": self.gamma2,
                "walls": self.walls, "friction": self.use_friction, "cutoff": self.cutoff,
                "split_friction": self.split_friction, "imex": self.imex}


class Mac2(BarotropicModel):
    """The hydrodynamic-scaling models (see module docstring)."""

    def __init__(self, name: str, *, local: bool, friction: bool, U_f=D['U_f'],
                 beta=D['beta'], tau=D['tau'], rho_cut=D['rho_cut'], u_max=None,
                 speed_law=D['speed_law'], rho_jam=D['rho_jam'], gamma_w=D['gamma_w'],
                 rho_shift=D['rho_shift'], speed_table=D['speed_table'],
                 lr_strength: float = D['lr_strength'], lr_length: float = D['lr_length'],
                 gamma1: float | None = None, **sfm) -> None:
        unknown = set(sfm) - set(_SFM_KEYS)
        if unknown:
            raise ParameterError(f"unknown parameter '{sorted(unknown)[0]}'")
        phi, _ = _sfm_kernels(**sfm)
        self.local = local
        self.use_friction = friction
        self.sfm = {k: float(v) for k, v in sfm.items()}
        if gamma1 is None:
            from .physics import gamma1 as _g1

            gamma1 = _g1(phi)
        for k_, v in (("gamma1", gamma1), ("lr_strength", lr_strength),
                      ("lr_length", lr_length)):
            P.get(k_).check(v, physical=False)
        self.gamma1 = float(gamma1)
        self.lr = LongRange(strength=float(lr_strength), length=float(lr_length))
        law = PressureLaw.quadratic(self.gamma1) if local else PressureLaw.isothermal(0.0)
        super().__init__(name, law, U_f=U_f, beta=beta, tau=tau, rho_cut=rho_cut, u_max=u_max,
                         speed_law=speed_law, rho_jam=rho_jam, gamma_w=gamma_w,
                         rho_shift=rho_shift, speed_table=speed_table)
        self.op = None

    def bind(self, mesh) -> None:
        if self.local and not self.use_friction:
            return
        from .nonlocal_ops import LongRangeOperator

        key = ("lr-op", self.lr)
        if key not in mesh._cache:
            mesh._cache[key] = LongRangeOperator(mesh, self.lr)
        self.op = mesh._cache[key]

    def cell_source(self, Q):
        if self.op is None:
            return None
        rho = np.maximum(Q[:, 0], 0.0)
        out = np.zeros_like(Q)
        if not self.local:
            out[:, 1:3] += self.op.repulsion(rho)
        if self.use_friction:
            out[:, 1:3] += self.op.friction(rho, Q[:, 1:3])
        return out

    def parameters(self) -> dict:
        return {**super().parameters(), **self.sfm, "gamma1": self.gamma1,
                "lr_strength": self.lr.strength, "lr_length": self.lr.length}


register_continuum_model(
    "mac1", lambda **kw: Mac1(**kw),
    BASE_PARAMETERS + SFM_PARAMETERS + ("walls", "friction", "cutoff", "split_friction", "imex"),
    description="the direct nonlocal model derived from the social force model")
for _name, _local, _friction in (("mac2-local", True, False), ("mac2-local-friction", True, True),
                                 ("mac2-nonlocal", False, False),
                                 ("mac2-nonlocal-friction", False, True)):
    register_continuum_model(
        _name, functools.partial(Mac2, _name, local=_local, friction=_friction),
        BASE_PARAMETERS + SFM_PARAMETERS + ("lr_strength", "lr_length", "gamma1"),
        description="hydrodynamic scaling of the social force model: "
                    + ("local pressure" if _local else "nonlocal repulsion")
                    + (" with friction" if _friction else ""))
