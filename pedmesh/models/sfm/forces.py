"""The pair force of the social force model, one definition for the pairs, the walls, the
pairs across a building's stair edges and the calibration."""

from __future__ import annotations

import math

import numba as nb

__all__ = ["pair_force"]


@nb.njit(cache=True, inline="always")
def pair_force(dx, dy, d, dvx, dvy, rij, A, invB, k, kappa, sij):
    """Force [N] on pedestrian i from j: ``dx, dy`` = x_i - x_j at distance ``d`` > 0 and
    ``dvx, dvy`` = v_j - v_i. The social repulsion A exp((s_ij - d)/B) and the body force
    k (r_ij - d)_+ along n_ij, and the sliding friction kappa (r_ij - d)_+ <v_j - v_i, t_ij>
    t_ij with t_ij = (-n_y, n_x). ``rij`` is the sum of the body radii [m], ``sij`` that of
    the social radii [m] (the space the two keep, :func:`social_radii`; ``sij = rij`` in the
    paper's model). The one definition used for pairs, walls (a resting partner at the
    contact point) and the calibration."""
    nx_ = dx / d
    ny_ = dy / d
    ov = rij - d
    f = A * math.exp((sij - d) * invB)
    fx = f * nx_
    fy = f * ny_
    if ov > 0.0:
        fx += k * ov * nx_
        fy += k * ov * ny_
        tx = -ny_
        ty = nx_
        ft = kappa * ov * (dvx * tx + dvy * ty)
        fx += ft * tx
        fy += ft * ty
    return fx, fy
