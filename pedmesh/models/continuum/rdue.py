"""RDUE / Hughes: ``rho_t + div(rho U_e(rho) e) = 0`` with the desired speed ``U_e`` of the
speed law (:mod:`pedmesh.speed`; the paper's ``U_f exp(-beta rho)`` by default) and e from the
eikonal equation with cost 1/U_e(rho) (reactive dynamic user equilibrium).

Flux at a point with normal n: ``f(rho) (e.n)``, ``f(rho) = rho U_e(rho)``; Rusanov with
``alpha = max |f'(rho)| |e.n|`` (exponential law: ``f'(rho) = U_f (1 - beta rho) exp(-beta
rho)``). Walls pass nothing. Exits (default ``demand``): the Godunov flux into empty space,
``f(min(rho, rho*)) (e.n)_+`` with ``rho*`` the density of the largest flow (1/beta for the
exponential law), so a saturated exit of width w passes its capacity ``w f(rho*)``
(``w U_f / (e beta)``); ``vacuum`` (Rusanov against 0) and ``transmissive``
(``f(rho) (e.n)_+``) are the alternatives.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from ...errors import ParameterError
from .fv_kernels import BLOCK, FAST, NCHUNK, PAR
from ...speed import SpeedLaw, flux_and_slope
from .adapter import SPEED_PARAMETERS, register_continuum_model
from .base import MacroModel
from ... import parameters as P
from ...parameters import DEFAULTS as D

__all__ = ["RDUE"]


@nb.njit(**FAST, inline="always")
def _f_df(r, U_f, law):
    """rho = max(r, 0), f(rho) = rho U_e(rho) and |f'(rho)| (speed law array ``law``)."""
    r = max(r, 0.0)
    f, d = flux_and_slope(law, U_f, r)
    return r, f, d


@nb.njit(**FAST, inline="always")
def _rusanov_en(rl, fl, dl, rr, fr, dr, en):
    """Rusanov flux and wave speed across a normal with e.n = ``en``, from the densities,
    fluxes and |f'| of both sides (see :func:`_f_df`)."""
    a = max(dl, dr) * abs(en)
    return 0.5 * (fl + fr) * en - 0.5 * a * (rr - rl), a


@nb.njit(**PAR)
def _rusanov(qL, qR, en, U_f, law, F, alpha):
    for k in nb.prange(qL.shape[0]):
        rl, fl, dl = _f_df(qL[k, 0], U_f, law)
        rr, fr, dr = _f_df(qR[k, 0], U_f, law)
        F[k, 0], alpha[k] = _rusanov_en(rl, fl, dl, rr, fr, dr, en[k])


@nb.njit(**PAR)
def _rusanov_edges(qL, qR, nx, ny, ex, ey, edges, lengths, U_f, law, F, live):
    """Rusanov fluxes at the 2 Gauss points of each of ``edges`` (states (k, 2, 1), unit
    normals (k,), directions (2 k,)), integrated over the edge into ``F[e]`` (0 where not
    ``live``)."""
    n_a = edges.shape[0]
    for c_ in nb.prange(NCHUNK):  # blocks dealt out in turn (load balance)
        for b_ in range(c_, ((n_a) + BLOCK - 1) // BLOCK, NCHUNK):
            for a in range(b_ * BLOCK, min(n_a, (b_ + 1) * BLOCK)):
                e = edges[a]
                if not live[e]:
                    F[e, 0] = 0.0
                    continue
                s = 0.0
                for g in range(2):
                    rl, fl, dl = _f_df(qL[a, g, 0], U_f, law)
                    rr, fr, dr = _f_df(qR[a, g, 0], U_f, law)
                    en = ex[2 * a + g] * nx[a] + ey[2 * a + g] * ny[a]
                    f, _ = _rusanov_en(rl, fl, dl, rr, fr, dr, en)
                    s += f
                F[e, 0] = 0.5 * lengths[e] * s


@nb.njit(**PAR)
def _rusanov_cells(Q, e2t, edges, nx, ny, ex, ey, lengths, U_f, law, F, alpha, live):
    """First-order fluxes of interior ``edges`` from their two cells' averages (read in
    place; f and f' once per edge, the direction at both Gauss points), integrated over the
    edge into ``F[e]``, and the larger wave speed of the two points into ``alpha[e]`` (0
    where not ``live``)."""
    n_a = edges.shape[0]
    for c_ in nb.prange(NCHUNK):  # blocks dealt out in turn (load balance)
        for b_ in range(c_, ((n_a) + BLOCK - 1) // BLOCK, NCHUNK):
            for a in range(b_ * BLOCK, min(n_a, (b_ + 1) * BLOCK)):
                e = edges[a]
                if not live[e]:
                    F[e, 0] = alpha[e] = 0.0
                    continue
                rl, fl, dl = _f_df(Q[e2t[e, 0], 0], U_f, law)
                rr, fr, dr = _f_df(Q[e2t[e, 1], 0], U_f, law)
                f0, a0 = _rusanov_en(rl, fl, dl, rr, fr, dr, ex[2 * a] * nx[a] + ey[2 * a] * ny[a])
                f1, a1 = _rusanov_en(rl, fl, dl, rr, fr, dr,
                                     ex[2 * a + 1] * nx[a] + ey[2 * a + 1] * ny[a])
                F[e, 0] = 0.5 * lengths[e] * (f0 + f1)
                alpha[e] = max(a0, a1)


class RDUE(MacroModel):
    """RDUE / Hughes model (see module docstring)."""

    name = "rdue"
    n_vars = 1
    #: (the flux limiter keeps rho >= 0 up to cfl 1; 0.9 leaves T50 and T90 of Example 2 as
    #: at 0.7 to 0.01 s)
    default_cfl = 0.9
    exit_conditions = ("demand", "vacuum", "transmissive")

    def __init__(self, *, U_f: float = D['U_f'], beta: float = D['beta'],
                 speed_law: str = D['speed_law'], rho_jam: float = D['rho_jam'],
                 gamma_w: float = D['gamma_w'], rho_shift: float = D['rho_shift'],
                 speed_table: str = D['speed_table']) -> None:
        for k, v in (("U_f", U_f), ("beta", beta)):
            P.get(k).check(v, physical=False)  # (bounds; the run checked the ranges)
        self.U_f, self.beta = float(U_f), float(beta)
        #: the desired-speed law U_e(rho) (:mod:`pedmesh.speed`)
        self.speed = SpeedLaw(speed_law, self.U_f, self.beta, float(rho_jam), float(gamma_w),
                              float(rho_shift), table=speed_table)
        self._law = self.speed.array
        #: [ped/m^2] the density of the largest flow (the exits' demand)
        self.rho_star = self.speed.capacity_density

    def f(self, rho):
        """f(rho) = rho U_e(rho) [ped/(m s)]."""
        if self.speed.name == "exponential" and not self.speed.shift:
            return rho * self.U_f * np.exp(-self.beta * rho)
        return self.speed.flow(rho)

    def flux(self, qL, qR, nx, ny, ex, ey):
        F = np.empty_like(qL)
        a = np.empty(len(qL))
        _rusanov(qL, qR, ex * nx + ey * ny, self.U_f, self._law, F, a)
        return F, a

    def edge_flux(self, qL, qR, nx, ny, ex, ey, edges, lengths, F, live):
        """:meth:`flux` at the 2 Gauss points of ``edges``, integrated into ``F`` in one pass
        (see :class:`~pedmesh.models.continuum.base.MacroModel`)."""
        _rusanov_edges(qL, qR, nx, ny, ex, ey, edges, lengths, self.U_f, self._law, F, live)

    def cell_flux(self, Q, e2t, edges, nx, ny, ex, ey, lengths, F, alpha, live):
        """First-order fluxes of interior ``edges`` from the cell averages ``Q`` in one pass
        (see :class:`~pedmesh.models.continuum.base.MacroModel`)."""
        _rusanov_cells(Q, e2t, edges, nx, ny, ex, ey, lengths, self.U_f, self._law, F, alpha,
                       live)

    def wall_flux(self, q, nx, ny, ex, ey):
        return np.zeros_like(q)

    def exit_flux(self, q, nx, ny, ex, ey, kind):
        en = ex * nx + ey * ny
        r = np.maximum(q[:, 0], 0.0)
        if kind == "demand":
            return (self.f(np.minimum(r, self.rho_star)) * np.maximum(en, 0.0))[:, None]
        if kind == "transmissive":
            return (self.f(r) * np.maximum(en, 0.0))[:, None]
        if kind == "vacuum":
            F, _ = self.flux(q, np.zeros_like(q), nx, ny, ex, ey)
            return F
        raise ParameterError(f"unknown exit condition '{kind}'")

    def velocity(self, q):
        return np.zeros((len(q), 2))  # filled by the solver from U_e e

    def parameters(self) -> dict:
        return self.speed.parameters()


register_continuum_model("rdue", RDUE, SPEED_PARAMETERS, aliases=("hughes",), surface=True,
                         description="the reactive dynamic user equilibrium (Hughes-type): "
                                     "density only, walking at U_e(rho) along the route")
