"""Nonlocal operators of the derived continuum models, discretised on the triangles.

Repulsion (paper mac1, f21 with the SFM kernel)::

    F_i = rho_i sum_j W_ij rho_j,   W_ij = |T_i|^-1 int_{T_i} int_{T_j} Phi(|x-y|) (x-y)/|x-y| dy dx

Friction (f31)::

    D_i = rho_i sum_j K_ij rho_j (u_j - u_i),   K_ij = |T_i|^-1 int int Psi(|x-y|) t t^T,
    t = (x-y)^perp/|x-y|

The cell-pair integrals of a kernel 0.08 m wide over cells of 0.3-1 m are computed exactly
up to quadrature error by turning them into double line integrals over the two triangle
boundaries (divergence theorem twice, with the radial potentials of
:class:`~pedmesh.models.continuum.physics.RadialTables`)::

    int int Phi r_hat   = - oint_{dT_i} oint_{dT_j} n_x FG(r) ((y-x).n_y)/r^2
    int int Psi t t^T   = - oint oint Q(r) n_x n_y^T  +  I oint oint Gam(r) (n_x.n_y)

whose integrands are bounded; each edge pair is integrated with Gauss-Legendre on pieces
graded towards the points where the edges come closest. Each pair (i < j) is integrated
once and mirrored: ``|T_i| W_ij = -|T_j| W_ji`` and ``|T_i| K_ij = |T_j| K_ji``, so the
repulsion conserves momentum exactly and the friction conserves momentum and dissipates
kinetic energy exactly (K is positive semi-definite).

Walls: the equations have no wall force. pedmesh lets walls act as mirrors, like the mirror
ghost states of the flux: every cell near a wall feels the repulsion of its mirror images
across the walls (straight wall pieces; corners get the images across both walls, not the
double reflection), so a crowd of uniform density is in equilibrium at a straight wall and
is pushed away from a wall it presses against. Exits have no images (empty space beyond).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
import scipy.sparse as sp

from ...mesh.triangle_mesh import BoundaryKind, TriMesh
from .physics import RadialTables
from ...parameters import DEFAULTS as D
from ..._threads import ensure_tbb

ensure_tbb()  # (before numba's first parallel loop: pedmesh._threads)

__all__ = ["PairOperators", "build_pair_operators", "LongRangeOperator"]

_GL3 = (np.array([-math.sqrt(3 / 5), 0.0, math.sqrt(3 / 5)]), np.array([5 / 9, 8 / 9, 5 / 9]))


@nb.njit(cache=True, nogil=True, inline="always")
def _interp(tab, dr, r, tail):
    """Linear interpolation of a table on [0, r_max]; beyond, the constant ``tail``."""
    s = r / dr
    i = int(s)
    if i >= tab.shape[0] - 1:
        return tail
    w = s - i
    return tab[i] * (1.0 - w) + tab[i + 1] * w


@nb.njit(cache=True, nogil=True, inline="always")
def _gam(tab, dr, r, r_max, gam_max, fg_inf):
    """Gam(r), with its logarithmic tail Gam(r_max) + Fg_inf ln(r / r_max)."""
    if r >= r_max:
        return gam_max + fg_inf * math.log(r / r_max)
    return _interp(tab, dr, r, gam_max)


@nb.njit(cache=True, nogil=True)
def _seg_dist(ax, ay, bx, by, cx, cy, dx, dy):
    """Distance between segments AB and CD and the parameters (s on AB, t on CD) of a
    closest pair (approximately: the best of the four end-point projections)."""
    best = np.inf
    bs = 0.0
    bt = 0.0
    # project endpoints of each onto the other
    for k in range(4):
        if k < 2:
            px = ax if k == 0 else bx
            py = ay if k == 0 else by
            ux, uy, vx, vy = cx, cy, dx, dy
        else:
            px = cx if k == 2 else dx
            py = cy if k == 2 else dy
            ux, uy, vx, vy = ax, ay, bx, by
        ex = vx - ux
        ey = vy - uy
        L2 = ex * ex + ey * ey
        t = ((px - ux) * ex + (py - uy) * ey) / L2 if L2 > 0 else 0.0
        t = min(max(t, 0.0), 1.0)
        qx = ux + t * ex
        qy = uy + t * ey
        d = math.sqrt((px - qx) ** 2 + (py - qy) ** 2)
        if d < best:
            best = d
            if k == 0:
                bs, bt = 0.0, t
            elif k == 1:
                bs, bt = 1.0, t
            elif k == 2:
                bs, bt = t, 0.0
            else:
                bs, bt = t, 1.0
    return best, bs, bt


@nb.njit(cache=True, nogil=True, inline="always")
def _gauss_piece(lo, hi, L, gl_x, gl_w, nodes, weights, n):
    """Append the Gauss-Legendre nodes of the piece [lo, hi] of [0, 1] (edge length L)
    at position n; returns the new count."""
    mid = 0.5 * (lo + hi)
    half = 0.5 * (hi - lo)
    for g in range(gl_x.shape[0]):
        nodes[n] = mid + half * gl_x[g]
        weights[n] = half * gl_w[g] * L
        n += 1
    return n


@nb.njit(cache=True, nogil=True)
def _graded_nodes(L, s0, d, h0, gl_x, gl_w, nodes, weights):
    """Gauss-Legendre nodes on [0, 1] (edge of length L) on pieces graded towards the
    parameter s0, where the other edge is closest (at distance d); returns the count."""
    n = 0
    base = max(h0, 0.7 * d)  # first piece length [m] at the closest point
    for side in range(2):
        a = s0
        length = base
        while True:
            if side == 0:
                b = min(a + length / L, 1.0)
                lo, hi = a, b
            else:
                b = max(a - length / L, 0.0)
                lo, hi = b, a
            if hi > lo:
                n = _gauss_piece(lo, hi, L, gl_x, gl_w, nodes, weights, n)
            if (side == 0 and b >= 1.0) or (side == 1 and b <= 0.0):
                break
            a = b
            length *= 2.2
    return n


@nb.njit(cache=True, nogil=True)
def _uniform_nodes(L, piece, gl_x, gl_w, nodes, weights):
    """Gauss-Legendre nodes on [0, 1] on equal pieces of about ``piece`` metres."""
    k = max(1, min(int(math.ceil(L / piece)), nodes.shape[0] // gl_x.shape[0]))
    n = 0
    for j in range(k):
        n = _gauss_piece(j / k, (j + 1) / k, L, gl_x, gl_w, nodes, weights, n)
    return n


@nb.njit(cache=True, nogil=True)
def pair_integral(Ti, Tj, FG, Qt, Gam, dr, r_max, FG_inf, Q_inf, Gam_max, Fg_inf,
                  want_w, want_k, h0, gl_x, gl_w, out_w, out_k):
    """int_{T_i} int_{T_j} Phi r_hat (2,) and Psi t t^T (2, 2) for two counter-clockwise
    triangles (3, 2), by double line integrals (see module docstring)."""
    out_w[0] = 0.0
    out_w[1] = 0.0
    out_k[0, 0] = 0.0
    out_k[0, 1] = 0.0
    out_k[1, 0] = 0.0
    out_k[1, 1] = 0.0
    xs = np.empty(512)
    xw = np.empty(512)
    ys = np.empty(512)
    yw = np.empty(512)
    for a in range(3):
        ax, ay = Ti[a, 0], Ti[a, 1]
        bx, by = Ti[(a + 1) % 3, 0], Ti[(a + 1) % 3, 1]
        Le = math.sqrt((bx - ax) ** 2 + (by - ay) ** 2)
        nex = (by - ay) / Le
        ney = -(bx - ax) / Le
        for b in range(3):
            cx, cy = Tj[b, 0], Tj[b, 1]
            dx, dy = Tj[(b + 1) % 3, 0], Tj[(b + 1) % 3, 1]
            Lf = math.sqrt((dx - cx) ** 2 + (dy - cy) ** 2)
            nfx = (dy - cy) / Lf
            nfy = -(dx - cx) / Lf
            d, s0, t0 = _seg_dist(ax, ay, bx, by, cx, cy, dx, dy)
            cross = (bx - ax) * (dy - cy) - (by - ay) * (dx - cx)
            if d < 1e-12 and abs(cross) < 1e-9 * Le * Lf:
                # collinear and touching (a shared edge): the kernels are singular along
                # the whole diagonal s = t, so use uniform fine pieces on both
                nx_ = _uniform_nodes(Le, 4.0 * h0, gl_x, gl_w, xs, xw)
                ny_ = _uniform_nodes(Lf, 4.0 * h0, gl_x, gl_w, ys, yw)
            else:
                nx_ = _graded_nodes(Le, s0, d, h0, gl_x, gl_w, xs, xw)
                ny_ = _graded_nodes(Lf, t0, d, h0, gl_x, gl_w, ys, yw)
            ndot = nex * nfx + ney * nfy
            for p in range(nx_):
                px = ax + xs[p] * (bx - ax)
                py = ay + xs[p] * (by - ay)
                for q in range(ny_):
                    qx = cx + ys[q] * (dx - cx)
                    qy = cy + ys[q] * (dy - cy)
                    rx = qx - px
                    ry = qy - py
                    r2 = rx * rx + ry * ry
                    r = math.sqrt(r2)
                    w = xw[p] * yw[q]
                    if want_w and r2 > 0.0:
                        f = _interp(FG, dr, r, FG_inf) * (rx * nfx + ry * nfy) / r2 * w
                        out_w[0] -= nex * f
                        out_w[1] -= ney * f
                    if want_k:
                        qv = _interp(Qt, dr, r, Q_inf) * w
                        out_k[0, 0] -= qv * nex * nfx
                        out_k[0, 1] -= qv * nex * nfy
                        out_k[1, 0] -= qv * ney * nfx
                        out_k[1, 1] -= qv * ney * nfy
                        gv = _gam(Gam, dr, r, r_max, Gam_max, Fg_inf) * ndot * w
                        out_k[0, 0] += gv
                        out_k[1, 1] += gv


@nb.njit(cache=True, nogil=True)
def _tri_distances(tri_pts, I, J, out):
    """Smallest distance between triangles I[p] and J[p] (non-overlapping triangles)."""
    for p in range(I.shape[0]):
        A = tri_pts[I[p]]
        B = tri_pts[J[p]]
        best = np.inf
        for a in range(3):
            for b in range(3):
                d, _, _ = _seg_dist(A[a, 0], A[a, 1], A[(a + 1) % 3, 0], A[(a + 1) % 3, 1],
                                    B[b, 0], B[b, 1], B[(b + 1) % 3, 0], B[(b + 1) % 3, 1])
                if d < best:
                    best = d
        out[p] = best


@nb.njit(cache=True, nogil=True, parallel=True)  # (each pair writes only its own row: no race)
def _all_pairs(tri_pts, I, J, dist, k_range, FG, Qt, Gam, dr, r_max, FG_inf, Q_inf, Gam_max,
               Fg_inf, want_w, want_k, h0, gl_x, gl_w, W, K):
    for p in nb.prange(I.shape[0]):
        w = np.empty(2)
        k = np.empty((2, 2))
        wk = want_k and dist[p] < k_range
        pair_integral(tri_pts[I[p]], tri_pts[J[p]], FG, Qt, Gam, dr, r_max, FG_inf, Q_inf,
                      Gam_max, Fg_inf, want_w, wk, h0, gl_x, gl_w, w, k)
        W[p, 0] = w[0]
        W[p, 1] = w[1]
        # symmetric tensor: average the (quadrature) asymmetry away
        K[p, 0] = k[0, 0]
        K[p, 1] = 0.5 * (k[0, 1] + k[1, 0])
        K[p, 2] = k[1, 1]


@nb.njit(cache=True, nogil=True, parallel=True)  # (each pair writes only its own row: no race)
def _image_pairs(tri_pts, img, near, A, B, FG, Qt, Gam, dr, r_max, FG_inf, Q_inf, Gam_max,
                 Fg_inf, h0, gl_x, gl_w, W):
    """The repulsion integrals of cell ``near[A[p]]`` and wall image ``img[B[p]]`` into
    ``W[p]``."""
    for p in nb.prange(A.shape[0]):
        w = np.empty(2)
        k = np.empty((2, 2))
        # (bool(): a constant argument is a type of its own to numba, which would compile
        # pair_integral once more for it than for _all_pairs' flags)
        pair_integral(tri_pts[near[A[p]]], img[B[p]], FG, Qt, Gam, dr, r_max, FG_inf, Q_inf,
                      Gam_max, Fg_inf, bool(True), bool(False), h0, gl_x, gl_w, w, k)
        W[p, 0] = w[0]
        W[p, 1] = w[1]


@nb.njit(cache=True, nogil=True, inline="always")
def _row_dot2(ptr, idx, dx, dy, rho, i):
    """Row i of two CSR matrices with one pattern times rho (sums in CSR order)."""
    fx = 0.0
    fy = 0.0
    for k in range(ptr[i], ptr[i + 1]):
        r = rho[idx[k]]
        fx += dx[k] * r
        fy += dy[k] * r
    return fx, fy


@nb.njit(cache=True, nogil=True, parallel=True)  # (rows in parallel; no FMA: scipy's exact sums)
def _rep_apply(ptr, idx, dx, dy, iptr, iidx, ix, iy, walls, rho, active, out):
    """out_i = rho_i (sum_j W_ij rho_j [+ sum_j I_ij rho_j]) for both components, with Wx,
    Wy (and Ix, Iy) sharing one CSR pattern each (sums in CSR order, like scipy's); 0 in
    empty cells and in those outside ``active`` without summing their rows."""
    for i in nb.prange(rho.shape[0]):
        if rho[i] == 0.0 or not active[i]:
            out[i, 0] = out[i, 1] = 0.0
            continue
        fx, fy = _row_dot2(ptr, idx, dx, dy, rho, i)
        if walls:
            gx, gy = _row_dot2(iptr, iidx, ix, iy, rho, i)
            fx = fx + gx
            fy = fy + gy
        out[i, 0] = rho[i] * fx
        out[i, 1] = rho[i] * fy


@nb.njit(cache=True, nogil=True, inline="always")
def _fric_row(ptr, idx, kxx, kxy, kyy, rho, mom, active, i):
    """Row i of :func:`_fric_apply`: rho_i (K m)_i - (K rho)_i m_i (0 for an empty cell at
    rest and for a cell outside ``active``)."""
    if (rho[i] == 0.0 and mom[i, 0] == 0.0 and mom[i, 1] == 0.0) or not active[i]:
        return 0.0, 0.0
    rxx = 0.0
    rxy = 0.0
    ryy = 0.0
    axx = 0.0
    axy = 0.0
    ayx = 0.0
    ayy = 0.0
    for k in range(ptr[i], ptr[i + 1]):
        j = idx[k]
        r = rho[j]
        mx = mom[j, 0]
        my = mom[j, 1]
        rxx += kxx[k] * r
        rxy += kxy[k] * r
        ryy += kyy[k] * r
        axx += kxx[k] * mx
        axy += kxy[k] * my
        ayx += kxy[k] * mx
        ayy += kyy[k] * my
    mx = mom[i, 0]
    my = mom[i, 1]
    return (rho[i] * (axx + axy) - (rxx * mx + rxy * my),
            rho[i] * (ayx + ayy) - (rxy * mx + ryy * my))


@nb.njit(cache=True, nogil=True, parallel=True)
def _fric_apply(ptr, idx, kxx, kxy, kyy, rho, mom, active, out):
    """out_i = rho_i (K m)_i - (K rho)_i m_i with the 2x2 blocks K_ij = [[kxx, kxy], [kxy,
    kyy]] on one CSR pattern (see :meth:`PairOperators.friction`); 0 in empty cells at rest
    and in those outside ``active`` without summing their rows."""
    for i in nb.prange(rho.shape[0]):
        fx, fy = _fric_row(ptr, idx, kxx, kxy, kyy, rho, mom, active, i)
        out[i, 0] = fx
        out[i, 1] = fy


@nb.njit(cache=True, nogil=True, parallel=True)
def _fric_rk3(ptr, idx, kxx, kxy, kyy, rho, M, active, h, n, M1, M2):
    """``n`` Shu-Osher SSP-RK3 steps of length ``h`` [s] of dM/dt = friction(rho, M) (density
    fixed), in place on ``M`` (m, 2); ``M1``, ``M2`` (m, 2) work. Each stage is one parallel
    pass over the rows (every row reads the previous stage only), with the operations in
    the order of the numpy expressions ``M1 = M + h f(M)``, ``M2 = 3/4 M + 1/4 (M1 + h
    f(M1))``, ``M = M/3 + 2/3 (M2 + h f(M2))``, so the result is the same to the bit."""
    m = rho.shape[0]
    c23 = 2.0 / 3.0
    for _ in range(n):
        for i in nb.prange(m):
            fx, fy = _fric_row(ptr, idx, kxx, kxy, kyy, rho, M, active, i)
            M1[i, 0] = M[i, 0] + h * fx
            M1[i, 1] = M[i, 1] + h * fy
        for i in nb.prange(m):
            fx, fy = _fric_row(ptr, idx, kxx, kxy, kyy, rho, M1, active, i)
            M2[i, 0] = 0.75 * M[i, 0] + 0.25 * (M1[i, 0] + h * fx)
            M2[i, 1] = 0.75 * M[i, 1] + 0.25 * (M1[i, 1] + h * fy)
        for i in nb.prange(m):
            fx, fy = _fric_row(ptr, idx, kxx, kxy, kyy, rho, M2, active, i)
            M1[i, 0] = M[i, 0] / 3.0 + c23 * (M2[i, 0] + h * fx)
            M1[i, 1] = M[i, 1] / 3.0 + c23 * (M2[i, 1] + h * fy)
        for i in nb.prange(m):
            M[i, 0] = M1[i, 0]
            M[i, 1] = M1[i, 1]


def _all(m: int) -> np.ndarray:
    return np.ones(m, np.bool_)


def _same_pattern(*Ms) -> bool:
    a = Ms[0]
    return all(np.array_equal(a.indptr, b.indptr) and np.array_equal(a.indices, b.indices)
               for b in Ms[1:])


class PairOperators:
    """Sparse repulsion and friction operators of a mesh (see module docstring).

    Attributes
    ----------
    Wx, Wy
        (m, m) CSR matrices: ``F = rho * (W @ rho)`` per component [m/s^2 ped/m^2 ...].
    Kxx, Kxy, Kyy
        (m, m) CSR matrices of the friction tensor.
    Ix, Iy
        (m, m) CSR matrices of the wall images' repulsion (``rho * (I @ rho)``).

    The components of each operator share one sparsity pattern (they are assembled from the
    same cell pairs), so :meth:`repulsion` and :meth:`friction` each make one compiled pass
    over it instead of one scipy product per component.
    """

    def __init__(self, Wx, Wy, Kxx, Kxy, Kyy, Ix, Iy, n_pairs: int, build_s: float) -> None:
        self.Wx, self.Wy = Wx, Wy
        self.Kxx, self.Kxy, self.Kyy = Kxx, Kxy, Kyy
        self.Ix, self.Iy = Ix, Iy
        self.n_pairs = n_pairs
        self.build_s = build_s
        for group in ((Wx, Wy), (Kxx, Kxy, Kyy), (Ix, Iy)):
            if group[0] is not None and not _same_pattern(*group):
                raise ValueError("the components of a pair operator must share one pattern")

    @property
    def nnz(self) -> int:
        return sum(int(M.nnz) for M in (self.Wx, self.Kxx, self.Ix) if M is not None)

    def repulsion(self, rho: np.ndarray, walls: bool = True,
                  active: np.ndarray | None = None) -> np.ndarray:
        """(m, 2) repulsion force density rho_i sum_j W_ij rho_j (plus wall images); 0
        outside the cells ``active`` (m,) (default: all)."""
        rho = np.ascontiguousarray(rho, dtype=np.float64)
        out = np.empty((len(rho), 2))
        W, I_ = self.Wx, self.Ix
        use_i = bool(walls and I_ is not None)
        if not use_i:
            I_, Iy = W, self.Wy  # (not read)
        else:
            Iy = self.Iy
        _rep_apply(W.indptr, W.indices, W.data, self.Wy.data, I_.indptr, I_.indices, I_.data,
                   Iy.data, use_i, rho, _all(len(rho)) if active is None else active, out)
        return out

    def friction(self, rho: np.ndarray, mom: np.ndarray,
                 active: np.ndarray | None = None) -> np.ndarray:
        """(m, 2) friction force density rho_i sum_j K_ij rho_j (u_j - u_i), with
        rho_j u_j = m_j and rho_i u_i = m_i:
        rho_i sum_j K_ij (m_j - rho_j u_i) = rho_i (K m)_i - (K rho)_i m_i; 0 outside the
        cells ``active`` (m,) (default: all)."""
        rho = np.ascontiguousarray(rho, dtype=np.float64)
        mom = np.ascontiguousarray(mom, dtype=np.float64)
        out = np.empty((len(rho), 2))
        K = self.Kxx
        _fric_apply(K.indptr, K.indices, K.data, self.Kxy.data, self.Kyy.data, rho, mom,
                    _all(len(rho)) if active is None else active, out)
        return out

    def friction_steps(self, rho: np.ndarray, mom: np.ndarray, h: float, n: int,
                       active: np.ndarray | None = None) -> np.ndarray:
        """``n`` SSP-RK3 steps of length ``h`` [s] of d(rho u)/dt = :meth:`friction` with the
        density ``rho`` fixed, from the momentum ``mom`` (m, 2); the new momentum (m, 2)."""
        rho = np.ascontiguousarray(rho, dtype=np.float64)
        M = np.array(mom, dtype=np.float64, order="C")
        K = self.Kxx
        _fric_rk3(K.indptr, K.indices, K.data, self.Kxy.data, self.Kyy.data, rho, M,
                  _all(len(rho)) if active is None else active, float(h), int(n),
                  np.empty_like(M), np.empty_like(M))
        return M


def _tri_pts(mesh: TriMesh) -> np.ndarray:
    return np.ascontiguousarray(mesh.points[mesh.triangles])


def build_pair_operators(mesh: TriMesh, phi=None, psi=None, *, cutoff: float = D['cutoff'],
                         walls: bool = True, h0: float = 0.02) -> PairOperators:
    """Assemble the repulsion (kernel ``phi``) and friction (``psi``) operators of a mesh.

    Cell pairs whose closest points are nearer than ``cutoff`` [m] get the repulsion (at
    1.0 m the SFM potential G has fallen to 2e-6 of its contact value), pairs within the
    friction kernel's support get the friction. ``h0`` [m] is the first quadrature piece
    at the point where two edges touch.
    """
    import time

    from scipy.spatial import cKDTree

    t0 = time.perf_counter()
    tab = RadialTables.build(phi, psi)
    m = mesh.n_triangles
    P = _tri_pts(mesh)
    c = mesh.centroids
    rad = np.max(np.hypot(*(P - c[:, None, :]).transpose(2, 0, 1)), axis=1)
    tree = cKDTree(c)
    reach = cutoff + 2 * rad.max()
    pairs = tree.query_pairs(reach, output_type="ndarray")
    if len(pairs):
        d = np.hypot(*(c[pairs[:, 0]] - c[pairs[:, 1]]).T)
        keep = d < cutoff + rad[pairs[:, 0]] + rad[pairs[:, 1]]
        pairs = pairs[keep]
    I = np.ascontiguousarray(pairs[:, 0]) if len(pairs) else np.zeros(0, np.int64)
    J = np.ascontiguousarray(pairs[:, 1]) if len(pairs) else np.zeros(0, np.int64)
    dist = np.empty(len(I))
    _tri_distances(P, I, J, dist)
    # the repulsion needs pairs closer than the cut-off, the friction (compact support)
    # only pairs closer than its support
    phi_range = cutoff if phi is not None else 0.0
    k_range = psi.support if psi is not None else 0.0
    keep = dist < max(phi_range, k_range)
    I, J, dist = I[keep], J[keep], dist[keep]
    W = np.zeros((len(I), 2))
    K = np.zeros((len(I), 3))
    gl_x, gl_w = _GL3  # Gauss-Legendre on [-1, 1]
    Q_inf = float(tab.Q[-1])
    Gam_max = float(tab.Gam[-1])
    _all_pairs(P, I, J, dist, k_range, tab.FG, tab.Q, tab.Gam, tab.dr, tab.r_max, tab.FG_inf,
               Q_inf, Gam_max, tab.Fg_inf, phi is not None, psi is not None, h0, gl_x, gl_w,
               W, K)
    area = mesh.areas

    def assemble(vals, sign, sel):
        rows = np.concatenate([I[sel], J[sel]])
        cols = np.concatenate([J[sel], I[sel]])
        data = np.concatenate([vals[sel] / area[I[sel]], sign * vals[sel] / area[J[sel]]])
        return sp.csr_matrix((data, (rows, cols)), shape=(m, m))

    Wx = Wy = Kxx = Kxy = Kyy = None
    if phi is not None:
        sw = dist < phi_range
        Wx, Wy = assemble(W[:, 0], -1.0, sw), assemble(W[:, 1], -1.0, sw)
    if psi is not None:
        sk = dist < k_range
        Kxx, Kxy, Kyy = (assemble(K[:, 0], 1.0, sk), assemble(K[:, 1], 1.0, sk),
                         assemble(K[:, 2], 1.0, sk))
    Ix = Iy = None
    if walls and phi is not None:
        Ix, Iy = _image_operators(mesh, tab, cutoff, rad, h0, gl_x, gl_w, Q_inf, Gam_max)
    return PairOperators(Wx, Wy, Kxx, Kxy, Kyy, Ix, Iy, len(I), time.perf_counter() - t0)


def _merged_intervals(lo: np.ndarray, hi: np.ndarray, gap: float):
    """The union of the intervals [lo_k, hi_k] [m] as sorted disjoint intervals (arrays of
    their starts and ends); intervals less than ``gap`` apart are joined."""
    order = np.argsort(lo, kind="stable")
    out_lo, out_hi = [float(lo[order[0]])], [float(hi[order[0]])]
    for a, b in zip(lo[order[1:]], hi[order[1:]]):
        if a <= out_hi[-1] + gap:
            out_hi[-1] = max(out_hi[-1], float(b))
        else:
            out_lo.append(float(a))
            out_hi.append(float(b))
    return np.array(out_lo), np.array(out_hi)


def _image_operators(mesh, tab, cutoff, rad, h0, gl_x, gl_w, Q_inf, Gam_max):
    """Repulsion of every cell by the mirror images (across straight wall pieces) of the
    cells near that wall."""
    from scipy.spatial import cKDTree

    import shapely

    m = mesh.n_triangles
    P = _tri_pts(mesh)
    c = mesh.centroids
    walls = mesh.wall_edges()
    if len(walls) == 0:
        z = sp.csr_matrix((m, m))
        return z, z
    # straight wall pieces: merge collinear wall edges into lines (origin, unit normal)
    e = mesh.edges[walls]
    n = mesh.edge_normals[walls]
    p0 = mesh.points[e[:, 0]]
    off = np.einsum("ij,ij->i", p0, n)
    key = np.round(np.column_stack([n, off]), 9)
    lines, inv = np.unique(key, axis=0, return_inverse=True)
    inv = inv.ravel()
    tree = cKDTree(c)
    region = None
    if mesh.room is not None:
        region = mesh.room.walkable
        shapely.prepare(region)
    rows, cols, vx, vy = [], [], [], []
    for li in range(len(lines)):
        sel = walls[inv == li]
        nx_, ny_, offset = lines[li]
        # cells within reach of this wall piece (its edges)
        mids = mesh.edge_midpoints[sel]
        lens = mesh.edge_lengths[sel]
        near = set()
        for mp, L in zip(mids, lens):
            near.update(tree.query_ball_point(mp, cutoff + 0.5 * L + 2 * rad.max()))
        near = np.array(sorted(near), dtype=np.int64)
        if len(near) == 0:
            continue
        dist = offset - (c[near] @ np.array([nx_, ny_]))  # distance inside the wall
        near = near[dist < cutoff + 2 * rad[near]]
        if len(near) == 0:
            continue
        # mirror images of the near cells across the line x.n = offset
        Pn = P[near]
        s = (Pn @ np.array([nx_, ny_])) - offset
        img = Pn - 2.0 * s[..., None] * np.array([nx_, ny_])
        img = np.ascontiguousarray(img[:, ::-1])  # reflection flips the orientation
        cimg = img.mean(axis=1)
        if region is not None:
            outside = ~shapely.contains_xy(region, cimg[:, 0], cimg[:, 1])
            if not outside.any():
                continue
        else:
            outside = np.ones(len(near), bool)
        itree = cKDTree(cimg)
        # an image acts only across the wall itself, not across an exit on the same line:
        # the segment from the cell to the image must cross the line on a wall edge, i.e.
        # (all on one line) within 1e-6 m of one of the edges' intervals along it
        nvec = np.array([nx_, ny_])
        tvec = np.array([-ny_, nx_])
        ends = mesh.points[mesh.edges[sel]] @ tvec  # (k, 2) edge ends along the line
        lo, hi = _merged_intervals(ends.min(axis=1), ends.max(axis=1), 2e-6)
        # every (cell near[a], image b) within reach, then those whose segment crosses the
        # wall on one of the intervals (vectorised: one tree query over all of them)
        found = itree.query_ball_point(c[near], cutoff + rad[near] + 2 * rad.max())
        counts = np.fromiter((len(f) for f in found), np.int64, len(found))
        if counts.sum() == 0:
            continue
        A = np.repeat(np.arange(len(near)), counts)
        Bi = np.concatenate([np.asarray(f, np.int64) for f in found if len(f)])
        ok = outside[Bi]
        A, Bi = A[ok], Bi[ok]
        ci = c[near[A]]
        di = offset - ci @ nvec
        dj = cimg[Bi] @ nvec - offset
        cross = ci + (cimg[Bi] - ci) * (di / np.maximum(di + dj, 1e-300))[:, None]
        # (a cell beyond the line from its image's side has di + dj <= 0: no crossing, and
        # the point is then far off the line)
        along = cross @ tvec
        k_ = np.searchsorted(lo, along + 1e-6, side="right") - 1
        ok = ((np.abs(cross @ nvec - offset) <= 1e-6) & (k_ >= 0)
              & (along <= hi[np.maximum(k_, 0)] + 1e-6))
        A, Bi = A[ok], Bi[ok]
        if len(A) == 0:
            continue
        W = np.empty((len(A), 2))
        _image_pairs(P, img, near, A, Bi, tab.FG, tab.Q, tab.Gam, tab.dr, tab.r_max,
                     tab.FG_inf, Q_inf, Gam_max, tab.Fg_inf, h0, gl_x, gl_w, W)
        i = near[A]
        rows.append(i)
        cols.append(near[Bi])
        vx.append(W[:, 0] / mesh.areas[i])
        vy.append(W[:, 1] / mesh.areas[i])
    if rows:
        rows, cols = np.concatenate(rows), np.concatenate(cols)
        vx, vy = np.concatenate(vx), np.concatenate(vy)
    Ix = sp.csr_matrix((vx, (rows, cols)), shape=(m, m))
    Iy = sp.csr_matrix((vy, (rows, cols)), shape=(m, m))
    return Ix, Iy


class LongRangeOperator:
    """Long-range (weak-interaction) convolutions by FFT on a background grid.

    Cell masses are deposited on a Cartesian grid (cloud-in-cell, bilinear weights),
    convolved with the kernel on a zero-padded grid (linear, not periodic, convolution),
    and read back with the same weights, so the discrete operator is the adjoint-consistent
    ``B^T (K * (B rho))``: for an odd vector kernel the total force vanishes and for an
    even tensor kernel the friction conserves momentum, to FFT round-off.
    """

    def __init__(self, mesh: TriMesh, kernel, spacing: float | None = None) -> None:
        from scipy import fft

        self.mesh = mesh
        self.kernel = kernel
        h = spacing or max(0.25, 0.8 * mesh.h)
        x0, y0, x1, y1 = mesh.bounds
        nx = int(np.ceil((x1 - x0) / h)) + 2
        ny = int(np.ceil((y1 - y0) / h)) + 2
        self.h, self.x0, self.y0, self.nx, self.ny = h, x0 - 0.5 * h, y0 - 0.5 * h, nx, ny
        # bilinear deposit/interpolation weights of the cell centroids (sparse, m x (nx ny))
        c = mesh.centroids
        fx = (c[:, 0] - self.x0) / h
        fy = (c[:, 1] - self.y0) / h
        i0 = np.clip(np.floor(fx).astype(np.int64), 0, nx - 2)
        j0 = np.clip(np.floor(fy).astype(np.int64), 0, ny - 2)
        tx = fx - i0
        ty = fy - j0
        rows = np.repeat(np.arange(mesh.n_triangles), 4)
        cols = np.stack([i0 * ny + j0, (i0 + 1) * ny + j0, i0 * ny + j0 + 1,
                         (i0 + 1) * ny + j0 + 1], axis=1).ravel()
        vals = np.stack([(1 - tx) * (1 - ty), tx * (1 - ty), (1 - tx) * ty, tx * ty],
                        axis=1).ravel()
        self.B = sp.csr_matrix((vals, (rows, cols)), shape=(mesh.n_triangles, nx * ny))
        self.BT = self.B.T.tocsr()
        # kernel on the padded grid of offsets
        PX, PY = 2 * nx, 2 * ny
        ox = np.fft.fftfreq(PX, d=1.0 / PX) * h
        oy = np.fft.fftfreq(PY, d=1.0 / PY) * h
        OX, OY = np.meshgrid(ox, oy, indexing="ij")
        R = np.hypot(OX, OY)
        with np.errstate(invalid="ignore", divide="ignore"):
            ux = np.where(R > 0, OX / R, 0.0)
            uy = np.where(R > 0, OY / R, 0.0)
        k = kernel(R) * h * h  # times the grid cell area
        self._fft = fft
        self.shape = (PX, PY)
        self.Kx = fft.rfft2(k * ux)
        self.Ky = fft.rfft2(k * uy)
        # friction tensor psi t t^T, t = (-uy, ux)
        self.Txx = fft.rfft2(k * uy * uy)
        self.Txy = fft.rfft2(-k * ux * uy)
        self.Tyy = fft.rfft2(k * ux * ux)

    def _grid(self, q: np.ndarray) -> np.ndarray:
        g = np.zeros(self.shape)
        g[: self.nx, : self.ny] = ((self.BT @ (q * self.mesh.areas)).reshape(self.nx, self.ny)
                                   / (self.h * self.h))
        return g

    def _conv(self, G_hat, f_hat) -> np.ndarray:
        return self._fft.irfft2(G_hat * f_hat, s=self.shape)[: self.nx, : self.ny].ravel()

    def repulsion(self, rho: np.ndarray) -> np.ndarray:
        """(m, 2) rho_i (phi r_hat * rho)(x_i) with odd kernel: net force zero."""
        r_hat = self._fft.rfft2(self._grid(rho))
        fx = self.B @ self._conv(self.Kx, r_hat)
        fy = self.B @ self._conv(self.Ky, r_hat)
        return np.column_stack([rho * fx, rho * fy])

    def friction(self, rho: np.ndarray, mom: np.ndarray) -> np.ndarray:
        """(m, 2) rho_i [(psi t t^T * m)(x_i) - (psi t t^T * rho)(x_i) u_i]."""
        fft = self._fft
        r_hat = fft.rfft2(self._grid(rho))
        mx_hat = fft.rfft2(self._grid(mom[:, 0]))
        my_hat = fft.rfft2(self._grid(mom[:, 1]))
        B = self.B
        axx = B @ self._conv(self.Txx, r_hat)
        axy = B @ self._conv(self.Txy, r_hat)
        ayy = B @ self._conv(self.Tyy, r_hat)
        gx = B @ (self._conv(self.Txx, mx_hat) + self._conv(self.Txy, my_hat))
        gy = B @ (self._conv(self.Txy, mx_hat) + self._conv(self.Tyy, my_hat))
        mx, my = mom[:, 0], mom[:, 1]
        fx = rho * gx - (axx * mx + axy * my)
        fy = rho * gy - (axy * mx + ayy * my)
        return np.column_stack([fx, fy])
