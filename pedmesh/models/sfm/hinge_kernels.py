"""Pairs across a building's stair edges (:mod:`pedmesh.models.sfm.building`).

In the atlas the two sides of a stair edge lie apart: a pedestrian at ``x_j`` on one side
is at ``x_j - s`` as seen from the other, with ``s`` the edge's shift. The pairs closer than
a cut-off across an edge are listed once per step (:func:`hinge_pairs`, from a cell list of
the positions) with the shift of each, and their forces and kernel densities are those of
:func:`pedmesh.models.sfm.kernels.pair_force` at the distance across the edge
(:func:`hinge_accel`, :func:`hinge_density`). A room has no such pairs, and nothing here
runs for it.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from .forces import cone_weights, pair_terms

__all__ = ["hinge_pairs", "hinge_accel", "hinge_density"]


@nb.njit(cache=True, nogil=True)
def _seg_dist2(px, py, ax, ay, bx, by):
    dx, dy = bx - ax, by - ay
    L2 = dx * dx + dy * dy
    s = ((px - ax) * dx + (py - ay) * dy) / L2 if L2 > 0 else 0.0
    s = min(max(s, 0.0), 1.0)
    qx, qy = ax + s * dx - px, ay + s * dy - py
    return qx * qx + qy * qy


@nb.njit(cache=True, nogil=True)
def hinge_pairs(x, n, tri, piece, hseg, hptr, hidx, hto, hshift, rc, cell_start, cell_order,
                cx0, cy0, cinv, cnx, cny, hi, hj, hs):
    """The pairs (i, j) closer than ``rc`` [m] across a stair edge, with i on the edge's
    side (its *from* piece) and j on ``hto[h]`` (each edge listed from one side only, so
    every pair once), into ``hi``, ``hj`` and their shifts ``hs`` (k, 2) [m] (x_i + hs is
    i as seen from j's side). ``hseg`` (h, 4): each edge's end points on the from side;
    ``hptr``, ``hidx``: the edges of each piece as their from piece (CSR by piece, each
    piece's in increasing order: the pairs in the order of going through all edges);
    ``piece`` (m,): the piece of each triangle, ``tri`` the pedestrians' triangles; the
    cell list (``cell_start``, ``cell_order`` on a grid at ``cx0``, ``cy0`` with cells of
    1/``cinv`` [m]) must hold the positions ``x``. Returns the number of pairs, -1 if the
    arrays are too small."""
    rc2 = rc * rc
    reach = int(rc * cinv) + 1
    cap = hi.shape[0]
    m = 0
    for i in range(n):
        pi_ = piece[tri[i]]
        for q in range(hptr[pi_], hptr[pi_ + 1]):
            h = hidx[q]
            if _seg_dist2(x[i, 0], x[i, 1], hseg[h, 0], hseg[h, 1], hseg[h, 2],
                          hseg[h, 3]) >= rc2:
                continue
            qx = x[i, 0] + hshift[h, 0]
            qy = x[i, 1] + hshift[h, 1]
            ci = int((qx - cx0) * cinv)
            cj = int((qy - cy0) * cinv)
            for ii in range(max(ci - reach, 0), min(ci + reach, cnx - 1) + 1):
                for jj in range(max(cj - reach, 0), min(cj + reach, cny - 1) + 1):
                    c = ii * cny + jj
                    for a in range(cell_start[c], cell_start[c + 1]):
                        j = cell_order[a]
                        if piece[tri[j]] != hto[h]:
                            continue
                        dx = qx - x[j, 0]
                        dy = qy - x[j, 1]
                        if dx * dx + dy * dy < rc2:
                            if m >= cap:
                                return -1
                            hi[m] = i
                            hj[m] = j
                            hs[m, 0] = hshift[h, 0]
                            hs[m, 1] = hshift[h, 1]
                            m += 1
    return m


@nb.njit(cache=True, nogil=True)
def hinge_density(x, nh, hi, hj, hs, rc_d, R, rho, e, cone):
    """Add the Gaussian kernel weights of the pairs across stair edges to ``rho`` (with the
    density cone ``cone`` of the directions ``e``,
    :func:`~pedmesh.models.sfm.forces.cone_weights`)."""
    w0 = 1.0 / (math.pi * R * R)
    invR2 = 1.0 / (R * R)
    rd2 = rc_d * rc_d
    for p in range(nh):
        i, j = hi[p], hj[p]
        dx = x[i, 0] + hs[p, 0] - x[j, 0]
        dy = x[i, 1] + hs[p, 1] - x[j, 1]
        d2 = dx * dx + dy * dy
        if d2 < rd2:
            w = w0 * math.exp(-d2 * invR2)
            wi, wj = cone_weights(dx, dy, d2, cone, e[i, 0], e[i, 1], e[j, 0], e[j, 1])
            rho[i] += w * wi
            rho[j] += w * wj


@nb.njit(cache=True, nogil=True)
def hinge_accel(x, v, nh, hi, hj, hs, rc_f, rc_d, rad, A, B, k, kappa, m, R, F, rho,
                with_density, rs, lam, e, cone):
    """Add the accelerations of the pairs across stair edges to ``F`` (and, with
    ``with_density``, their kernel weights to ``rho``), as
    :func:`~pedmesh.models.sfm.kernels.pair_accel_list` does for the other pairs (the same
    force, the field of vision ``lam`` weighting the social repulsion)."""
    invB = 1.0 / B
    inv_m = 1.0 / m
    rc_f2 = rc_f * rc_f
    if with_density:
        hinge_density(x, nh, hi, hj, hs, rc_d, R, rho, e, cone)
    for p in range(nh):
        i, j = hi[p], hj[p]
        dx = x[i, 0] + hs[p, 0] - x[j, 0]
        dy = x[i, 1] + hs[p, 1] - x[j, 1]
        d2 = dx * dx + dy * dy
        if not (d2 < rc_f2 and d2 > 0.0):
            continue
        aix, aiy, ajx, ajy = pair_terms(dx, dy, math.sqrt(d2), v[j, 0] - v[i, 0],
                                        v[j, 1] - v[i, 1], rad[i] + rad[j], rs[i] + rs[j],
                                        A, invB, k, kappa, inv_m, lam, e[i, 0], e[i, 1],
                                        e[j, 0], e[j, 1])
        F[i, 0] += aix
        F[i, 1] += aiy
        F[j, 0] -= ajx
        F[j, 1] -= ajy


def empty_pairs() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Empty hinge-pair arrays (a room's)."""
    return np.zeros(1, np.int64), np.zeros(1, np.int64), np.zeros((1, 2))
