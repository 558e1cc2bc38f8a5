"""The pair force of the social force model, one definition for the pairs, the walls, the
pairs across a building's stair edges and the calibration; and a pair's two accelerations
with the field of vision, one definition for the pairs in the cell list and those across
a building's stair edges."""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from ...speed import cone_norm

__all__ = ["pair_force", "pair_terms", "cone_norm", "cone_weights", "unit_direction",
           "unit_rows", "NO_CONE", "UNIT_SLACK"]

#: the kernel density's (exponent, normalisation) without a cone: every neighbour counts
#: fully (the paper's eq3)
NO_CONE = np.array([0.0, 1.0])


#: how far from 1 a direction's squared length may be and still be read as a unit vector:
#: the route's directions are unit to round-off, except on a building's stairs, where they
#: carry the stair's speed factor (0.5 up, 0.6 down by default) as their length
UNIT_SLACK = 1e-9


@nb.njit(cache=True, nogil=True, inline="always")
def unit_direction(ex, ey):
    """``(ex, ey)`` as a unit vector: the desired direction without the length a stair's
    speed factor gives it (0 stays 0; a unit vector to round-off is returned as it is, so
    runs on rooms keep every bit). The density cone and the field of vision take the
    cosine of an angle from it (:func:`cone_weights`, :func:`pair_terms`), so the kernels
    keep the directions they read unit (:func:`~pedmesh.models.sfm.kernels.accel`)."""
    e2 = ex * ex + ey * ey
    if e2 > 0.0 and abs(e2 - 1.0) > UNIT_SLACK:
        s = 1.0 / math.sqrt(e2)
        return ex * s, ey * s
    return ex, ey


@nb.njit(cache=True, nogil=True)
def unit_rows(e):
    """Directions ``e`` (k, 2) as the density cone reads them: a copy with each row through
    :func:`unit_direction`."""
    out = np.empty_like(e)
    for i in range(e.shape[0]):
        out[i, 0], out[i, 1] = unit_direction(e[i, 0], e[i, 1])
    return out


@nb.njit(cache=True, nogil=True, inline="always")
def _cone(c, p, norm):
    if c <= 0.0:
        return 0.0
    if p == 2.0:
        return norm * c * c
    if p == 1.0:
        return norm * c
    return norm * c ** p


@nb.njit(cache=True, nogil=True, inline="always")
def cone_weights(dx, dy, d2, cone, eix, eiy, ejx, ejy):
    """The weights of a pair's kernel term in i's and j's densities: ``dx, dy`` = x_i -
    x_j at squared distance ``d2``, ``cone`` = (p, norm) of the density cone. With p > 0
    one's neighbour counts ``norm max(0, cos)^p`` times, cos the cosine between one's
    desired direction (``eix, eiy``; ``ejx, ejy``) and the neighbour: the people ahead
    count, those behind do not (a pedestrian adapts the speed to the space in front);
    with p = 0 both are 1 (the isotropic kernel, bit for bit). The directions must be unit
    vectors: the kernels keep a stair's speed factor out of them (:func:`unit_direction`)."""
    p = cone[0]
    if p <= 0.0:
        return 1.0, 1.0
    if d2 <= 0.0:  # (on top of each other: the mean weight)
        return 1.0, 1.0
    d = math.sqrt(d2)
    return (_cone(-(dx * eix + dy * eiy) / d, p, cone[1]),
            _cone((dx * ejx + dy * ejy) / d, p, cone[1]))


@nb.njit(cache=True, nogil=True, inline="always")
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


@nb.njit(cache=True, nogil=True, inline="always")
def pair_terms(dx, dy, d, dvx, dvy, rij, sij, A, invB, k, kappa, inv_m, lam, eix, eiy, ejx,
               ejy):
    """The accelerations [m/s^2] a pair gives: ``(aix, aiy, ajx, ajy)``, i's to add and j's
    to subtract (:func:`pair_force` over the mass, ``inv_m`` = 1/m). With a field of vision
    ``lam`` < 1 the social repulsion on each is weighted by lam + (1 - lam) (1 + cos)/2,
    cos the cosine between one's direction (``eix, eiy``; ``ejx, ejy``) and the other
    (so the two differ); with ``lam`` = 1 both are the pair force (Newton's third law)."""
    if lam < 1.0:
        fx, fy = pair_force(dx, dy, d, dvx, dvy, rij, 0.0, invB, k, kappa, sij)
        fs = A * math.exp((sij - d) * invB) / d
        ci = -(dx * eix + dy * eiy) / d
        cj = (dx * ejx + dy * ejy) / d
        wi = lam + (1.0 - lam) * 0.5 * (1.0 + ci)
        wj = lam + (1.0 - lam) * 0.5 * (1.0 + cj)
        return ((fx + wi * fs * dx) * inv_m, (fy + wi * fs * dy) * inv_m,
                (fx + wj * fs * dx) * inv_m, (fy + wj * fs * dy) * inv_m)
    fx, fy = pair_force(dx, dy, d, dvx, dvy, rij, A, invB, k, kappa, sij)
    fx *= inv_m
    fy *= inv_m
    return fx, fy, fx, fy
