r"""The density the social force model's people see near an exit, for the continuum's speed
law (``eos`` under the ``validated`` preset: the parameter ``exit_kernel``).

A pedestrian of the social force model reads its desired speed at its kernel density, the
Gaussian sum ``sum_j exp(-|x_i - x_j|^2 / R^2) / (pi R^2)`` over the people around it
(``R`` = 0.7 m). Beyond an exit there is nobody: within about a metre of a door the kernel
density is lower than the crowd's density by the kernel's mass beyond the exit, and the
people in the door want to walk faster than the crowd behind them. The continuum's speed
law is read at the local density and misses that; with ``exit_kernel`` = R it is read at
``rho (1 - w(x))``, ``w`` the mass of the normalised kernel beyond the exits,

.. math::  w(x) = \sum_{\text{exit edges}} \tfrac12 \operatorname{erfc}(s / R)
           \cdot \tfrac12 \left[\operatorname{erf}((L - t) / R)
           + \operatorname{erf}(t / R)\right]

for an edge of length ``L``, ``s`` the distance of ``x`` from the edge's line on the
walkable side and ``t`` its coordinate along the edge (the half-strip beyond the edge:
exact for a straight exit). Walls are left alone: at a wall the social force model's
people also see nobody beyond it, but they are pushed off it by the wall force, which the
continuum's walls (mirror states) do not have either.

With the social force model's density cone (``density_cone`` = p: a neighbour at angle
``theta`` from one's heading counts ``norm max(0, cos theta)^p`` times) the people near an
exit look through it, and the mass beyond an infinite straight exit at a distance ``s`` of
someone heading out is

.. math::  w_p(s) = \frac{\mathrm{norm}_p}{2 \pi} \int_{-\pi/2}^{\pi/2} \cos^p\theta\,
           e^{-s^2 / (R^2 \cos^2\theta)} \, d\theta

(1 on the exit line: they see nobody ahead; the isotropic kernel's is 1/2), times the same
factor along the edge as above (the isotropic kernel's, an approximation near the edge's
ends); the eos parameter ``exit_cone`` = p.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import erf, erfc

from ...speed import cone_norm

__all__ = ["exit_kernel_mass", "interior_points", "cone_mass_beyond"]


def cone_mass_beyond(s: np.ndarray, R: float, p: float) -> np.ndarray:
    """``w_p(s)`` of the module docstring: the mass of the cone-weighted kernel (exponent
    ``p`` > 0, width ``R`` [m]) beyond a straight line at distance(s) ``s`` [m] >= 0 ahead
    of the viewer (Gauss-Legendre quadrature in the angle, 64 nodes)."""
    s = np.maximum(np.asarray(s, float), 0.0)
    x, wq = np.polynomial.legendre.leggauss(64)
    th = 0.5 * math.pi * x  # (-pi/2, pi/2)
    c = np.cos(th)
    f = c ** p * np.exp(-(s[..., None] / R) ** 2 / (c * c))
    return cone_norm(p) / (2.0 * math.pi) * (0.5 * math.pi) * (f * wq).sum(axis=-1)


def interior_points(mesh) -> np.ndarray:
    """(m, 3, 2) the interior quadrature points of each cell, as the solver places them."""
    from .reconstruction import INTERIOR_BARY

    corners = mesh.points[:, :2][mesh.triangles]
    return np.einsum("pb,mbd->mpd", INTERIOR_BARY, corners)


def exit_kernel_mass(mesh, points: np.ndarray, cells: np.ndarray, R: float,
                     cone: float = 0.0) -> np.ndarray:
    """The mass ``w`` (k,) of the normalised Gaussian kernel of width ``R`` [m] beyond the
    exit edges of ``mesh`` at ``points`` (k, 2) [m] in the cells ``cells`` (k,) (see the
    module docstring; ``cone`` > 0: weighted by the density cone of that exponent, seen by
    people heading out). On a building's surface an exit edge counts only for the cells of
    its own piece (the pieces lie side by side in one plane)."""
    from ...mesh.triangle_mesh import BoundaryKind

    pts = np.asarray(points, float).reshape(-1, 2)
    w = np.zeros(len(pts))
    if not R > 0:
        return w
    exits = np.flatnonzero(mesh.edge_kind == BoundaryKind.EXIT)
    if not len(exits):
        return w
    P = mesh.points[:, :2]
    ed = mesh.edges[exits]
    own = mesh.edge_triangles[exits, 0]
    piece = getattr(mesh, "piece", None)
    cell_piece = None if piece is None else np.asarray(piece)[np.asarray(cells)]
    reach = 4.0 * R  # erfc(4) = 1.5e-8
    for k in range(len(exits)):
        a, b = P[ed[k, 0]], P[ed[k, 1]]
        L = math.hypot(*(b - a))
        if L <= 0:
            continue
        t_ = (b - a) / L
        nrm = np.array([t_[1], -t_[0]])
        if np.dot(P[mesh.triangles[own[k]]].mean(0) - a, nrm) < 0:
            nrm = -nrm  # towards the walkable side
        d = pts - a
        s = d @ nrm
        t = d @ t_
        near = (s > -1e-9) & (s < reach) & (t > -reach) & (t < L + reach)
        if cell_piece is not None:
            near &= cell_piece == piece[own[k]]
        if not near.any():
            continue
        sn, tn = np.maximum(s[near], 0.0), t[near]
        across = erfc(sn / R) if cone <= 0 else 2.0 * cone_mass_beyond(sn, R, cone)
        w[near] += 0.25 * across * (erf((L - tn) / R) + erf(tn / R))
    return np.clip(w, 0.0, 1.0)
