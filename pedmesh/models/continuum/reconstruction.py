"""Third-order CWENO reconstruction on triangles (Dumbser-Boscheri-Semplice-Russo 2017).

For cell i with centroid x_i, area ``|T_i|`` and ``h_i = sqrt(|T_i|)``, in scaled coordinates
xi = (x - x_i)/h_i, a polynomial is ``p = qbar_i + sum_k a_k phi_k`` with the mean-free basis

    phi_1 = xi, phi_2 = eta, phi_3 = xi^2 - <xi^2>_i, phi_4 = xi eta - <xi eta>_i,
    phi_5 = eta^2 - <eta^2>_i,

so every reconstruction keeps the cell average exactly. Ingredients, all precomputed once
per mesh and stored as arrays:

* ``P_opt``: the least-squares quadratic on a central stencil (face neighbours and their
  face neighbours, plus all vertex neighbours if fewer than 8), interior cells only (so
  cells at walls and exits get one-sided stencils). Rows are exact cell averages of the
  basis (3-point rule). Too few cells or a condition number above 1e8 -> least-squares
  linear; fewer than two cells -> first order.
* up to six linear polynomials ``P_k`` on pairs of neighbours: the three face-neighbour
  pairs (central sectors) and, for every face neighbour, its two further face neighbours
  (forward sectors, which stay on one side of a front that cuts two face neighbours off);
  at the boundary also pairs of a face neighbour and one of its neighbours.
* the CWENO combination ``P_0 = (P_opt - sum d_k P_k)/d_0`` with d_0 = 0.8, nonlinear
  weights ``alpha_k = d_k/(beta_k + eps)^2`` from the Hu-Shu smoothness indicators and
  ``eps = (eps_hat * q_ref * h_i / 1 m)^2`` per variable (the h^2 scaling keeps the order
  at smooth extrema).

The reconstruction is component-wise in the conserved variables (the pressureless Jacobian
is not diagonalisable). Point values are produced at the 6 edge Gauss points (2 per edge)
and the 3 interior points (barycentric (2/3, 1/6, 1/6) and permutations, exact for
quadratics) of every cell.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np

from ..._arrays import readonly
from ...mesh.triangle_mesh import TriMesh
from .fv_kernels import BLOCK, FAST, NCHUNK, PAR, positivity_limit, zhang_shu_theta

__all__ = ["ReconstructionData", "build_reconstruction", "reconstruct", "GAUSS_S", "D0"]

#: Gauss points on an edge, as fractions from edges[e, 0] to edges[e, 1]
GAUSS_S = (0.5 - np.sqrt(3.0) / 6.0, 0.5 + np.sqrt(3.0) / 6.0)
#: CWENO linear weight of the central polynomial
D0 = 0.8
#: barycentric coordinates of the 3 interior quadrature points (weights 1/3)
INTERIOR_BARY = np.array([[2 / 3, 1 / 6, 1 / 6], [1 / 6, 2 / 3, 1 / 6], [1 / 6, 1 / 6, 2 / 3]])
MAX_STENCIL = 24
MAX_PAIRS = 6
COND_LIMIT = 1e8


@dataclass(frozen=True)
class ReconstructionData:
    """Precomputed per-mesh data of the CWENO3 reconstruction (see module docstring)."""

    h: np.ndarray  # (m,) sqrt(area) [m]
    stencil: np.ndarray  # (m, S) int32 cells of the central stencil, -1 padded (S = largest)
    R: np.ndarray  # (m, S, 5) least-squares operator of P_opt (row s: stencil cell s)
    opt_degree: np.ndarray  # (m,) 2, 1 or 0
    moments: np.ndarray  # (m, 3) <xi^2>, <xi eta>, <eta^2> over the cell itself
    pairs: np.ndarray  # (m, 6, 2) int32 cells of the linear sector polynomials, -1 unused
    pair_inv: np.ndarray  # (m, 6, 2, 2) inverse of the 2x2 centroid-offset matrices
    n_pairs: np.ndarray  # (m,)
    point_xy: np.ndarray  # (m, 9, 2) scaled coordinates (xi, eta) of the 6 edge + 3 interior points
    edge_pt: np.ndarray  # (k, 2, 2) physical Gauss points of every edge
    edge_cell_pt: np.ndarray  # (k, 2, 2) local point index (0..5) in the L and R cell

    def apply(self, qbar: np.ndarray, out_edge: np.ndarray, out_int: np.ndarray, *,
              order: int = 3, eps_hat: float = 0.1, qref: np.ndarray | None = None,
              slot: np.ndarray | None = None,
              positivity: tuple[float, float] | None = None,
              cact: np.ndarray | None = None) -> None:
        """Point values of the reconstruction of cell averages ``qbar`` (m, nv): at the 6
        edge Gauss points into ``out_edge`` and at the 3 interior points into ``out_int``
        (m, 3, nv); see :func:`reconstruct`. ``out_edge`` is (m, 6, nv), or any array whose
        rows ``slot[i, p]`` receive point p of cell i (the solver writes the edge states in
        the order its fluxes read them).

        ``positivity = (rho_eps, rho_cut)`` applies the Zhang-Shu limiter of
        :func:`~pedmesh.models.continuum.fv_kernels.positivity_limit` to the result (variable 0
        is the
        density); the 3-variable kernel does it while it writes the points. ``cact`` (m,):
        only these cells are reconstructed (default: all)."""
        qref = np.ones(qbar.shape[1]) if qref is None else qref
        m, nv = qbar.shape
        if cact is None:
            cact = np.ones(m, np.bool_)
        if slot is None:
            slot = np.arange(6 * m).reshape(m, 6)
        out_edge = out_edge.reshape(-1, nv)
        args = (qbar, order, self.stencil, self.R, self.opt_degree, self.moments, self.pairs,
                self.pair_inv, self.n_pairs, self.h, eps_hat, qref, self.point_xy, out_edge, slot,
                out_int, cact)
        if nv == 3:
            limit = positivity is not None
            rho_eps, rho_cut = positivity if limit else (0.0, 0.0)
            _reconstruct3(*args, limit, rho_eps, rho_cut)
            return
        if nv == 1:
            limit = positivity is not None
            rho_eps, rho_cut = positivity if limit else (0.0, 0.0)
            _reconstruct1(*args, limit, rho_eps, rho_cut)
            return
        reconstruct(*args)
        if positivity is not None:
            positivity_limit(out_edge, slot, out_int, qbar, *positivity, cact)


def _scaled_moments(pts_tri: np.ndarray, xc: np.ndarray, h) -> np.ndarray:
    """<xi>, <eta>, <xi^2>, <xi eta>, <eta^2> over triangles (m, 3, 2), each in the frame of
    its centroid ``xc`` (m, 2) and scale ``h`` (m, 1) (3-point rule: exact for quadratics)."""
    q = np.einsum("pb,...bd->...pd", INTERIOR_BARY, pts_tri)  # (..., 3, 2)
    xi = (q[..., 0] - xc[..., None, 0]) / h
    eta = (q[..., 1] - xc[..., None, 1]) / h
    return np.stack([xi.mean(-1), eta.mean(-1), (xi * xi).mean(-1), (xi * eta).mean(-1),
                     (eta * eta).mean(-1)], axis=-1)


@nb.njit(**FAST)
def _stencils(nbr, tri, vptr, vidx, out):
    """Central stencils: face neighbours, their face neighbours, and all vertex neighbours
    when that gives fewer than 8 cells (a rule that does not depend on cell numbering, so
    mirror-symmetric meshes get mirror-symmetric stencils)."""
    m = nbr.shape[0]
    S = out.shape[1]
    for i in range(m):
        n = 0
        for a in range(3):
            j = nbr[i, a]
            if j >= 0:
                out[i, n] = j
                n += 1
        n1 = n
        for a in range(n1):
            j = out[i, a]
            for b in range(3):
                k = nbr[j, b]
                if k < 0 or k == i:
                    continue
                dup = False
                for c in range(n):
                    if out[i, c] == k:
                        dup = True
                        break
                if not dup and n < S:
                    out[i, n] = k
                    n += 1
        if n < 8:
            for a in range(3):
                v = tri[i, a]
                for q in range(vptr[v], vptr[v + 1]):
                    k = vidx[q]
                    if k == i:
                        continue
                    dup = False
                    for c in range(n):
                        if out[i, c] == k:
                            dup = True
                            break
                    if not dup and n < S:
                        out[i, n] = k
                        n += 1


def _pinv_t(U, s, Vt):
    """The transposed pseudo-inverses (k, L, n) of matrices (k, L, n) of full rank given by
    their thin SVDs ``U s Vt`` (the condition was checked: no singular value is cut):
    ``(V s^-1 U^T)^T = U s^-1 V^T``, as numpy.linalg.pinv computes it from the same SVD."""
    return np.matmul(Vt.transpose(0, 2, 1), (1.0 / s)[..., None] * U.transpose(0, 2, 1)
                     ).transpose(0, 2, 1)


def _store_pairs(ci, ca, cb, both, cen, h, pairs, pair_inv, n_pairs, shift=None) -> None:
    """Of the candidate sector pairs (cells ``ca``, ``cb``) of cells ``ci``, the
    well-conditioned ones (scaled |det| > 1e-3 of the largest entry squared), the first
    MAX_PAIRS of each cell into ``pairs``, their inverse 2x2 matrices into ``pair_inv``, and
    their count into ``n_pairs``: in the order listed, or with ``both`` (bool per candidate)
    those of two face neighbours first, then by |det| from the largest (ties in the order
    listed). Each cell's candidates must come in one call. ``shift``: the mesh's
    ``cell_shift`` (a building's atlas), which moves the centroids into cell i's frame."""
    if shift is None:
        M = np.stack([(cen[ca] - cen[ci]) / h[ci, None], (cen[cb] - cen[ci]) / h[ci, None]],
                     axis=1)
    else:
        M = np.stack([(cen[ca] + shift(ci, ca) - cen[ci]) / h[ci, None],
                      (cen[cb] + shift(ci, cb) - cen[ci]) / h[ci, None]], axis=1)
    d = np.abs(np.linalg.det(M))
    good = d > 1e-3 * np.abs(M).reshape(len(ci), -1).max(axis=1) ** 2
    ci, ca, cb, d, M = ci[good], ca[good], cb[good], d[good], M[good]
    order = np.lexsort((ci,) if both is None else (-d, ~both[good], ci))  # (stable)
    ci, ca, cb, inv = ci[order], ca[order], cb[order], np.linalg.inv(M[order])
    rank = np.arange(len(ci)) - np.searchsorted(ci, ci)  # (place among the cell's pairs)
    keep = rank < MAX_PAIRS
    pairs[ci[keep], rank[keep]] = np.stack([ca[keep], cb[keep]], axis=1)
    pair_inv[ci[keep], rank[keep]] = inv[keep]
    np.add.at(n_pairs, ci[keep], 1)


def build_reconstruction(mesh: TriMesh) -> ReconstructionData:
    """Stencils, least-squares operators and point basis values of a mesh (once per mesh)."""
    cache = mesh._cache
    if "cweno3" in cache:
        return cache["cweno3"]
    m = mesh.n_triangles
    nbr = mesh.triangle_neighbors
    P = mesh.points[mesh.triangles]  # (m, 3, 2)
    cen = mesh.centroids
    h = np.sqrt(mesh.areas)
    ptr, idx = mesh.vertex_triangles
    own = _scaled_moments(P, cen, h[:, None])  # (m, 5): moments of each cell in its frame
    moments = np.ascontiguousarray(own[:, 2:5])
    stencil = np.full((m, MAX_STENCIL), -1, np.int64)
    _stencils(nbr, mesh.triangles, readonly(ptr), readonly(idx), stencil)
    size = (stencil >= 0).sum(axis=1)
    # least-squares rows: cell averages of the basis of cell i over stencil cells
    sj = np.where(stencil >= 0, stencil, 0)
    Pj = P[sj]  # (m, S, 3, 2)
    shift = getattr(mesh, "cell_shift", None)  # (a building's atlas: cells of other pieces
    if shift is not None:  # are moved into cell i's frame)
        Pj = Pj + shift(np.arange(m)[:, None], sj)[:, :, None, :]
    q = np.einsum("pb,msbd->mspd", INTERIOR_BARY, Pj)
    xi = (q[..., 0] - cen[:, None, None, 0]) / h[:, None, None]
    eta = (q[..., 1] - cen[:, None, None, 1]) / h[:, None, None]
    A = np.stack([xi.mean(-1), eta.mean(-1), (xi * xi).mean(-1) - own[:, None, 2],
                  (xi * eta).mean(-1) - own[:, None, 3], (eta * eta).mean(-1) - own[:, None, 4]],
                 axis=-1)  # (m, S, 5)
    A[stencil < 0] = 0.0
    R = np.zeros((m, MAX_STENCIL, 5))
    opt_degree = np.zeros(m, np.int64)
    for L in np.unique(size):
        rows = np.flatnonzero(size == L)
        if L < 2:
            continue
        AL = A[rows, :L]
        quad = np.zeros(len(rows), bool)
        if L >= 7:
            U, sv, Vt = np.linalg.svd(AL, full_matrices=False)
            quad = (sv[:, -1] > 0) & (sv[:, 0] < COND_LIMIT * sv[:, -1])
            if quad.any():
                R[rows[quad], :L, :] = _pinv_t(U[quad], sv[quad], Vt[quad])
                opt_degree[rows[quad]] = 2
        lin = ~quad
        if lin.any():
            U, sv, Vt = np.linalg.svd(AL[lin][:, :, :2], full_matrices=False)
            ok = (sv[:, -1] > 0) & (sv[:, 0] < COND_LIMIT * sv[:, -1])
            r = rows[lin][ok]
            if len(r):
                R[r, :L, :2] = _pinv_t(U[ok], sv[ok], Vt[ok])
                opt_degree[r] = 1
    # linear sector polynomials on pairs of neighbours
    pairs = np.full((m, MAX_PAIRS, 2), -1, np.int64)
    pair_inv = np.zeros((m, MAX_PAIRS, 2, 2))
    n_pairs = np.zeros(m, np.int64)
    cand_a, cand_b, cand_i = [], [], []
    full = np.all(nbr >= 0, axis=1)
    fi = np.flatnonzero(full)
    for u, w in ((0, 1), (1, 2), (2, 0)):  # central sectors
        cand_i.append(fi)
        cand_a.append(nbr[fi, u])
        cand_b.append(nbr[fi, w])
    for k in range(3):  # forward sectors: the far neighbours of each face neighbour
        a_ = nbr[fi, k]
        na = nbr[a_]  # (f, 3)
        other = na != fi[:, None]
        ok = (other.sum(axis=1) == 2) & np.all(na >= 0, axis=1)
        rows = np.flatnonzero(ok)
        two = na[rows][other[rows]].reshape(-1, 2)
        cand_i.append(fi[rows])
        cand_a.append(two[:, 0])
        cand_b.append(two[:, 1])
    _store_pairs(np.concatenate(cand_i), np.concatenate(cand_a), np.concatenate(cand_b),
                 None, cen, h, pairs, pair_inv, n_pairs, shift)
    # boundary cells: also pairs with second-ring cells; the pairs of two face neighbours
    # first, then the best conditioned
    cand = []  # (cell, a, b, both face neighbours)
    nbl = nbr.tolist()
    for i in np.flatnonzero(~full).tolist():
        n1 = [j for j in nbl[i] if j >= 0]
        cand += [(i, a, b, True) for ka, a in enumerate(n1) for b in n1[ka + 1:]]
        cand += [(i, a, b, False) for a in n1 for b in nbl[a]
                 if b >= 0 and b != i and b not in n1]
    if cand:
        c = np.array(cand, np.int64)
        _store_pairs(c[:, 0], c[:, 1], c[:, 2], c[:, 3].astype(bool), cen, h, pairs,
                     pair_inv, n_pairs, shift)
    # Gauss points on the edges and basis values at the 9 points of every cell
    e = mesh.edges
    p0 = mesh.points[e[:, 0]]
    p1 = mesh.points[e[:, 1]]
    edge_pt = np.stack([p0 + s * (p1 - p0) for s in GAUSS_S], axis=1)  # (k, 2, 2)
    t2e = mesh.triangle_edges
    cell_pts = np.zeros((m, 9, 2))
    cell_pts[:, :6] = edge_pt[t2e].reshape(m, 6, 2)
    if shift is not None:  # (an edge's points are in the frame of its first cell)
        e2t0 = mesh.edge_triangles[t2e, 0]  # (m, 3)
        cell_pts[:, :6] += np.repeat(shift(np.arange(m)[:, None], e2t0), 2, axis=1)
    cell_pts[:, 6:] = np.einsum("pb,mbd->mpd", INTERIOR_BARY, P)
    xi = (cell_pts[..., 0] - cen[:, None, 0]) / h[:, None]
    eta = (cell_pts[..., 1] - cen[:, None, 1]) / h[:, None]
    # local point index of each edge Gauss point in its two cells
    e2t = mesh.edge_triangles
    edge_cell_pt = np.full((len(e), 2, 2), -1, np.int64)
    for side in range(2):
        t = e2t[:, side]
        ok = t >= 0
        loc = np.argmax(t2e[t[ok]] == np.flatnonzero(ok)[:, None], axis=1)
        edge_cell_pt[ok, side, 0] = 2 * loc
        edge_cell_pt[ok, side, 1] = 2 * loc + 1
    # compact storage (the reconstruction streams these arrays once per stage)
    S = max(int(size.max()), 1)
    data = ReconstructionData(
        h=h, stencil=np.ascontiguousarray(stencil[:, :S], dtype=np.int32),
        R=np.ascontiguousarray(R[:, :S]), opt_degree=opt_degree, moments=moments,
        pairs=pairs.astype(np.int32), pair_inv=pair_inv, n_pairs=n_pairs,
        point_xy=np.ascontiguousarray(np.stack([xi, eta], axis=-1)), edge_pt=edge_pt,
        edge_cell_pt=edge_cell_pt,
    )
    cache["cweno3"] = data
    return data


@nb.njit(**FAST, inline="always")
def _beta2(a1, a2, a3, a4, a5, mxx, mxy, myy):
    return (a1 * a1 + a2 * a2 + (4 * a3 * a3 + a4 * a4) * mxx + (a4 * a4 + 4 * a5 * a5) * myy
            + 4 * a4 * (a3 + a5) * mxy + 4 * a3 * a3 + a4 * a4 + 4 * a5 * a5)


@nb.njit(**FAST, inline="always")
def _basis(point_xy, i, p, mxx, mxy, myy):
    """The mean-free basis xi, eta, xi^2 - <xi^2>, xi eta - <xi eta>, eta^2 - <eta^2> at
    point p of cell i."""
    x = point_xy[i, p, 0]
    y = point_xy[i, p, 1]
    return x, y, x * x - mxx, x * y - mxy, y * y - myy


@nb.njit(**FAST, inline="always")
def _same_rows(qbar, i, j):
    """Whether cells i and j hold the same values of every variable."""
    for v in range(qbar.shape[1]):
        if qbar[j, v] != qbar[i, v]:
            return False
    return True


@nb.njit(**FAST, inline="always")
def _flat(qbar, i, stencil, pairs, npair):
    """Whether every cell of the central stencil and the sector pairs of cell i holds the
    values of cell i (constant data, e.g. the empty parts of a room: first order is exact)."""
    for s in range(stencil.shape[1]):
        j = stencil[i, s]
        if j < 0:
            break
        if not _same_rows(qbar, i, j):
            return False
    for kp in range(npair):
        if not (_same_rows(qbar, i, pairs[i, kp, 0]) and _same_rows(qbar, i, pairs[i, kp, 1])):
            return False
    return True


@nb.njit(**PAR)
def reconstruct(qbar, order, stencil, R, opt_degree, moments, pairs, pair_inv, n_pairs, h,
                eps_hat, qref, point_xy, out_edge, slot, out_int, cact):
    """Point values of the reconstruction of cell averages ``qbar`` (m, nv): the value at
    edge Gauss point p (0..5) of cell i goes to row ``slot[i, p]`` of ``out_edge`` (k, nv),
    the values at the 3 interior points to ``out_int`` (m, 3, nv) (kept apart so that the
    sources read them without a copy).

    ``order`` 3: CWENO3; 2: CWENO with the linear least-squares polynomial of the central
    stencil (second-order option); 1: first order (constant). Per cell, the five polynomial
    coefficients of every variable are found first (the stencil sums in scalars), then the
    basis is evaluated once per point for all variables. Only the cells ``cact`` (m,) are
    reconstructed.
    """
    m, nv = qbar.shape
    # blocks of cells dealt out in turn to the threads (see _kernels.BLOCK), each chunk
    # with its own work arrays
    nblock = (m + BLOCK - 1) // BLOCK
    for c in nb.prange(NCHUNK):
        q0 = np.zeros(nv)
        coef = np.zeros((nv, 5))
        for b in range(c, nblock, NCHUNK):
            for i in range(b * BLOCK, min(m, (b + 1) * BLOCK)):
                if not cact[i]:
                    continue
                _reconstruct_cell(i, qbar, order, stencil, R, opt_degree, moments, pairs,
                                  pair_inv, n_pairs, h, eps_hat, qref, point_xy, out_edge, slot,
                                  out_int, q0, coef)


@nb.njit(**FAST)
def _reconstruct_cell(i, qbar, order, stencil, R, opt_degree, moments, pairs, pair_inv,
                      n_pairs, h, eps_hat, qref, point_xy, out_edge, slot, out_int, q0, coef):
    """:func:`reconstruct` of cell ``i`` (``q0`` (nv,) and ``coef`` (nv, 5) work arrays)."""
    nv = qbar.shape[1]
    S = stencil.shape[1]
    inv_d0 = 1.0 / D0
    deg = opt_degree[i] if order >= 2 else 0
    npair = n_pairs[i]
    for v in range(nv):
        q0[v] = qbar[i, v]
    if deg > 0 and npair > 0 and _flat(qbar, i, stencil, pairs, npair):
        deg = 0  # constant data around the cell (e.g. the empty parts of a room)
    if deg == 0 or npair == 0:
        # first order (or no sector polynomials to detect oscillations)
        for v in range(nv):
            for p in range(6):
                out_edge[slot[i, p], v] = q0[v]
            for p in range(3):
                out_int[i, p, v] = q0[v]
        return
    mxx = moments[i, 0]
    mxy = moments[i, 1]
    myy = moments[i, 2]
    dk = (1.0 - D0) / npair
    for v in range(nv):
        p0 = p1 = p2 = p3 = p4 = 0.0
        for s in range(S):
            j = stencil[i, s]
            if j < 0:
                break
            d = qbar[j, v] - q0[v]
            p0 += R[i, s, 0] * d
            p1 += R[i, s, 1] * d
            p2 += R[i, s, 2] * d
            p3 += R[i, s, 3] * d
            p4 += R[i, s, 4] * d
        if order == 2:
            p2 = p3 = p4 = 0.0
        eps = (eps_hat * qref[v] * h[i]) ** 2 + 1e-300
        w0 = _w(_beta2(p0, p1, p2, p3, p4, mxx, mxy, myy), eps, D0)
        t = w0
        # sum_k w_k lin_k (s.) and sum_k lin_k (u.) of the sector gradients
        sx = sy = ux = uy = 0.0
        for kp in range(npair):
            lx, ly, w = _sector(qbar, pairs[i, kp, 0], pairs[i, kp, 1], v, q0[v],
                                pair_inv[i, kp, 0, 0], pair_inv[i, kp, 0, 1],
                                pair_inv[i, kp, 1, 0], pair_inv[i, kp, 1, 1], eps, dk)
            t, sx, sy, ux, uy = t + w, sx + w * lx, sy + w * ly, ux + lx, uy + ly
        # p = w0 (P_opt - dk sum_k P_k) / d0 + sum_k w_k P_k, the weights normalised by t
        it = 1.0 / t
        f0 = w0 * it * inv_d0
        k0 = f0 * dk
        coef[v, 0] = f0 * p0 + sx * it - k0 * ux
        coef[v, 1] = f0 * p1 + sy * it - k0 * uy
        coef[v, 2] = f0 * p2
        coef[v, 3] = f0 * p3
        coef[v, 4] = f0 * p4
    for p in range(9):
        x, y, bxx, bxy, byy = _basis(point_xy, i, p, mxx, mxy, myy)
        for v in range(nv):
            val = (q0[v] + coef[v, 0] * x + coef[v, 1] * y + coef[v, 2] * bxx
                   + coef[v, 3] * bxy + coef[v, 4] * byy)
            if p < 6:
                out_edge[slot[i, p], v] = val
            else:
                out_int[i, p - 6, v] = val


@nb.njit(**FAST, inline="always")
def _w(b, eps, d):
    """CWENO nonlinear weight d / (beta + eps)^2."""
    x = b + eps
    return d / (x * x)


@nb.njit(**FAST, inline="always")
def _sector(qbar, pa, pb, v, q0, g00, g01, g10, g11, eps, dk):
    """Gradient (lx, ly) of the sector polynomial of variable v through cells pa, pb (inverse
    offset matrix g) and its unnormalised CWENO weight."""
    d1 = qbar[pa, v] - q0
    d2 = qbar[pb, v] - q0
    lx = g00 * d1 + g01 * d2
    ly = g10 * d1 + g11 * d2
    return lx, ly, _w(lx * lx + ly * ly, eps, dk)


@nb.njit(**PAR)
def _reconstruct3(qbar, order, stencil, R, opt_degree, moments, pairs, pair_inv, n_pairs, h,
                  eps_hat, qref, point_xy, out_edge, slot, out_int, cact, limit, rho_eps,
                  rho_cut):
    """:func:`reconstruct` for exactly 3 variables (density and momentum), each quantity held
    in scalars per variable: every stencil and sector row is read once for all three
    variables, and the work arrays of the general kernel are gone (about 10 % faster).
    With ``limit`` it applies
    :func:`~pedmesh.models.continuum.fv_kernels.positivity_limit` as it writes
    the points (first order where the density is below ``rho_cut``; the density's
    deviations scaled so that it is >= ``rho_eps`` at every point where the average
    allows)."""
    m = qbar.shape[0]
    # blocks of cells dealt out in turn to the threads (see _kernels.BLOCK)
    nblock = (m + BLOCK - 1) // BLOCK
    for c in nb.prange(NCHUNK):
        for b in range(c, nblock, NCHUNK):
            for i in range(b * BLOCK, min(m, (b + 1) * BLOCK)):
                if not cact[i]:
                    continue
                _reconstruct3_cell(i, qbar, order, stencil, R, opt_degree, moments, pairs,
                                   pair_inv, n_pairs, h, eps_hat, qref, point_xy, out_edge,
                                   slot, out_int, limit, rho_eps, rho_cut)


@nb.njit(**FAST, inline="always")
def _reconstruct3_cell(i, qbar, order, stencil, R, opt_degree, moments, pairs, pair_inv,
                       n_pairs, h, eps_hat, qref, point_xy, out_edge, slot, out_int, limit,
                       rho_eps, rho_cut):
    """:func:`_reconstruct3` of cell ``i``."""
    S = stencil.shape[1]
    inv_d0 = 1.0 / D0
    deg = opt_degree[i] if order >= 2 else 0
    npair = n_pairs[i]
    qa = qbar[i, 0]
    qb = qbar[i, 1]
    qc = qbar[i, 2]
    if limit and qa < rho_cut:
        deg = 0
    if deg > 0 and npair > 0:
        j = stencil[i, 0]  # (a quick look at one neighbour rejects most cells)
        if (qbar[j, 0] == qa and qbar[j, 1] == qb and qbar[j, 2] == qc
                and _flat(qbar, i, stencil, pairs, npair)):
            deg = 0
    if deg == 0 or npair == 0:
        for p in range(6):
            k = slot[i, p]
            out_edge[k, 0] = qa
            out_edge[k, 1] = qb
            out_edge[k, 2] = qc
        for p in range(3):
            out_int[i, p, 0] = qa
            out_int[i, p, 1] = qb
            out_int[i, p, 2] = qc
        return
    mxx = moments[i, 0]
    mxy = moments[i, 1]
    myy = moments[i, 2]
    dk = (1.0 - D0) / npair
    a0 = a1 = a2 = a3 = a4 = 0.0
    b0 = b1 = b2 = b3 = b4 = 0.0
    c0 = c1 = c2 = c3 = c4 = 0.0
    for s in range(S):
        j = stencil[i, s]
        if j < 0:
            break
        da = qbar[j, 0] - qa
        db = qbar[j, 1] - qb
        dc = qbar[j, 2] - qc
        r0 = R[i, s, 0]
        r1 = R[i, s, 1]
        r2 = R[i, s, 2]
        r3 = R[i, s, 3]
        r4 = R[i, s, 4]
        a0 += r0 * da
        a1 += r1 * da
        a2 += r2 * da
        a3 += r3 * da
        a4 += r4 * da
        b0 += r0 * db
        b1 += r1 * db
        b2 += r2 * db
        b3 += r3 * db
        b4 += r4 * db
        c0 += r0 * dc
        c1 += r1 * dc
        c2 += r2 * dc
        c3 += r3 * dc
        c4 += r4 * dc
    if order == 2:
        a2 = a3 = a4 = b2 = b3 = b4 = c2 = c3 = c4 = 0.0
    hh = h[i] * eps_hat
    ea = (hh * qref[0]) ** 2 + 1e-300
    eb = (hh * qref[1]) ** 2 + 1e-300
    ec = (hh * qref[2]) ** 2 + 1e-300
    wa0 = _w(_beta2(a0, a1, a2, a3, a4, mxx, mxy, myy), ea, D0)
    wb0 = _w(_beta2(b0, b1, b2, b3, b4, mxx, mxy, myy), eb, D0)
    wc0 = _w(_beta2(c0, c1, c2, c3, c4, mxx, mxy, myy), ec, D0)
    ta = wa0
    tb = wb0
    tc = wc0
    # per variable: sum_k w_k lin_k (s..) and sum_k lin_k (u..) of the sector gradients
    sax = say = sbx = sby = scx = scy = 0.0
    uax = uay = ubx = uby = ucx = ucy = 0.0
    for kp in range(npair):
        pa = pairs[i, kp, 0]
        pb = pairs[i, kp, 1]
        g00 = pair_inv[i, kp, 0, 0]
        g01 = pair_inv[i, kp, 0, 1]
        g10 = pair_inv[i, kp, 1, 0]
        g11 = pair_inv[i, kp, 1, 1]
        lx, ly, w = _sector(qbar, pa, pb, 0, qa, g00, g01, g10, g11, ea, dk)
        ta, sax, say, uax, uay = ta + w, sax + w * lx, say + w * ly, uax + lx, uay + ly
        lx, ly, w = _sector(qbar, pa, pb, 1, qb, g00, g01, g10, g11, eb, dk)
        tb, sbx, sby, ubx, uby = tb + w, sbx + w * lx, sby + w * ly, ubx + lx, uby + ly
        lx, ly, w = _sector(qbar, pa, pb, 2, qc, g00, g01, g10, g11, ec, dk)
        tc, scx, scy, ucx, ucy = tc + w, scx + w * lx, scy + w * ly, ucx + lx, ucy + ly
    # p = w0 (P_opt - dk sum_k P_k) / d0 + sum_k w_k P_k, the weights normalised by t
    ia = 1.0 / ta
    ib = 1.0 / tb
    ic = 1.0 / tc
    fa = wa0 * ia * inv_d0
    fb = wb0 * ib * inv_d0
    fc = wc0 * ic * inv_d0
    ka = fa * dk
    kb = fb * dk
    kc = fc * dk
    A0 = fa * a0 + sax * ia - ka * uax
    A1 = fa * a1 + say * ia - ka * uay
    B0 = fb * b0 + sbx * ib - kb * ubx
    B1 = fb * b1 + sby * ib - kb * uby
    C0 = fc * c0 + scx * ic - kc * ucx
    C1 = fc * c1 + scy * ic - kc * ucy
    A2 = fa * a2
    A3 = fa * a3
    A4 = fa * a4
    B2 = fb * b2
    B3 = fb * b3
    B4 = fb * b4
    C2 = fc * c2
    C3 = fc * c3
    C4 = fc * c4
    mn = qa  # the density's smallest point value
    for p in range(9):
        x, y, bxx, bxy, byy = _basis(point_xy, i, p, mxx, mxy, myy)
        va = qa + A0 * x + A1 * y + A2 * bxx + A3 * bxy + A4 * byy
        mn = min(mn, va)
        vb = qb + B0 * x + B1 * y + B2 * bxx + B3 * bxy + B4 * byy
        vc = qc + C0 * x + C1 * y + C2 * bxx + C3 * bxy + C4 * byy
        if p < 6:
            k = slot[i, p]
            out_edge[k, 0] = va
            out_edge[k, 1] = vb
            out_edge[k, 2] = vc
        else:
            out_int[i, p - 6, 0] = va
            out_int[i, p - 6, 1] = vb
            out_int[i, p - 6, 2] = vc
    if limit and mn < rho_eps:  # Zhang-Shu: scale the density's deviations (rare)
        _write_scaled_density(i, qa, zhang_shu_theta(qa, mn, rho_eps), A0, A1, A2, A3, A4,
                              point_xy, mxx, mxy, myy, out_edge, slot, out_int)


@nb.njit(**PAR)
def _reconstruct1(qbar, order, stencil, R, opt_degree, moments, pairs, pair_inv, n_pairs, h,
                  eps_hat, qref, point_xy, out_edge, slot, out_int, cact, limit, rho_eps,
                  rho_cut):
    """:func:`reconstruct` for one variable (the density of rdue) in scalars, with the
    positivity limiter applied as the points are written (as :func:`_reconstruct3`): about
    three times faster than the general kernel with its work arrays."""
    m = qbar.shape[0]
    nblock = (m + BLOCK - 1) // BLOCK
    for c in nb.prange(NCHUNK):
        for b in range(c, nblock, NCHUNK):
            for i in range(b * BLOCK, min(m, (b + 1) * BLOCK)):
                if cact[i]:
                    _reconstruct1_cell(i, qbar, order, stencil, R, opt_degree, moments, pairs,
                                       pair_inv, n_pairs, h, eps_hat, qref, point_xy,
                                       out_edge, slot, out_int, limit, rho_eps, rho_cut)


@nb.njit(**FAST, inline="always")
def _reconstruct1_cell(i, qbar, order, stencil, R, opt_degree, moments, pairs, pair_inv,
                       n_pairs, h, eps_hat, qref, point_xy, out_edge, slot, out_int, limit,
                       rho_eps, rho_cut):
    """:func:`_reconstruct1` of cell ``i``."""
    S = stencil.shape[1]
    deg = opt_degree[i] if order >= 2 else 0
    npair = n_pairs[i]
    qa = qbar[i, 0]
    if limit and qa < rho_cut:
        deg = 0
    if deg > 0 and npair > 0:
        if qbar[stencil[i, 0], 0] == qa and _flat(qbar, i, stencil, pairs, npair):
            deg = 0
    if deg == 0 or npair == 0:
        for p in range(6):
            out_edge[slot[i, p], 0] = qa
        for p in range(3):
            out_int[i, p, 0] = qa
        return
    mxx = moments[i, 0]
    mxy = moments[i, 1]
    myy = moments[i, 2]
    dk = (1.0 - D0) / npair
    a0 = a1 = a2 = a3 = a4 = 0.0
    for s in range(S):
        j = stencil[i, s]
        if j < 0:
            break
        da = qbar[j, 0] - qa
        a0 += R[i, s, 0] * da
        a1 += R[i, s, 1] * da
        a2 += R[i, s, 2] * da
        a3 += R[i, s, 3] * da
        a4 += R[i, s, 4] * da
    if order == 2:
        a2 = a3 = a4 = 0.0
    ea = (h[i] * eps_hat * qref[0]) ** 2 + 1e-300
    wa0 = _w(_beta2(a0, a1, a2, a3, a4, mxx, mxy, myy), ea, D0)
    ta = wa0
    sax = say = uax = uay = 0.0
    for kp in range(npair):
        lx, ly, w = _sector(qbar, pairs[i, kp, 0], pairs[i, kp, 1], 0, qa, pair_inv[i, kp, 0, 0],
                            pair_inv[i, kp, 0, 1], pair_inv[i, kp, 1, 0],
                            pair_inv[i, kp, 1, 1], ea, dk)
        ta, sax, say, uax, uay = ta + w, sax + w * lx, say + w * ly, uax + lx, uay + ly
    ia = 1.0 / ta
    fa = wa0 * ia * (1.0 / D0)
    ka = fa * dk
    A0 = fa * a0 + sax * ia - ka * uax
    A1 = fa * a1 + say * ia - ka * uay
    A2 = fa * a2
    A3 = fa * a3
    A4 = fa * a4
    mn = qa
    for p in range(9):
        x, y, bxx, bxy, byy = _basis(point_xy, i, p, mxx, mxy, myy)
        va = qa + A0 * x + A1 * y + A2 * bxx + A3 * bxy + A4 * byy
        mn = min(mn, va)
        if p < 6:
            out_edge[slot[i, p], 0] = va
        else:
            out_int[i, p - 6, 0] = va
    if limit and mn < rho_eps:  # Zhang-Shu: scale the deviations (rare)
        _write_scaled_density(i, qa, zhang_shu_theta(qa, mn, rho_eps), A0, A1, A2, A3, A4,
                              point_xy, mxx, mxy, myy, out_edge, slot, out_int)


@nb.njit(**FAST, inline="always")
def _write_scaled_density(i, qa, th, A0, A1, A2, A3, A4, point_xy, mxx, mxy, myy, out_edge,
                          slot, out_int):
    """Rewrite the density at cell ``i``'s 9 points with its deviations from the mean ``qa``
    scaled by ``th`` (the Zhang-Shu limiter of :func:`_reconstruct3` and
    :func:`_reconstruct1`)."""
    for p in range(9):
        x, y, bxx, bxy, byy = _basis(point_xy, i, p, mxx, mxy, myy)
        va = qa + th * (A0 * x + A1 * y + A2 * bxx + A3 * bxy + A4 * byy)
        if p < 6:
            out_edge[slot[i, p], 0] = va
        else:
            out_int[i, p - 6, 0] = va
