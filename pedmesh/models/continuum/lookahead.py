r"""The density ahead: the continuum's speed law read where the social force model's people
read theirs (``eos`` with ``lookahead`` = p > 0).

A pedestrian of the ``validated`` social force model reads its desired speed at its kernel
density with the density cone: a neighbour at angle ``theta`` from one's desired direction
``e`` counts ``norm_p max(0, cos theta)^p`` times (``norm_p`` such that a uniform crowd
reads its density), with the Gaussian ``exp(-d^2 / R^2) / (pi R^2)``. In a crowd that thins
towards an exit the people read the thinner crowd ahead of them and walk faster than the
local density's law says: a nonlocal speed law of the kind of Colombo, Garavello &
Lecureux-Mercier (2012), ``U_e(rho * eta)`` with a kernel that looks ahead.

On the mesh, each cell ``i`` reads the cone-weighted average of the cell averages

.. math::  \bar\rho^{\,a}_i = \frac{\sum_j w_{ij} \bar\rho_j}{\sum_j w_{ij}}, \qquad
           w_{ij} = |T_j| \, e^{-d_{ij}^2 / R^2} \, c_p(\cos\theta_{ij}),

over the cells of its own piece within ``3 R`` (``d_ij`` between centroids, ``theta_ij``
between ``e_i`` and the direction to ``j``; ``c_p(c) = norm_p max(0, c)^p``, 1 for ``j = i``),
normalised by the weights inside the walkable area: walls act as mirrors, as in the
continuum's fluxes (the social force model's people are pushed off walls by the wall force
and do not read the wall as empty). What lies beyond an exit is empty: the model keeps its
``exit_kernel`` factor ``1 - w(x)`` (:mod:`~pedmesh.models.continuum.exit_kernel`) on top.
So the law is read at ``rho(x) (1 - w(x)) rho^a_i / rho_i``: in a uniform crowd exactly the
``exit_kernel`` read, and with ``p`` = 0 the isotropic kernel average.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from scipy.spatial import cKDTree

from ..._threads import ensure_tbb
from ...speed import cone_norm

ensure_tbb()  # (before numba's first parallel loop: pedmesh._threads)

__all__ = ["Lookahead"]


@nb.njit(cache=True, nogil=True, parallel=True)
def _ahead(indptr, idx, dx, dy, base, ex, ey, rho, p, norm, out):
    """out[i] = the cone-weighted, normalised average of ``rho`` ahead of cell i along
    (ex[i], ey[i]); dx, dy = x_j - x_i per stored pair."""
    m = len(indptr) - 1
    for i in nb.prange(m):
        num = 0.0
        den = 0.0
        exi, eyi = ex[i], ey[i]
        cone = p > 0.0 and (exi != 0.0 or eyi != 0.0)  # (no direction: isotropic)
        for k in range(indptr[i], indptr[i + 1]):
            j = idx[k]
            w = base[k]
            if cone and j != i:
                d = math.sqrt(dx[k] * dx[k] + dy[k] * dy[k])
                c = (exi * dx[k] + eyi * dy[k]) / d
                if c <= 0.0:
                    continue
                if p == 2.0:
                    w *= norm * c * c
                else:
                    w *= norm * c ** p
            num += w * rho[j]
            den += w
        out[i] = num / den if den > 0.0 else rho[i]


class Lookahead:
    """The cone-weighted kernel average of the density ahead of each cell of ``mesh`` (see the
    module docstring): kernel width ``R`` [m], cone exponent ``p`` >= 0."""

    def __init__(self, mesh, R: float, p: float) -> None:
        self.R, self.p = float(R), float(p)
        self.norm = cone_norm(self.p) if self.p > 0 else 1.0
        c = np.asarray(mesh.centroids, float)[:, :2]
        m = len(c)
        pairs = cKDTree(c).query_pairs(3.0 * self.R, output_type="ndarray")
        piece = getattr(mesh, "piece", None)
        if piece is not None:  # a building's pieces lie side by side in one plane
            piece = np.asarray(piece)
            pairs = pairs[piece[pairs[:, 0]] == piece[pairs[:, 1]]]
        rows = np.concatenate([pairs[:, 0], pairs[:, 1], np.arange(m)])
        cols = np.concatenate([pairs[:, 1], pairs[:, 0], np.arange(m)])
        order = np.argsort(rows, kind="stable")
        rows, cols = rows[order], cols[order]
        self.indptr = np.searchsorted(rows, np.arange(m + 1)).astype(np.int64)
        self.idx = cols.astype(np.int32)
        d = c[cols] - c[rows]
        self.dx = np.ascontiguousarray(d[:, 0])
        self.dy = np.ascontiguousarray(d[:, 1])
        areas = np.asarray(mesh.areas, float)
        self.base = areas[cols] * np.exp(-(self.dx ** 2 + self.dy ** 2) / self.R ** 2)
        self._out = np.empty(m)

    @property
    def pairs(self) -> int:
        """Stored (i, j) pairs, self pairs included."""
        return len(self.idx)

    def __call__(self, rho: np.ndarray, ex: np.ndarray, ey: np.ndarray) -> np.ndarray:
        """(m,) the density ahead [ped/m^2] of the cell averages ``rho`` (m,) with unit
        desired directions ``ex``, ``ey`` (m,) (zero: the isotropic average)."""
        _ahead(self.indptr, self.idx, self.dx, self.dy, self.base,
               np.ascontiguousarray(ex, dtype=float), np.ascontiguousarray(ey, dtype=float),
               np.ascontiguousarray(rho, dtype=float), self.p, self.norm, self._out)
        return self._out
