"""The implicit pressure correction of the semi-implicit (IMEX) finite-volume step.

A barotropic model ``rho_t + div q = 0``, ``q_t + div(q (x) q / rho) + grad p(rho) = S`` has
two speeds: the crowd's own (``|u|``, about 1 m/s) and the sound speed ``sqrt(p'(rho))`` of its
pressure (3-4 m/s in the queue at a door for ``eos``, 7 m/s for the mean-field pressure).
An explicit scheme must resolve the faster one. The semi-implicit step resolves only the
crowd: every forward-Euler stage of the SSP Runge-Kutta step becomes

1. an explicit stage of the model *without* its pressure in the interior fluxes (transport,
   relaxation, sources; CWENO3 and the flux limiter as before; exits keep their exact
   Godunov flux with the pressure) giving ``(rho*, q*)``, stable and positive under the CFL
   condition of the material speed ``|u|``;
2. this correction, implicit in the density (in the manner of Degond, Hua & Navoret, J.
   Comput. Phys. 230, 2011, and the all-speed schemes of Haack, Jin & Liu, 2012): the mass
   flux is the one of the *new* momentum ``q* - dt grad p(rho_new)``::

       |T_i| rho_i = |T_i| rho*_i - sum_f (G_f + a_f (rho_i - rho_j))

   with ``a_f = dt^2 l_f / d_f * (p(rho*_i) - p(rho*_j)) / (rho*_i - rho*_j)`` (two-point
   flux across the face, ``d_f`` the normal distance of the centroids, the secant slope of
   p) and ``G_f = dt^2 l_f <(q* - q)/dt>_f . n_f`` the mass the explicit stage's change of
   momentum moves (so that in a steady queue, where that change balances the pressure, the
   two cancel: Rhie-Chow). The matrix ``diag|T| + sum a_f`` is a symmetric M-matrix, so the
   new density is non-negative whenever the right-hand side is; it is solved by conjugate
   gradients (scipy) on the cells the pressure couples strongly (``a_f / |T| > 1e-2``; the
   other faces take the same flux explicitly). The face fluxes of the solution
   are applied conservatively (mass to round-off whatever the solver tolerance), limited
   where a cell would lose more than it has (rarely, and never in exact arithmetic when the
   right-hand side is non-negative);
3. the momentum takes the pressure force of the new density, ``-rho grad h(rho)`` with the
   enthalpy ``h = int p'(s)/s ds`` (finite at vacuum, so a thin film next to a crowd is not
   flung away; the isothermal law uses ``-grad p``), face by face as a two-point gradient,
   plus the momentum the corrected mass flux carries (upwind velocity), and at exits the
   pressure of the cell (the exit flux supplies the door's own pressure).

Walls pass nothing. The explicit scheme stays available (``implicit_pressure=0``), and the
semi-implicit one converges to it as dt -> 0 (``tests/continuum/test_implicit.py``).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from .fv_kernels import BLOCK, FAST, NCHUNK, PAR, cell_edges, sum_in_order
from .barotropic import ISOTHERMAL, _p_c, _prim

__all__ = ["ImplicitPressure"]

#: faces whose coupling ``a_f / |T|`` is below this take their pressure flux explicitly (from
#: the explicit stage's densities: stable and positive far below its bound of 1/3, and
#: within ``(a_f/|T|)^2`` of the implicit flux), the others implicitly; so only the dense part
#: of the crowd, where the sound is fast, enters the linear system
A_IMPLICIT = 1e-2
#: relative residual of the conjugate gradients (the correction is then applied as fluxes,
#: so the mass stays exact to round-off whatever this is). On Example 2 (paper preset) 1e-4
#: takes 4.9 iterations a solve, 1e-6 8.4 and 1e-8 12; 1e-4 and 1e-6 give T50 and T90 within
#: 0.002 s of each other, T100 within 0.1 s, and the same orders in the tests
CG_RTOL = 1e-4
#: the largest number of conjugate-gradient iterations of one solve
CG_MAXITER = 500


def enthalpy_table(law, rho_max: float = 60.0, n: int = 12000) -> tuple[np.ndarray, np.ndarray]:
    """(drho, h): ``h(rho) = int_0^rho p'(s)/s ds`` [m^2/s^2] at ``rho = k drho``,
    k = 0..n (finite at 0 for laws with p ~ rho^2 near vacuum; integrated on a geometric
    grid, then sampled on the uniform one, so that a lookup is one multiplication); beyond
    ``rho_max`` ``h`` grows as ``p'(rho_max) ln rho``."""
    r = np.concatenate([[0.0], np.geomspace(1e-8, rho_max, 20 * n)])
    c = law.sound_speed(r)
    g = np.where(r > 0, c * c / np.where(r > 0, r, 1.0), 0.0)  # p'(s)/s
    g[0] = g[1]  # the limit at vacuum (p'/s is bounded for these laws)
    h = np.concatenate([[0.0], np.cumsum(0.5 * (g[1:] + g[:-1]) * np.diff(r))])
    u = np.linspace(0.0, rho_max, n + 1)
    return np.array([rho_max / n]), np.ascontiguousarray(np.interp(u, r, h))


@nb.njit(**FAST, inline="always")
def _h(rho, tr, th, kind, prm):
    """Enthalpy h(rho) from its uniform table (``tr[0]`` the spacing; linear interpolation;
    log beyond)."""
    if rho <= 0.0:
        return 0.0
    n = th.shape[0] - 1
    x = rho / tr[0]
    if x >= n:
        r_n = n * tr[0]
        _, c = _p_c(kind, prm, r_n)
        return th[n] + c * c * math.log(rho / r_n)
    k = int(x)
    w = x - k
    return th[k] + w * (th[k + 1] - th[k])


@nb.njit(**PAR)
def _faces(V, Rq, L, R, nx, ny, ln, tau, areas, dt, kind, prm, cact, livef, thr, pc, a, G,
           imp):
    """Per interior face: the pressure coupling ``a`` [m^2], the Rhie-Chow mass ``G``
    [ped] (see module docstring), and whether the face is implicit (``imp``: ``a`` above
    ``thr`` times the smaller area of its cells; else its pressure flux is explicit); 0 on
    faces that are not live (``livef``). ``pc`` (2, m) work array: p and p' per active
    cell (``cact``)."""
    m = areas.shape[0]
    for c_ in nb.prange(NCHUNK):
        for b_ in range(c_, (m + BLOCK - 1) // BLOCK, NCHUNK):
            for i in range(b_ * BLOCK, min(m, (b_ + 1) * BLOCK)):
                if cact[i]:
                    p, c = _p_c(kind, prm, max(V[i, 0], 0.0))
                    pc[0, i] = p
                    pc[1, i] = c * c
    n_e = L.shape[0]
    for c_ in nb.prange(NCHUNK):
        for b_ in range(c_, (n_e + BLOCK - 1) // BLOCK, NCHUNK):
            for f in range(b_ * BLOCK, min(n_e, (b_ + 1) * BLOCK)):
                if not livef[f]:
                    a[f] = G[f] = 0.0
                    imp[f] = False
                    continue
                i = L[f]
                j = R[f]
                ri = max(V[i, 0], 0.0)
                rj = max(V[j, 0], 0.0)
                if abs(ri - rj) > 1e-9 * (ri + rj):
                    s = (pc[0, i] - pc[0, j]) / (ri - rj)  # the secant slope of p
                else:
                    s = 0.5 * (pc[1, i] + pc[1, j])
                a[f] = dt * dt * tau[f] * max(s, 0.0)
                G[f] = dt * dt * ln[f] * 0.5 * ((Rq[i, 0] + Rq[j, 0]) * nx[f]
                                                + (Rq[i, 1] + Rq[j, 1]) * ny[f])
                imp[f] = a[f] > thr * min(areas[i], areas[j])


@nb.njit(**FAST, inline="always")
def _face_mass(f, imp, G, a, rho_sol, V, L, R):
    """The face mass ``G + a (rho_L - rho_R)`` of face ``f`` before the limiter (the
    densities of the solution on implicit faces ``imp``, those of ``V`` on the others)."""
    if imp[f]:
        return G[f] + a[f] * (rho_sol[L[f]] - rho_sol[R[f]])
    return G[f] + a[f] * (V[L[f], 0] - V[R[f], 0])


@nb.njit(**FAST, inline="always")
def _limited_mass(f, imp, G, a, rho_sol, V, L, R, lim):
    """The face mass of face ``f`` scaled by the share ``lim`` of the cell it leaves."""
    x = _face_mass(f, imp, G, a, rho_sol, V, L, R)
    return x * (lim[L[f]] if x > 0.0 else lim[R[f]])


@nb.njit(**PAR)
def _apply(V, rho_sol, a, G, imp, L, R, nx, ny, ln, areas, cf, cs, ecell, enx, eny, eln,
           kind, prm, tr, th, enthalpy, dt, rho_vac, umax, cact, livef, W, out):
    """Face masses ``X = G + a (rho_L - rho_R)`` (the densities of the solution on implicit
    faces ``imp``, those of the explicit stage ``V`` on the others), limited so that no cell
    loses more than it holds, applied to the density; the momentum gets the pressure force
    of the new density and the momentum the face masses carry. Cells outside the active set
    ``cact`` keep their state, faces that are not live (``livef``) pass nothing (their
    ``a`` and ``G`` are 0). ``W`` (5, m) work array.

    Three passes over the cells (a parallel region costs about as much as a pass's work on
    Example 2): each cell computes the masses of its faces itself (both cells of a face the
    same number), so no pass over the faces stores them."""
    m = areas.shape[0]
    lim, ux, uy, hc, pc = W[0], W[1], W[2], W[3], W[4]
    # per cell: the share of its outflows it can afford, and its velocity
    for c_ in nb.prange(NCHUNK):
        for b_ in range(c_, (m + BLOCK - 1) // BLOCK, NCHUNK):
            for i in range(b_ * BLOCK, min(m, (b_ + 1) * BLOCK)):
                o = 0.0
                for k in range(3):
                    f = cf[i, k]
                    if f >= 0:
                        x = cs[i, k] * _face_mass(f, imp, G, a, rho_sol, V, L, R)
                        if x > 0.0:
                            o += x
                have = areas[i] * max(V[i, 0], 0.0)
                lim[i] = 1.0 if o <= have else have / o
                if cact[i]:
                    _, ux[i], uy[i] = _prim(V[i, 0], V[i, 1], V[i, 2], rho_vac, umax)
    # the density with its enthalpy and pressure, then the momentum (faces gathered per
    # cell in a fixed order)
    for c_ in nb.prange(NCHUNK):
        for b_ in range(c_, (m + BLOCK - 1) // BLOCK, NCHUNK):
            for i in range(b_ * BLOCK, min(m, (b_ + 1) * BLOCK)):
                if not cact[i]:
                    out[i, 0] = V[i, 0]
                    continue
                r = areas[i] * V[i, 0]
                for k in range(3):
                    f = cf[i, k]
                    if f >= 0:
                        r -= cs[i, k] * _limited_mass(f, imp, G, a, rho_sol, V, L, R, lim)
                r /= areas[i]
                if r < 0.0:  # round-off below an emptied cell
                    r = 0.0
                out[i, 0] = r
                hc[i], pc[i] = _h_p(r, tr, th, kind, prm, enthalpy)
    for c_ in nb.prange(NCHUNK):
        for b_ in range(c_, (m + BLOCK - 1) // BLOCK, NCHUNK):
            for i in range(b_ * BLOCK, min(m, (b_ + 1) * BLOCK)):
                if not cact[i]:
                    out[i, 1] = V[i, 1]
                    out[i, 2] = V[i, 2]
                    continue
                fx, fy = _pressure_force(i, out[i, 0], hc, pc, enthalpy, L, R, nx, ny, ln,
                                         cf, cs, ecell, enx, eny, eln, livef)
                mx = V[i, 1]
                my = V[i, 2]
                ia = 1.0 / areas[i]
                for k in range(3):
                    f = cf[i, k]
                    if f < 0 or not livef[f]:
                        continue
                    # momentum of the face mass, with the velocity of the cell it leaves
                    sg = cs[i, k]  # +1: the face's normal points out of i
                    j = R[f] if sg > 0 else L[f]
                    x = sg * _limited_mass(f, imp, G, a, rho_sol, V, L, R, lim)  # > 0: out
                    src = i if x > 0.0 else j
                    mx -= x * ia * ux[src]
                    my -= x * ia * uy[src]
                out[i, 1] = mx + dt * ia * fx
                out[i, 2] = my + dt * ia * fy


@nb.njit(**FAST, inline="always")
def _h_p(r, tr, th, kind, prm, enthalpy):
    """The enthalpy (0 without ``enthalpy``) and the pressure at density ``r``."""
    p, _ = _p_c(kind, prm, r)
    return (_h(r, tr, th, kind, prm) if enthalpy else 0.0), p


@nb.njit(**FAST, inline="always")
def _pressure_force(i, ri, hc, pc, enthalpy, L, R, nx, ny, ln, cf, cs, ecell, enx, eny, eln,
                    livef):
    """The pressure force on cell i (density ``ri``) integrated over its faces [ped m/s^2]:
    ``-rho_i grad h`` as a two-point difference of the cells' enthalpies ``hc`` across the
    ``livef`` interior faces (the isothermal law, ``enthalpy`` False: ``-grad p`` of the
    pressures ``pc``), and at exits the cell's own pressure on the face."""
    fx = 0.0
    fy = 0.0
    for k in range(3):
        f = cf[i, k]
        if f < 0:
            e = ecell[i, k]
            if e >= 0:  # an exit: the cell's pressure on the face
                fx += eln[e] * enx[e] * pc[i]
                fy += eln[e] * eny[e] * pc[i]
            continue
        if not livef[f]:
            continue
        sg = cs[i, k]  # +1: the face's normal points out of i
        j = R[f] if sg > 0 else L[f]
        if enthalpy:
            w = 0.5 * ri * (hc[j] - hc[i])
        else:
            w = 0.5 * (pc[j] - pc[i])
        fx -= ln[f] * sg * nx[f] * w
        fy -= ln[f] * sg * ny[f] * w
    return fx, fy


@nb.njit(**PAR)
def _subtract_force(rho, kind, prm, tr, th, enthalpy, L, R, nx, ny, ln, areas, cf, cs, ecell,
                    enx, eny, eln, livef, cact, W, out):
    """out[i, 1:3] -= the pressure force per area (:func:`_pressure_force`) at the
    densities ``rho``, for the active cells ``cact``. ``W`` (2, m) work array."""
    m = rho.shape[0]
    hc, pc = W[0], W[1]
    for c_ in nb.prange(NCHUNK):
        for b_ in range(c_, (m + BLOCK - 1) // BLOCK, NCHUNK):
            for i in range(b_ * BLOCK, min(m, (b_ + 1) * BLOCK)):
                hc[i], pc[i] = _h_p(rho[i], tr, th, kind, prm, enthalpy)
    for c_ in nb.prange(NCHUNK):
        for b_ in range(c_, (m + BLOCK - 1) // BLOCK, NCHUNK):
            for i in range(b_ * BLOCK, min(m, (b_ + 1) * BLOCK)):
                if not cact[i]:
                    continue
                fx, fy = _pressure_force(i, rho[i], hc, pc, enthalpy, L, R, nx, ny, ln, cf,
                                         cs, ecell, enx, eny, eln, livef)
                out[i, 1] -= fx / areas[i]
                out[i, 2] -= fy / areas[i]


class ImplicitPressure:
    """The implicit correction of a semi-implicit stage (see module docstring) for a
    barotropic model on a mesh.

    Parameters
    ----------
    mesh
        The triangle mesh.
    model
        The model (its pressure ``law``, ``rho_vac``, ``u_max``).
    """

    def __init__(self, mesh, model) -> None:
        from ...mesh.triangle_mesh import BoundaryKind

        e2t = mesh.edge_triangles
        interior = np.flatnonzero(e2t[:, 1] >= 0)
        self.interior = interior
        self.L = np.ascontiguousarray(e2t[interior, 0])
        self.R = np.ascontiguousarray(e2t[interior, 1])
        n = mesh.edge_normals[interior]
        self.nx = np.ascontiguousarray(n[:, 0])
        self.ny = np.ascontiguousarray(n[:, 1])
        self.ln = np.ascontiguousarray(mesh.edge_lengths[interior])
        c = mesh.centroids
        dc = c[self.R] - c[self.L]
        shift = getattr(mesh, "cell_shift", None)
        if shift is not None:  # (a building's atlas: R's centroid in L's frame)
            dc = dc + shift(self.L, self.R)
        d = dc[:, 0] * self.nx + dc[:, 1] * self.ny  # normal distance of the centroids
        dist = np.hypot(dc[:, 0], dc[:, 1])
        d = np.where(d > 0.2 * dist, d, dist)
        self.tau = self.ln / d  # [1]
        self.areas = mesh.areas
        m = mesh.n_triangles
        # per cell and local edge: the interior face number (-1 otherwise), the sign
        # (+1 where the face normal points out of the cell), and the exit number (-1)
        face_of = np.full(mesh.n_edges, -1, np.int64)
        face_of[interior] = np.arange(len(interior))
        t2e = cell_edges(mesh)
        self.cf = face_of[t2e]
        self.cs = np.where(e2t[t2e, 0] == np.arange(m)[:, None], 1.0, -1.0)
        exits = np.flatnonzero(mesh.edge_kind == BoundaryKind.EXIT)
        exit_of = np.full(mesh.n_edges, -1, np.int64)
        exit_of[exits] = np.arange(len(exits))
        self.ecell = exit_of[t2e]
        self.enx = np.ascontiguousarray(mesh.edge_normals[exits, 0])
        self.eny = np.ascontiguousarray(mesh.edge_normals[exits, 1])
        self.eln = np.ascontiguousarray(mesh.edge_lengths[exits])
        # the neighbour across each local face (for the system's rows)
        nb_ = np.where(self.cs > 0, self.R[np.maximum(self.cf, 0)], self.L[np.maximum(self.cf, 0)])
        self.nbr = np.where(self.cf >= 0, nb_, -1).astype(np.int64)
        law = model.law
        self.kind = int(law.kind)
        self.prm = np.ascontiguousarray(law.params, dtype=np.float64)
        self.enthalpy = law.kind != ISOTHERMAL  # (isothermal: grad p, h = c0^2 ln rho)
        self.tr, self.th = enthalpy_table(law) if self.enthalpy else (np.ones(1), np.zeros(2))
        self.rho_vac = float(model.rho_vac)
        self.u_max = float(model.u_max)
        k = len(interior)
        self._a = np.empty(k)
        self._G = np.empty(k)
        self._imp = np.zeros(k, np.bool_)
        self._W = np.empty((5, m))
        #: statistics: solves, conjugate-gradient iterations, unknowns (summed)
        self.stats = {"solves": 0, "iterations": 0, "unknowns": 0}

    def correct(self, V: np.ndarray, Rq: np.ndarray, dt: float, cact: np.ndarray,
                livef: np.ndarray) -> np.ndarray:
        """The corrected state (m, 3) of the explicit stage's result ``V`` (m, 3) (its
        momentum change per second ``Rq`` (m, 2)) for a stage of length ``dt`` [s], on the
        active cells ``cact`` (m,) and the live interior faces ``livef`` (faces whose cells
        are both active; see :meth:`live_faces`)."""
        a, G, imp = self._a, self._G, self._imp
        V = np.ascontiguousarray(V)  # (Rq may be a view: the kernel reads it in place)
        _faces(V, Rq, self.L, self.R, self.nx, self.ny, self.ln, self.tau, self.areas, dt,
               self.kind, self.prm, cact, livef, A_IMPLICIT, self._W, a, G, imp)
        cells, indptr, indices, data, b, x0, scale, rho = _system(
            a, G, imp, V, self.areas, self.cf, self.cs, self.nbr)
        n = len(cells)
        if n:
            # the system scaled symmetrically to a unit diagonal (Jacobi), solved by CG
            y, it = conjugate_gradients(indptr, indices, data, b, x0, CG_RTOL, CG_MAXITER)
            _scatter_scaled(rho, cells, y, scale)
            self.stats["solves"] += 1
            self.stats["iterations"] += it
            self.stats["unknowns"] += n
        out = np.empty_like(V)
        _apply(V, rho, a, G, imp, self.L, self.R, self.nx, self.ny, self.ln, self.areas,
               self.cf, self.cs, self.ecell, self.enx, self.eny, self.eln, self.kind, self.prm,
               self.tr, self.th, self.enthalpy, dt, self.rho_vac, self.u_max, cact, livef,
               self._W, out)
        return out

    def subtract_pressure_force(self, rho: np.ndarray, out: np.ndarray,
                                cact: np.ndarray | None = None) -> None:
        """``out[:, 1:3] -=`` the pressure force per area [ped m/s^2 per m^2] with which
        :meth:`correct` applies the pressure at the densities ``rho`` (m,) (every interior
        face; on the active cells ``cact``, else all): a model that moves part of its force
        into the pressure (mac1's local repulsion) takes it out of its explicit source
        with it."""
        m = len(rho)
        if cact is None:
            cact = np.ones(m, np.bool_)
        if getattr(self, "_all_faces", None) is None:
            self._all_faces = np.ones(len(self.L), np.bool_)
        _subtract_force(np.ascontiguousarray(rho, dtype=np.float64), self.kind, self.prm,
                        self.tr, self.th, self.enthalpy, self.L, self.R, self.nx, self.ny,
                        self.ln, self.areas, self.cf, self.cs, self.ecell, self.enx, self.eny,
                        self.eln, self._all_faces, cact, self._W, out)

    def live_faces(self, live: np.ndarray) -> np.ndarray:
        """The interior faces (in this object's numbering) among the ``live`` edges."""
        return live[self.interior]


@nb.njit(**PAR)
def _system(a, G, imp, V, areas, cf, cs, nbr):
    """The linear system of the implicit faces ``imp`` over the cells they couple
    (``cells``): ``(diag|T| + sum_f a_f (e_i - e_j)(e_i - e_j)^T) rho = r`` with ``r = |T| rho*``
    minus the divergence of ``G`` and of the explicit faces' pressure flux
    ``a_f (rho*_L - rho*_R)``, scaled to a unit diagonal (``D^-1/2 A D^-1/2 y = D^-1/2 r``,
    ``rho = D^-1/2 y``): CSR arrays, right-hand side, first guess and ``D^-1/2``. Also
    ``r / |T|`` of every cell (the new density of the cells outside the system).

    Three passes: the cells in parallel (right-hand side, diagonal, row length), the rows
    numbered in order (a running sum, the only serial part), the rows filled in parallel;
    every number is computed as by one serial pass."""
    m = areas.shape[0]
    rho = np.empty(m)
    dg = np.empty(m)
    width = np.zeros(m, np.int64)  # 1 + implicit faces of the cells in the system, else 0
    for c_ in nb.prange(NCHUNK):
        for b_ in range(c_, (m + BLOCK - 1) // BLOCK, NCHUNK):
            for i in range(b_ * BLOCK, min(m, (b_ + 1) * BLOCK)):
                s = areas[i] * V[i, 0]
                d = areas[i]
                w = 0
                for k in range(3):
                    f = cf[i, k]
                    if f < 0:
                        continue
                    if imp[f]:
                        s -= cs[i, k] * G[f]
                        d += a[f]
                        w += 1
                    else:
                        s -= cs[i, k] * (G[f] + cs[i, k] * a[f] * (V[i, 0] - V[nbr[i, k], 0]))
                rho[i] = s / areas[i]
                dg[i] = d
                width[i] = w + 1 if w > 0 else 0
    loc = np.full(m, -1, np.int64)
    n = 0
    for i in range(m):
        if width[i] > 0:
            loc[i] = n
            n += 1
    cells = np.empty(n, np.int64)
    indptr = np.zeros(n + 1, np.int64)
    nnz = 0
    for i in range(m):
        if width[i] > 0:
            cells[loc[i]] = i
            nnz += width[i]
            indptr[loc[i] + 1] = nnz
    indices = np.empty(nnz, np.int32)
    data = np.empty(nnz)
    b = np.empty(n)
    x0 = np.empty(n)
    scale = np.empty(n)
    for c_ in nb.prange(NCHUNK):
        for b_ in range(c_, (n + BLOCK - 1) // BLOCK, NCHUNK):
            for r in range(b_ * BLOCK, min(n, (b_ + 1) * BLOCK)):
                i = cells[r]
                si = 1.0 / np.sqrt(dg[i])
                scale[r] = si
                p = indptr[r]
                indices[p] = r
                data[p] = 1.0
                q = p + 1
                for k in range(3):
                    f = cf[i, k]
                    if f >= 0 and imp[f]:
                        j = nbr[i, k]
                        indices[q] = loc[j]
                        data[q] = -a[f] * si / np.sqrt(dg[j])
                        q += 1
                b[r] = rho[i] * areas[i] * si
                x0[r] = rho[i] / si
    return cells, indptr, indices, data, b, x0, scale, rho


#: the length of the chunks of the conjugate gradients' vectors: each chunk is one task of
#: the threads, and the dot products add the chunks' partial sums in order (fixed: the
#: answer does not depend on the number of threads)
CG_CHUNK = 1024


@nb.njit(cache=True, nogil=True, parallel=True)
def _cg_dot(x, y, part):
    """``x . y`` over the chunks."""
    n = x.shape[0]
    nc = (n + CG_CHUNK - 1) // CG_CHUNK
    for c in nb.prange(nc):
        acc = 0.0
        for i in range(c * CG_CHUNK, min(n, (c + 1) * CG_CHUNK)):
            acc += x[i] * y[i]
        part[c] = acc
    return sum_in_order(part, nc)


@nb.njit(cache=True, nogil=True, parallel=True)
def _cg_matvec_dot(indptr, indices, data, p, q, part):
    """``q = A p`` (CSR, rows in their stored order) and ``p . q``."""
    n = q.shape[0]
    nc = (n + CG_CHUNK - 1) // CG_CHUNK
    for c in nb.prange(nc):
        acc = 0.0
        for r in range(c * CG_CHUNK, min(n, (c + 1) * CG_CHUNK)):
            s = 0.0
            for k in range(indptr[r], indptr[r + 1]):
                s += data[k] * p[indices[k]]
            q[r] = s
            acc += p[r] * s
        part[c] = acc
    return sum_in_order(part, nc)


@nb.njit(cache=True, nogil=True, parallel=True)
def _cg_update(alpha, p, q, x, r, part):
    """``x += alpha p``, ``r -= alpha q``, and ``r . r``."""
    n = x.shape[0]
    nc = (n + CG_CHUNK - 1) // CG_CHUNK
    for c in nb.prange(nc):
        acc = 0.0
        for i in range(c * CG_CHUNK, min(n, (c + 1) * CG_CHUNK)):
            x[i] += alpha * p[i]
            ri = r[i] - alpha * q[i]
            r[i] = ri
            acc += ri * ri
        part[c] = acc
    return sum_in_order(part, nc)


@nb.njit(cache=True, nogil=True, parallel=True)
def _cg_direction(r, beta, p):
    """``p = r + beta p``."""
    n = p.shape[0]
    nc = (n + CG_CHUNK - 1) // CG_CHUNK
    for c in nb.prange(nc):
        for i in range(c * CG_CHUNK, min(n, (c + 1) * CG_CHUNK)):
            p[i] = r[i] + beta * p[i]


@nb.njit(cache=True, nogil=True, parallel=True)
def _scatter_scaled(rho, cells, y, scale):
    """``rho[cells] = y * scale``, on the threads."""
    n = cells.shape[0]
    for c_ in nb.prange(NCHUNK):
        for b_ in range(c_, (n + BLOCK - 1) // BLOCK, NCHUNK):
            for r in range(b_ * BLOCK, min(n, (b_ + 1) * BLOCK)):
                rho[cells[r]] = y[r] * scale[r]


@nb.njit(cache=True, nogil=True)
def conjugate_gradients(indptr, indices, data, b, x0, rtol, maxiter):
    """The symmetric positive definite system ``A x = b`` (CSR; scaled to a unit diagonal,
    so unpreconditioned) by conjugate gradients from ``x0``, until ``|r| < rtol |b|`` (as
    :func:`scipy.sparse.linalg.cg`): ``(x, iterations)``. Three parallel passes an
    iteration (the product with its dot product, the updates with theirs, the new
    direction); every dot product adds fixed chunks in order: the same answer on any
    number of threads."""
    n = b.shape[0]
    part = np.empty((n + CG_CHUNK - 1) // CG_CHUNK + 1)
    x = x0.copy()
    q = np.empty(n)
    _cg_matvec_dot(indptr, indices, data, x, q, part)
    r = b - q
    tol = rtol * np.sqrt(_cg_dot(b, b, part))
    rr = _cg_dot(r, r, part)
    p = r.copy()
    it = 0
    while it < maxiter and not np.sqrt(rr) < tol:
        pq = _cg_matvec_dot(indptr, indices, data, p, q, part)
        alpha = rr / pq
        rr_new = _cg_update(alpha, p, q, x, r, part)
        it += 1
        if np.sqrt(rr_new) < tol:
            break
        _cg_direction(r, rr_new / rr, p)
        rr = rr_new
    return x, it
