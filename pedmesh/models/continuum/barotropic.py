"""Density + momentum models with a barotropic pressure and relaxation to the desired
velocity:

.. math::
    \\rho_t + \\nabla\\cdot(\\rho u) = 0, \\qquad
    (\\rho u)_t + \\nabla\\cdot(\\rho u \\otimes u + p(\\rho) I)
        = \\rho \\frac{U_e(\\rho) e - u}{\\tau} + \\text{(model sources)}

* ``pw`` (Payne-Whitham): p = c0^2 rho, sound speed c0 (c0 = 0 is pressureless Euler);
* ``mac2-local`` (issue 6) and ``eos`` (issue 8) use other pressure laws.

Numerics at the quadrature points: the velocity is desingularised near vacuum
(Kurganov-Petrova, ``u = sqrt(2) rho m / sqrt(rho^4 + max(rho^4, rho_vac^4))`` with
``rho_vac = 1e-3 rho_cut``, 1e-6 ped/m^2) and capped at ``u_max`` (1.5 U_f); cells below
``rho_cut`` are reconstructed to first order, so a thin film of crowd moves with its own
velocity and drains instead of creeping. The flux is Rusanov with wave speed
``|u.n| + c(rho)``; walls are mirror states (zero mass flux); exits open onto empty space
(``vacuum``: Rusanov against rho = 0, so mass only leaves) or are ``transmissive``
(zero-gradient, u.n clipped >= 0). With the semi-implicit step (the default for a model with
a pressure) the interior fluxes carry no pressure (:meth:`BarotropicModel.explicit_part`)
and :mod:`pedmesh.models.continuum.implicit` adds it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba as nb
import numpy as np

from ...errors import ParameterError
from .fv_kernels import BLOCK, FAST, NCHUNK, PAR, short_block
from .base import MacroModel
from ...speed import SpeedLaw, shape
from ... import parameters as P
from ...parameters import DEFAULTS as D

__all__ = ["BarotropicModel", "PressureLaw"]

SQRT2 = math.sqrt(2.0)
#: rho_vac / rho_cut (see BarotropicModel.rho_vac)
VAC_FRACTION = 1e-3
ISOTHERMAL, QUADRATIC, TABLE, SPEED_ONLY = 0, 1, 2, 3


@dataclass(frozen=True)
class PressureLaw:
    """p(rho) [m^2/s^2 ped/m^2 ... per unit mass]: ``isothermal`` c0^2 rho, ``quadratic``
    gamma rho^2 / 2, or ``table`` (monotone piecewise-cubic on a density grid)."""

    kind: int
    params: np.ndarray  # isothermal: [c0]; quadratic: [gamma]; table: [rho_0..rho_n, p..., dp...]

    @classmethod
    def isothermal(cls, c0: float) -> "PressureLaw":
        return cls(ISOTHERMAL, np.array([float(c0)]))

    @classmethod
    def quadratic(cls, gamma: float) -> "PressureLaw":
        return cls(QUADRATIC, np.array([float(gamma)]))

    @classmethod
    def table(cls, rho, p, dp) -> "PressureLaw":
        """Monotone cubic Hermite p(rho) through nodes (rho_k, p_k) with slopes dp_k; below
        the first node p = p_0 (rho/rho_0)^2, above the last a straight line."""
        rho, p, dp = (np.asarray(a, float) for a in (rho, p, dp))
        if len(rho) < 2 or np.any(np.diff(rho) <= 0) or np.any(np.diff(p) < 0) or np.any(dp < 0):
            raise ParameterError("an equation of state needs increasing densities and a "
                                 "non-decreasing pressure with non-negative slopes")
        return cls(TABLE, np.concatenate([[len(rho)], rho, p, dp]))

    @property
    def pressured(self) -> bool:
        return self.kind in (QUADRATIC, TABLE) or (self.kind == ISOTHERMAL and self.params[0] > 0)

    def h_table(self, rho_max: float = 60.0, n: int = 4000):
        """(rho, h) with h(rho) = int_0^rho c(s)/s ds on a grid (for the table law)."""
        if self.kind != TABLE:
            return np.zeros(2), np.zeros(2)
        r = np.concatenate([[0.0], np.geomspace(1e-6, rho_max, n)])
        c = self.sound_speed(r)
        f = np.where(r > 0, c / np.where(r > 0, r, 1.0), 0.0)
        # near 0, c ~ sqrt(rho): c/rho ~ rho^-1/2, integrable: integrate in sqrt(rho)
        s = np.sqrt(r)
        g = f * 2 * s  # d rho = 2 s ds
        h = np.concatenate([[0.0], np.cumsum(0.5 * (g[1:] + g[:-1]) * np.diff(s))])
        return np.ascontiguousarray(r), np.ascontiguousarray(h)

    @classmethod
    def speed_only(cls, gamma: float) -> "PressureLaw":
        """No pressure in the flux, but the Rusanov wave speed includes sqrt(gamma rho):
        for a repulsion that acts as an un-upwinded pressure in the sources (mac1)."""
        return cls(SPEED_ONLY, np.array([float(gamma)]))

    def pressure(self, rho):
        r = np.asarray(rho, float)
        out = np.empty_like(r)
        c = np.empty_like(r)
        _p_c_vec(self.kind, self.params, r.ravel(), out.ravel(), c.ravel())
        return out

    def sound_speed(self, rho):
        r = np.asarray(rho, float)
        out = np.empty_like(r)
        c = np.empty_like(r)
        _p_c_vec(self.kind, self.params, r.ravel(), out.ravel(), c.ravel())
        return c


@nb.njit(**FAST, inline="always")
def _p_c(kind, prm, rho):
    """Pressure (per unit mass, [m^2/s^2 ped/m^2]) and sound speed [m/s] at density rho."""
    if rho <= 0.0:
        return 0.0, (prm[0] if kind == ISOTHERMAL else 0.0)
    if kind == ISOTHERMAL:
        return prm[0] * prm[0] * rho, prm[0]
    if kind == QUADRATIC:
        return 0.5 * prm[0] * rho * rho, math.sqrt(prm[0] * rho)
    if kind == SPEED_ONLY:
        return 0.0, math.sqrt(prm[0] * rho)
    # TABLE: prm = [n, rho_0..rho_{n-1}, p_0..p_{n-1}, dp_0..dp_{n-1}] (Hermite cubic)
    n = int(prm[0])
    r0 = prm[1]
    rn = prm[n]
    if rho >= rn:  # linear extension with the last slope
        pn = prm[2 * n]
        dpn = prm[3 * n]
        return pn + dpn * (rho - rn), math.sqrt(max(dpn, 0.0))
    if rho <= r0:
        dp0 = prm[2 * n + 1]
        p0 = prm[n + 1]
        # below the first node: p = p0 (rho/r0)^2 keeps p(0) = 0 and p' >= 0
        return p0 * (rho / r0) ** 2, math.sqrt(max(2.0 * p0 * rho / (r0 * r0), 0.0))
    lo = 0
    hi = n - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if prm[1 + mid] <= rho:
            lo = mid
        else:
            hi = mid
    x0 = prm[1 + lo]
    x1 = prm[1 + hi]
    w = x1 - x0
    t = (rho - x0) / w
    y0 = prm[1 + n + lo]
    y1 = prm[1 + n + hi]
    d0 = prm[1 + 2 * n + lo] * w
    d1 = prm[1 + 2 * n + hi] * w
    t2 = t * t
    t3 = t2 * t
    p = ((2 * t3 - 3 * t2 + 1) * y0 + (t3 - 2 * t2 + t) * d0
         + (-2 * t3 + 3 * t2) * y1 + (t3 - t2) * d1)
    dp = ((6 * t2 - 6 * t) * y0 + (3 * t2 - 4 * t + 1) * d0 + (-6 * t2 + 6 * t) * y1
          + (3 * t2 - 2 * t) * d1) / w
    return p, math.sqrt(max(dp, 0.0))


@nb.njit(**PAR)
def _p_c_vec(kind, prm, rho, p, c):
    for i in nb.prange(rho.shape[0]):
        p[i], c[i] = _p_c(kind, prm, rho[i])


@nb.njit(**FAST, inline="always")
def _prim(r, mx, my, rho_vac, umax):
    """Velocity of a state: m / rho, desingularised (Kurganov-Petrova) below ``rho_vac``, and
    capped at ``umax``."""
    if r <= 0.0:
        return 0.0, 0.0, 0.0
    if r >= rho_vac:  # the formula reduces to m / rho
        ir = 1.0 / r
        ux = mx * ir
        uy = my * ir
    else:
        r4 = r * r * r * r
        c4 = rho_vac * rho_vac * rho_vac * rho_vac
        f = SQRT2 * r / math.sqrt(r4 + c4)
        ux = f * mx
        uy = f * my
    s2 = ux * ux + uy * uy
    if s2 > umax * umax:  # nobody walks faster than umax
        f = umax / math.sqrt(s2)
        ux *= f
        uy *= f
    return r, ux, uy


@nb.njit(**FAST, inline="always")
def _rusanov_point(qL, qR, nx, ny, kind, prm, rho_cut, umax):
    """Rusanov flux (3 components) and wave speed between the states (3,) ``qL``, ``qR``
    across the unit normal (nx, ny)."""
    rl, ulx, uly = _prim(qL[0], qL[1], qL[2], rho_cut, umax)
    rr, urx, ury = _prim(qR[0], qR[1], qR[2], rho_cut, umax)
    pl, cl = _p_c(kind, prm, rl)
    pr, cr = _p_c(kind, prm, rr)
    unl = ulx * nx + uly * ny
    unr = urx * nx + ury * ny
    a = max(abs(unl) + cl, abs(unr) + cr)
    f0 = 0.5 * (rl * unl + rr * unr) - 0.5 * a * (rr - rl)
    f1 = (0.5 * (rl * ulx * unl + pl * nx + rr * urx * unr + pr * nx)
          - 0.5 * a * (rr * urx - rl * ulx))
    f2 = (0.5 * (rl * uly * unl + pl * ny + rr * ury * unr + pr * ny)
          - 0.5 * a * (rr * ury - rl * uly))
    return f0, f1, f2, a


@nb.njit(**PAR)
def rusanov(qL, qR, nx, ny, kind, prm, rho_cut, umax, F, alpha):
    """Rusanov flux of the barotropic system at k points (states (k, 3))."""
    for k in nb.prange(qL.shape[0]):
        F[k, 0], F[k, 1], F[k, 2], alpha[k] = _rusanov_point(qL[k], qR[k], nx[k], ny[k], kind,
                                                             prm, rho_cut, umax)


@nb.njit(**PAR)
def rusanov_edges(qL, qR, nx, ny, kind, prm, rho_cut, umax, edges, lengths, F, live):
    """Rusanov fluxes at the 2 Gauss points of each of the ``live`` ``edges`` (states
    (k, 2, 3), unit normals (k,)), integrated over the edge into ``F[e]`` (the 2-point Gauss
    rule); 0 on the others."""
    n_a = edges.shape[0]
    for c_ in nb.prange(NCHUNK):  # blocks dealt out in turn (load balance)
        for b_ in range(c_, ((n_a) + BLOCK - 1) // BLOCK, NCHUNK):
            for a in range(b_ * BLOCK, min(n_a, (b_ + 1) * BLOCK)):
                e = edges[a]
                if not live[e]:
                    F[e, 0] = F[e, 1] = F[e, 2] = 0.0
                    continue
                f0, f1, f2, _ = _rusanov_point(qL[a, 0], qR[a, 0], nx[a], ny[a], kind, prm,
                                               rho_cut, umax)
                g0, g1, g2, _ = _rusanov_point(qL[a, 1], qR[a, 1], nx[a], ny[a], kind, prm,
                                               rho_cut, umax)
                w = 0.5 * lengths[e]
                F[e, 0] = w * (f0 + g0)
                F[e, 1] = w * (f1 + g1)
                F[e, 2] = w * (f2 + g2)


@nb.njit(**PAR)
def rusanov_cells(Q, e2t, edges, nx, ny, kind, prm, rho_cut, umax, lengths, F, alpha, live):
    """First-order Rusanov fluxes between the two cells of each of ``edges`` (interior),
    integrated over the edge (``F[e] = l_e f``), and the wave speeds ``alpha[e]``: the cell
    states are read in place instead of being gathered first. 0 on edges not ``live``."""
    n_k = edges.shape[0]
    for c_ in nb.prange(NCHUNK):  # blocks dealt out in turn (load balance)
        for b_ in range(c_, ((n_k) + BLOCK - 1) // BLOCK, NCHUNK):
            for k in range(b_ * BLOCK, min(n_k, (b_ + 1) * BLOCK)):
                e = edges[k]
                if not live[e]:
                    F[e, 0] = F[e, 1] = F[e, 2] = alpha[e] = 0.0
                    continue
                f0, f1, f2, a = _rusanov_point(Q[e2t[e, 0]], Q[e2t[e, 1]], nx[k], ny[k], kind, prm,
                                               rho_cut, umax)
                w = lengths[e]
                F[e, 0] = w * f0
                F[e, 1] = w * f1
                F[e, 2] = w * f2
                alpha[e] = a


@nb.njit(**FAST, inline="always")
def _mirror_point(q, nx, ny):
    """The mirror state of ``q`` (3,) at a wall with unit normal (nx, ny): the same density,
    the normal velocity reversed."""
    mn = q[1] * nx + q[2] * ny
    return q[0], q[1] - 2.0 * mn * nx, q[2] - 2.0 * mn * ny


@nb.njit(**PAR)
def mirror(q, nx, ny, out):
    """Mirror states: same density, normal velocity reversed."""
    for k in nb.prange(q.shape[0]):
        out[k, 0], out[k, 1], out[k, 2] = _mirror_point(q[k], nx[k], ny[k])


@nb.njit(**PAR)
def transmissive(q, nx, ny, kind, prm, rho_cut, umax, F):
    """Physical flux of the interior state with u.n clipped to >= 0 (no re-entry)."""
    for k in nb.prange(q.shape[0]):
        r, ux, uy = _prim(q[k, 0], q[k, 1], q[k, 2], rho_cut, umax)
        un = ux * nx[k] + uy * ny[k]
        if un < 0.0:
            ux -= un * nx[k]
            uy -= un * ny[k]
            un = 0.0
        p, c = _p_c(kind, prm, r)
        F[k, 0] = r * un
        F[k, 1] = r * ux * un + p * nx[k]
        F[k, 2] = r * uy * un + p * ny[k]


@nb.njit(**FAST, inline="always")
def _h(kind, prm, rho, h_rho, h_val):
    """Riemann-invariant integral h(rho) = int_0^rho c(s)/s ds (isothermal: c0 ln rho, up to
    a constant, which cancels)."""
    if kind == ISOTHERMAL:
        return prm[0] * math.log(rho)
    if kind == QUADRATIC:
        return 2.0 * math.sqrt(prm[0] * rho)
    # table: interpolate the tabulated integral
    n = h_rho.shape[0]
    if rho >= h_rho[n - 1]:
        _, c = _p_c(kind, prm, rho)
        return h_val[n - 1] + c * math.log(rho / h_rho[n - 1])
    lo = 0
    hi = n - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if h_rho[mid] <= rho:
            lo = mid
        else:
            hi = mid
    w = (rho - h_rho[lo]) / (h_rho[hi] - h_rho[lo])
    return h_val[lo] * (1 - w) + h_val[hi] * w


@nb.njit(**FAST)
def _godunov_point(q, n0, n1, kind, prm, rho_cut, umax, h_rho, h_val):
    """The exact Godunov flux (3 components) between the state (3,) ``q`` and vacuum
    across the unit normal (n0, n1) (see :func:`vacuum_godunov`). A function of its own,
    not inlined: it holds six copies of the pressure law, and inlined into
    :func:`boundary_edges` beside the Rusanov flux's they made its first compilation 72 s
    (now 26 s, and 11 s for this function, once for both callers: benchmarks/compile_time.py;
    the same numbers: the exits' fluxes are stored as they come)."""
    r, ux, uy = _prim(q[0], q[1], q[2], rho_cut, umax)
    if r <= 0.0:
        return 0.0, 0.0, 0.0
    un = ux * n0 + uy * n1
    tx = ux - un * n0
    ty = uy - un * n1
    p, c = _p_c(kind, prm, r)
    if c == 0.0 or un - c >= 0.0:  # pressureless, or supersonic outflow
        if un <= 0.0:
            return 0.0, 0.0, 0.0
        rs, us, ps = r, un, p
    else:
        if kind == ISOTHERMAL:
            if un >= prm[0]:
                rs, us = r, un
            else:
                rs = r * math.exp(un / prm[0] - 1.0)
                us = prm[0]
        elif kind == QUADRATIC:
            cs = (un + 2.0 * c) / 3.0
            if cs <= 0.0:
                return 0.0, 0.0, 0.0
            rs = cs * cs / prm[0]
            us = cs
        else:
            target = un + _h(kind, prm, r, h_rho, h_val)
            lo = 0.0
            hi = r
            if target <= 0.0:
                return 0.0, 0.0, 0.0
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                _, cm = _p_c(kind, prm, mid)
                g = (_h(kind, prm, mid, h_rho, h_val) if mid > 0 else 0.0) + cm - target
                if g > 0.0:
                    hi = mid
                else:
                    lo = mid
            rs = 0.5 * (lo + hi)
            _, us = _p_c(kind, prm, rs)
        ps, _ = _p_c(kind, prm, rs)
    m = rs * us
    return m, m * (us * n0 + tx) + ps * n0, m * (us * n1 + ty) + ps * n1


@nb.njit(**PAR)
def vacuum_godunov(q, nx, ny, kind, prm, rho_cut, umax, h_rho, h_val, F):
    """Exact Godunov flux of the Riemann problem between each state and vacuum (empty space
    beyond an exit), for a barotropic pressure: the left-moving rarefaction ends in vacuum,
    and the flux is that of the state at x/t = 0 -- the left state if it is supersonic
    outwards, vacuum if the whole fan moves inwards, else the sonic state where u = c(rho),
    found through the Riemann invariant u + h(rho) = u_L + h(rho_L)."""
    n_k = q.shape[0]
    bs = short_block(n_k)
    for c_ in nb.prange(NCHUNK):  # blocks dealt out in turn (load balance)
        for b_ in range(c_, (n_k + bs - 1) // bs, NCHUNK):
            for k in range(b_ * bs, min(n_k, (b_ + 1) * bs)):
                F[k, 0], F[k, 1], F[k, 2] = _godunov_point(q[k], nx[k], ny[k], kind, prm,
                                                           rho_cut, umax, h_rho, h_val)


@nb.njit(**PAR)
def boundary_edges(q, nx, ny, g, wall, kind, prm, xkind, xprm, rho_cut, umax, h_rho, h_val,
                   edges, lengths, F, alpha, want_alpha, exit_speed, live):
    """Wall (``wall``) or exit fluxes of ``edges`` in one pass, at each of the ``g`` points
    of each edge (states (k g, 3), unit normals (k g,)), integrated over the edge into
    ``F[e]`` (the Gauss rule for g = 2, ``l_e f`` for g = 1); with ``want_alpha`` the edge's
    largest wave speed into ``alpha[e]``; both 0 on edges that are not ``live``.

    Walls: the Rusanov flux of the law (``kind``, ``prm``) against the mirror state. Exits:
    the exact Godunov flux into vacuum of the exit law (``xkind``, ``xprm``). The wave speed
    is the Rusanov speed of the state under the law, at exits with ``exit_speed`` that of
    :func:`_exit_speed` (the exit law is not the flux law). The same arithmetic as
    :func:`mirror`, :func:`rusanov`, :func:`vacuum_godunov`, :func:`_exit_speed` and
    :func:`~pedmesh.models.continuum.fv_kernels.integrate_edges` (to round-off: the compiler
    may contract other products into fused multiply-adds). The edges in parallel (each
    writes only its own rows)."""
    k_e = edges.shape[0]
    bs = short_block(k_e)
    for c_ in nb.prange(NCHUNK):
        s = np.empty(3)
        f = np.empty((2, 3))
        for b_ in range(c_, (k_e + bs - 1) // bs, NCHUNK):
            for a_ in range(b_ * bs, min(k_e, (b_ + 1) * bs)):
                e = edges[a_]
                if not live[e]:
                    F[e, 0] = F[e, 1] = F[e, 2] = 0.0
                    if want_alpha:
                        alpha[e] = 0.0
                    continue
                am = 0.0
                for j in range(g):
                    k = a_ * g + j
                    if wall:
                        s[0], s[1], s[2] = _mirror_point(q[k], nx[k], ny[k])
                        f[j, 0], f[j, 1], f[j, 2], _ = _rusanov_point(
                            q[k], s, nx[k], ny[k], kind, prm, rho_cut, umax)
                    else:
                        f[j, 0], f[j, 1], f[j, 2] = _godunov_point(
                            q[k], nx[k], ny[k], xkind, xprm, rho_cut, umax, h_rho, h_val)
                    if want_alpha:
                        if exit_speed and not wall:
                            aj = _exit_speed_point(q[k], f[j, 0], nx[k], ny[k], rho_cut,
                                                   umax)
                        else:
                            _, _, _, aj = _rusanov_point(q[k], q[k], nx[k], ny[k], kind, prm,
                                                         rho_cut, umax)
                        am = aj if j == 0 else max(am, aj)
                _integrate(f, g, lengths[e], F, e)
                if want_alpha:
                    alpha[e] = am


@nb.njit(**FAST, inline="always")
def _integrate(f, g, length, F, e):
    """F[e] = l/2 (f_0 + f_1) (g = 2) or l f_0 (g = 1), as integrate_edges does."""
    for v in range(3):
        if g == 2:
            F[e, v] = 0.5 * length * (f[0, v] + f[1, v])
        else:
            F[e, v] = length * f[0, v]


@nb.njit(**FAST, inline="always")
def _relax_point(q, ex, ey, U_f, law, rho_cut, umax, f):
    """tau times the relaxation rho (U_e(f rho) e - u)/tau of the state (3,) ``q`` (speed
    law array ``law``, see :mod:`pedmesh.speed`), the law read at ``f`` times the density
    (1: the density itself, exactly; eos's exit kernel: the density the social force
    model's people see, :mod:`pedmesh.models.continuum.exit_kernel`)."""
    r, ux, uy = _prim(q[0], q[1], q[2], rho_cut, umax)
    ue = U_f * shape(law, r * f)
    return r * (ue * ex - ux), r * (ue * ey - uy)


#: no density factors (the relaxation kernels' ``seen``: the law at the density itself)
NO_SEEN = np.ones(0)


@nb.njit(**PAR)
def relaxation(q, ex, ey, U_f, law, tau, rho_cut, umax, seen, S):
    """rho (U_e(rho) e - u)/tau at k points (the law read at ``seen`` (k,) times their
    densities; ``seen`` empty: at the densities)."""
    some = seen.shape[0] > 0
    for k in nb.prange(q.shape[0]):
        s1, s2 = _relax_point(q[k], ex[k], ey[k], U_f, law, rho_cut, umax,
                              seen[k] if some else 1.0)
        S[k, 0] = 0.0
        S[k, 1] = s1 / tau
        S[k, 2] = s2 / tau


@nb.njit(**PAR)
def relaxation_mean(Vi, ex, ey, U_f, law, tau, rho_cut, umax, seen, dQ, cact):
    """dQ[i] += the mean of the relaxation at the 3 interior points of cell i (states
    ``Vi`` (m, 3, 3), directions ``ex``, ``ey`` (3 m,)), for the active cells ``cact``; the
    law read at ``seen`` (3 m,) times the points' densities (empty: at the densities)."""
    some = seen.shape[0] > 0
    c = 1.0 / (3.0 * tau)
    n_i = dQ.shape[0]
    for c_ in nb.prange(NCHUNK):  # blocks dealt out in turn (load balance)
        for b_ in range(c_, ((n_i) + BLOCK - 1) // BLOCK, NCHUNK):
            for i in range(b_ * BLOCK, min(n_i, (b_ + 1) * BLOCK)):
                if not cact[i]:
                    continue
                s1 = s2 = 0.0
                for p in range(3):
                    a1, a2 = _relax_point(Vi[i, p], ex[3 * i + p], ey[3 * i + p], U_f, law,
                                          rho_cut, umax, seen[3 * i + p] if some else 1.0)
                    s1 += a1
                    s2 += a2
                dQ[i, 1] += c * s1
                dQ[i, 2] += c * s2


@nb.njit(**PAR)
def _exit_speed(q, F, nx, ny, rho_cut, umax, out):
    """See :meth:`BarotropicModel.exit_wave_speed`."""
    for k in nb.prange(q.shape[0]):
        out[k] = _exit_speed_point(q[k], F[k, 0], nx[k], ny[k], rho_cut, umax)


@nb.njit(**FAST, inline="always")
def _exit_speed_point(q, f_rho, nx, ny, rho_cut, umax):
    """``max(|u.n|, 2 F_rho / rho - u.n)`` of the state ``q`` (3,) with exit mass flux
    ``f_rho`` (see :meth:`BarotropicModel.exit_wave_speed`)."""
    r, ux, uy = _prim(q[0], q[1], q[2], rho_cut, umax)
    un = ux * nx + uy * ny
    a = abs(un)
    if r > 0.0:
        a = max(a, 2.0 * f_rho / r - un)
    return a


@nb.njit(**PAR)
def velocities(q, rho_cut, umax, out):
    for k in nb.prange(q.shape[0]):
        r, ux, uy = _prim(q[k, 0], q[k, 1], q[k, 2], rho_cut, umax)
        out[k, 0] = ux
        out[k, 1] = uy


_NO_ALPHA = np.zeros(1)


class BarotropicModel(MacroModel):
    """Density, momentum, barotropic pressure and relaxation (see module docstring)."""

    n_vars = 3
    #: the default speed cap u_max in units of U_f (the mean-field pressure of mac1/mac2
    #: does fling crowd edges faster than 1.5 U_f: capping them there moves mac2-local's T90
    #: on Example 2 by 1.7 %)
    default_u_max = 2.5
    direction_dependent_flux = False
    exit_conditions = ("vacuum", "transmissive")
    #: (m, 3) the factor of the density the speed law is read at, at each cell's interior
    #: points (None: 1 everywhere; eos's exit kernel sets it)
    seen: np.ndarray | None = None

    def __init__(self, name: str, law: PressureLaw, *, U_f: float = D['U_f'],
                 beta: float = D['beta'], tau: float = D['tau'],
                 rho_cut: float = D['rho_cut'], u_max: float | None = None,
                 default_exit: str | None = None, speed_law: str = D['speed_law'],
                 rho_jam: float = D['rho_jam'], gamma_w: float = D['gamma_w'],
                 rho_shift: float = D['rho_shift'], speed_table: str = D['speed_table']) -> None:
        for k, v in (("U_f", U_f), ("beta", beta), ("tau", tau), ("rho_cut", rho_cut)):
            P.get(k).check(v, physical=False)  # (bounds; the run checked the ranges)
        #: the desired-speed law U_e(rho) (:mod:`pedmesh.speed`)
        self.speed = SpeedLaw(speed_law, float(U_f), float(beta), float(rho_jam), float(gamma_w),
                              float(rho_shift), table=speed_table)
        self._law = self.speed.array
        self.name = name
        self.law = law
        #: no pressure (momentum flux rho u (x) u only): the flux limiter then also keeps the
        #: velocity within the bounds of the neighbourhood (the first-order scheme does)
        self.pressureless = (law.kind == ISOTHERMAL and float(law.params[0]) == 0.0) or \
            law.kind == SPEED_ONLY
        self.U_f, self.beta = float(U_f), float(beta)
        self.tau, self.rho_cut = float(tau), float(rho_cut)
        #: [ped/m^2] below this the velocity m / rho is desingularised (a film of 1e-6
        #: ped/m^2 holds 0.005 people in a 5000 m^2 room); from rho_vac to rho_cut the film
        #: moves at its own velocity (first order there, see rho_cut), so it drains
        self.rho_vac = VAC_FRACTION * self.rho_cut
        #: largest speed [m/s] (default ``default_u_max`` U_f): the relaxation keeps a crowd
        #: below U_f, but a pressure flings the thin edge of a dense crowd into empty space
        #: at up to u + 2c, and a film at that speed sets the time step
        self.u_max = float(u_max) if u_max is not None else self.default_u_max * self.U_f
        # exits: Rusanov against empty space (vacuum), zero gradient (transmissive), and for
        # a model with a pressure the exact Godunov flux into empty space (godunov)
        ex = ["vacuum", "transmissive"] + (["godunov"] if law.pressured else [])
        if default_exit is not None:
            ex.remove(default_exit)
            ex.insert(0, default_exit)
        self.exit_conditions = tuple(ex)
        self._h_rho, self._h_val = law.h_table()
        #: the law of the exact Godunov exit flux (the full pressure law, also in the
        #: pressureless explicit part of a semi-implicit step: see :meth:`explicit_part`)
        self.exit_law = law

    @property
    def supports_implicit_pressure(self) -> bool:
        """Whether the pressure can be treated implicitly (a pressure law in the flux; not
        mac1's repulsion, which acts through nonlocal sources)."""
        return self.law.pressured and self.law.kind != SPEED_ONLY

    def explicit_part(self) -> "BarotropicModel":
        """The model without its pressure in the interior fluxes: the explicit part of the
        semi-implicit scheme (:mod:`pedmesh.models.continuum.implicit`). Transport, relaxation and
        sources stay; the pressure acts through the implicit correction, except at exits,
        whose exact Godunov flux keeps the full law (the pressure at the door decides its
        throughput). The wave speeds, hence the time step, are the material ones."""
        import copy

        part = copy.copy(self)
        part.law = PressureLaw.isothermal(0.0)
        part.exit_law = self.law
        return part

    def exit_wave_speed(self, q, F, nx, ny):
        """The wave speed (k,) [m/s] of exit points with states ``q`` (k, 3) and exit fluxes
        ``F`` (k, 3) for the time step, or None for the Rusanov speed of the state. The
        explicit part of a semi-implicit step (whose own law has no pressure, while its
        exit flux has) gives the exact positivity bound of the exit flux:
        ``max(|u.n|, 2 F_rho / rho - u.n)`` (with it the exit edge enters the first-order
        positivity bound ``dt <= 2|T| / sum l alpha`` exactly as a Rusanov edge would)."""
        if self.exit_law is self.law:
            return None
        a = np.empty(len(q))
        _exit_speed(q, F, nx, ny, self.rho_vac, self.u_max, a)
        return a

    def flux(self, qL, qR, nx, ny, ex, ey):
        F = np.empty_like(qL)
        a = np.empty(len(qL))
        rusanov(qL, qR, nx, ny, self.law.kind, self.law.params, self.rho_vac, self.u_max, F, a)
        return F, a

    def edge_flux(self, qL, qR, nx, ny, ex, ey, edges, lengths, F, live):
        """High-order fluxes of ``edges`` from the states (k, 2, 3) at their 2 Gauss points,
        integrated over the edges into ``F`` (n_edges, 3) (0 where not ``live``); unit
        normals (k,) per edge (the flux does not depend on the direction ``ex``, ``ey``)."""
        rusanov_edges(qL, qR, nx, ny, self.law.kind, self.law.params, self.rho_vac,
                      self.u_max, edges, lengths, F, live)

    def source_mean(self, Vi, ex, ey, dQ, cact):
        """Adds to ``dQ`` (m, 3) the mean of :meth:`source` at each active (``cact``) cell's
        3 interior points (states ``Vi`` (m, 3, 3), directions (3 m,))."""
        relaxation_mean(Vi, ex, ey, self.U_f, self._law, self.tau, self.rho_vac, self.u_max,
                        self._seen(len(Vi) * 3), dQ, cact)

    def cell_flux(self, Q, e2t, edges, nx, ny, ex, ey, lengths, F, alpha, live):
        """First-order fluxes of interior ``edges`` between their cells' averages ``Q``,
        integrated over the edges into ``F`` (n_edges, 3), wave speeds into ``alpha`` (one
        point per edge: the flux does not depend on the direction); 0 where not ``live``."""
        rusanov_cells(Q, e2t, edges, nx, ny, self.law.kind, self.law.params, self.rho_vac,
                      self.u_max, lengths, F, alpha, live)

    def wall_flux(self, q, nx, ny, ex, ey):
        g = np.empty_like(q)
        mirror(q, nx, ny, g)
        F, _ = self.flux(q, g, nx, ny, ex, ey)
        return F

    def exit_flux(self, q, nx, ny, ex, ey, kind):
        law = self.exit_law
        if kind == "vacuum":
            F = np.empty_like(q)
            rusanov(q, np.zeros_like(q), nx, ny, law.kind, law.params, self.rho_vac,
                    self.u_max, F, np.empty(len(q)))
            return F
        if kind == "transmissive":
            F = np.empty_like(q)
            transmissive(q, nx, ny, law.kind, law.params, self.rho_vac, self.u_max, F)
            return F
        if kind == "godunov":
            F = np.empty_like(q)
            vacuum_godunov(q, nx, ny, self.exit_law.kind, self.exit_law.params, self.rho_vac,
                           self.u_max, self._h_rho, self._h_val, F)
            return F
        raise ParameterError(f"unknown exit condition '{kind}'")

    def boundary_flux(self, name, q, nx, ny, g, edges, lengths, F, alpha, live, exit_kind):
        """The wall (``name`` 'wall') or Godunov exit ('exit') fluxes of ``edges`` in one
        pass, integrated over the edges into ``F`` (n_edges, 3), and, unless ``alpha`` is
        None, each edge's largest wave speed into ``alpha``: what :meth:`wall_flux`,
        :meth:`exit_flux`, :meth:`exit_wave_speed` and the solver's integration give (to
        round-off). States ``q`` (k g, 3) at ``g`` points per edge, unit normals (k g,). Returns
        False (nothing done) for the other exit conditions."""
        want = alpha is not None
        al = alpha if want else _NO_ALPHA
        if name != "wall" and not (name == "exit" and exit_kind == "godunov"):
            return False
        x = self.exit_law
        boundary_edges(q, nx, ny, g, name == "wall", self.law.kind, self.law.params, x.kind,
                       x.params, self.rho_vac, self.u_max, self._h_rho, self._h_val, edges,
                       lengths, F, al, want, x is not self.law, live)
        return True

    def source(self, q, ex, ey):
        S = np.empty_like(q)
        relaxation(q, ex, ey, self.U_f, self._law, self.tau, self.rho_vac, self.u_max,
                   self._seen(len(q)), S)
        return S

    def _seen(self, k: int) -> np.ndarray:
        """:attr:`seen` for ``k`` source points (they must be every cell's interior points),
        else :data:`NO_SEEN`."""
        if self.seen is None:
            return NO_SEEN
        if k != self.seen.size:
            raise ValueError(f"{self.name} with density factors: sources at the cells' "
                             "interior points only")
        return self.seen.ravel()

    def velocity(self, q):
        out = np.empty((len(q), 2))
        velocities(q, self.rho_vac, self.u_max, out)
        return out

    @property
    def speed_floor(self) -> float:
        """Pedestrians accelerate to U_f within a few tau: the CFL wave speed never assumes
        less (a crowd at rest has no other wave speed when the model has no pressure)."""
        return self.U_f

    def source_dt(self, Q) -> float:
        """Resolve the relaxation: dt <= tau / 2 (SSP-RK3 itself is stable to 2.5 tau)."""
        return 0.5 * self.tau

    def parameters(self) -> dict:
        return {**self.speed.parameters(), "tau": self.tau, "rho_cut": self.rho_cut,
                "u_max": self.u_max}
