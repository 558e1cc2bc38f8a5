"""The social force model's kernels as they were before they ran on threads (serial
loops), kept as the reference that tests/sfm/test_sfm_parallel.py compares the
parallel kernels with, bit for bit. Not used by pedmesh itself.

All kernels work on flat arrays of the ``n`` active pedestrians (rows ``0..n-1``). Neighbours
come from a cell list (counting sort into square cells at least as large as the search
radius) searched over half of the 3x3 stencil, so every pair is visited once and its force
is added to one pedestrian and subtracted from the other: Newton's third law holds to
round-off, and the search is O(n).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from pedmesh.eikonal.direction import _inside_packed, _interpolate
from pedmesh.speed import shape
from pedmesh.models.sfm.crowding import crowd_factors
from pedmesh.models.sfm.forces import cone_weights, pair_force  # (unchanged by the threads)

EXIT_KIND = 3  # BoundaryKind.EXIT
#: barycentric margin of the division-free "still inside its triangle" test; anything
#: closer to an edge goes through the exact test and the walk, as before
INSIDE_MARGIN = 1e-9


# ------------------------------------------------------------------ cell list
@nb.njit(cache=False)
def build_cells(x, n, x0, y0, inv_cell, nx, ny, cell_start, cell_order):
    """Counting sort of pedestrians into cells; ``cell_start`` has nx*ny+1 entries."""
    nc = nx * ny
    for c in range(nc + 1):
        cell_start[c] = 0
    cell_of = np.empty(n, np.int64)
    for i in range(n):
        ci = int((x[i, 0] - x0) * inv_cell)
        cj = int((x[i, 1] - y0) * inv_cell)
        ci = min(max(ci, 0), nx - 1)
        cj = min(max(cj, 0), ny - 1)
        c = ci * ny + cj
        cell_of[i] = c
        cell_start[c + 1] += 1
    for c in range(nc):
        cell_start[c + 1] += cell_start[c]
    fill = cell_start[:nc].copy()
    for i in range(n):
        c = cell_of[i]
        cell_order[fill[c]] = i
        fill[c] += 1


# ------------------------------------------------------------------ pair forces + density
@nb.njit(cache=False)
def build_pairs(x, n, cell_start, cell_order, nx, ny, rc, rc_near, pi, pj, rho, rc_d, R,
                with_density, e, cone):
    """All pairs closer than ``rc``, each once (i from the lower cell), split in two groups:
    the *near* pairs (closer than ``rc_near``) fill ``pi``/``pj`` from the front, the *far*
    ones from the back. Returns ``(n_near, n_far)``, or ``(-1, -1)`` if ``pi``/``pj`` are
    too small. The cells must be at least ``rc`` wide.

    The pair forces only act within the near group (``rc_near`` = force cut-off + skin), so
    the far group needs the density kernel alone. With ``with_density`` the Gaussian kernel
    densities (cut-off ``rc_d``, self term included) at these positions go into ``rho`` on
    the way, and the far pairs are not stored (``n_far = 0``); each weighted by the density
    cone ``cone`` of the directions ``e`` (``cone_weights``).
    """
    rc2 = rc * rc
    rn2 = rc_near * rc_near
    rd2 = rc_d * rc_d
    w0 = 1.0 / (math.pi * R * R)
    invR2 = 1.0 / (R * R)
    if with_density:
        for i in range(n):
            rho[i] = w0
    cap = pi.shape[0]
    m_near = 0
    m_far = 0
    for ci in range(nx):
        for cj in range(ny):
            c = ci * ny + cj
            s0 = cell_start[c]
            s1 = cell_start[c + 1]
            if s0 == s1:
                continue
            for q in range(5):
                # q = 0: the cell itself (pairs a < b); then (+1,-1), (+1,0), (+1,+1), (0,+1)
                if q == 0:
                    ni = ci
                    nj = cj
                elif q < 4:
                    ni = ci + 1
                    nj = cj + q - 2
                else:
                    ni = ci
                    nj = cj + 1
                if ni >= nx or nj < 0 or nj >= ny:
                    continue
                c2 = ni * ny + nj
                t1 = cell_start[c2 + 1]
                for a in range(s0, s1):
                    i = cell_order[a]
                    xi = x[i, 0]
                    yi = x[i, 1]
                    rhoi = 0.0
                    t0 = a + 1 if q == 0 else cell_start[c2]
                    for b in range(t0, t1):
                        j = cell_order[b]
                        dx = xi - x[j, 0]
                        dy = yi - x[j, 1]
                        d2 = dx * dx + dy * dy
                        if with_density and d2 < rd2:
                            w = w0 * math.exp(-d2 * invR2)
                            wi, wj = cone_weights(dx, dy, d2, cone, e[i, 0], e[i, 1],
                                                  e[j, 0], e[j, 1])
                            rhoi += w * wi
                            rho[j] += w * wj
                        if d2 < rn2:
                            if m_near + m_far >= cap:
                                return -1, -1
                            pi[m_near] = i
                            pj[m_near] = j
                            m_near += 1
                        elif d2 < rc2 and not with_density:
                            if m_near + m_far >= cap:
                                return -1, -1
                            m_far += 1
                            pi[cap - m_far] = i
                            pj[cap - m_far] = j
                    if with_density:
                        rho[i] += rhoi
    return m_near, m_far


@nb.njit(cache=False)
def pair_accel_list(x, v, n, pi, pj, n_near, n_far, rc_f, rc_d, rad, A, B, k, kappa, m, R, F,
                    rho, with_density, rs, lam, e, cone):
    """Pair accelerations (into ``F``, zeroed first) and Gaussian kernel densities over a
    pair list from :func:`build_pairs` (a superset of the pairs in range).

    ``rho[i] = sum_j w(|x_i - x_j|)`` over all j including i itself (paper eq3, eq4),
    truncated at ``rc_d``; the pair force (social repulsion, body force and sliding
    friction, divided by m; r_ij = ``rad[i] + rad[j]``, the body radii [m]) is truncated at
    ``rc_f`` and must vanish for every far pair; ``rs``: the social radii [m]
    (:func:`social_radii`; ``rad`` itself in the paper's model)
    (``build_pairs`` guarantees it when its ``rc_near`` covers ``rc_f`` plus the motion
    since the list was built). Each pair's force is added to one pedestrian and subtracted
    from the other, so Newton's third law holds to round-off. With ``with_density`` false,
    ``rho`` is left as it is and only the near pairs are visited.
    """
    w0 = 1.0 / (math.pi * R * R)
    invR2 = 1.0 / (R * R)
    invB = 1.0 / B
    inv_m = 1.0 / m
    rc_f2 = rc_f * rc_f
    rc_d2 = rc_d * rc_d
    for i in range(n):
        F[i, 0] = 0.0
        F[i, 1] = 0.0
    if with_density:
        for i in range(n):
            rho[i] = w0
    for p in range(n_near):
        i = pi[p]
        j = pj[p]
        dx = x[i, 0] - x[j, 0]
        dy = x[i, 1] - x[j, 1]
        d2 = dx * dx + dy * dy
        if with_density and d2 < rc_d2:
            w = w0 * math.exp(-d2 * invR2)
            wi, wj = cone_weights(dx, dy, d2, cone, e[i, 0], e[i, 1], e[j, 0], e[j, 1])
            rho[i] += w * wi
            rho[j] += w * wj
        if d2 < rc_f2 and d2 > 0.0:
            rij = rad[i] + rad[j]
            sij = rs[i] + rs[j]
            if lam < 1.0:  # the social repulsion weighted by each one's field of vision
                d = math.sqrt(d2)
                fx, fy = pair_force(dx, dy, d, v[j, 0] - v[i, 0], v[j, 1] - v[i, 1],
                                    rij, 0.0, invB, k, kappa, sij)
                fs = A * math.exp((sij - d) * invB) / d
                # cos of the angle between one's direction and the other: -n_ij e_i, n_ij e_j
                ci = -(dx * e[i, 0] + dy * e[i, 1]) / d
                cj = (dx * e[j, 0] + dy * e[j, 1]) / d
                wi = lam + (1.0 - lam) * 0.5 * (1.0 + ci)
                wj = lam + (1.0 - lam) * 0.5 * (1.0 + cj)
                F[i, 0] += (fx + wi * fs * dx) * inv_m
                F[i, 1] += (fy + wi * fs * dy) * inv_m
                F[j, 0] -= (fx + wj * fs * dx) * inv_m
                F[j, 1] -= (fy + wj * fs * dy) * inv_m
                continue
            fx, fy = pair_force(dx, dy, math.sqrt(d2), v[j, 0] - v[i, 0], v[j, 1] - v[i, 1],
                                rij, A, invB, k, kappa, sij)
            fx *= inv_m
            fy *= inv_m
            F[i, 0] += fx
            F[i, 1] += fy
            F[j, 0] -= fx
            F[j, 1] -= fy
    if not with_density:
        return
    cap = pi.shape[0]
    for p in range(cap - n_far, cap):  # density only
        i = pi[p]
        j = pj[p]
        dx = x[i, 0] - x[j, 0]
        dy = x[i, 1] - x[j, 1]
        d2 = dx * dx + dy * dy
        if d2 < rc_d2:
            w = w0 * math.exp(-d2 * invR2)
            wi, wj = cone_weights(dx, dy, d2, cone, e[i, 0], e[i, 1], e[j, 0], e[j, 1])
            rho[i] += w * wi
            rho[j] += w * wj


# ------------------------------------------------------------------ space requirement
@nb.njit(cache=False)
def social_radii(n, rad, ue, shrink, t_space, crowd, cf, rs):
    """The social radii [m] of the speed-dependent space requirement into ``rs``:
    ``min(rad_i, rad_i - shrink + t_space ue_i / 2)`` with ``ue_i`` the desired speed [m/s]
    of pedestrian i. A person who wants to stand keeps a radius ``shrink`` [m] smaller than
    their body radius ``rad_i`` [m], and it grows by ``t_space`` / 2 [s] per m/s of desired
    speed back to ``rad_i`` (Seyfried et al. 2005: the length a walker needs grows linearly
    with speed, 0.36 m + 1.06 s x v). The desired speed, not the velocity: a radius that
    follows the velocity feeds a moving person's repulsion back into their motion, and a
    pressed crowd then never comes to rest (docs/validation/dense_crowds.md). The social
    repulsion acts from the sum of two social radii, the body (contact) forces from the sum
    of the body radii. With ``crowd``, the shrink is ``shrink cf[i]``: a queueing person
    (crowding factor 0) keeps their space, a crowding one (1) gives up ``shrink``."""
    h = 0.5 * t_space
    for i in range(n):
        s = rad[i] - (shrink * cf[i] if crowd else shrink) + h * ue[i]
        rs[i] = s if s < rad[i] else rad[i]


@nb.njit(cache=False, inline="always")
def crowd_density(rho, c, knee, stretch):
    """The density [ped/m^2] at which the speed law is read for a pedestrian with crowding
    factor ``c`` (:mod:`pedmesh.models.sfm.crowding`): above ``knee`` the law's dense part is
    stretched by ``1 + c (stretch - 1)``, so a crowding person (c = 1) still wants to move
    at densities where a queueing one (c = 0) stands."""
    if rho <= knee or c <= 0.0:
        return rho
    return knee + (rho - knee) / (1.0 + c * (stretch - 1.0))


@nb.njit(cache=False)
def desired_speeds(n, u0, law, rho, const_speed, crowd, cf, knee, stretch, ue):
    """Desired speeds [m/s] into ``ue``: ``u0[i] g(rho[i])`` (the density read through
    :func:`crowd_density` if ``crowd``), or ``const_speed`` if that is >= 0."""
    for i in range(n):
        if const_speed >= 0.0:
            ue[i] = const_speed
        elif crowd:
            ue[i] = u0[i] * shape(law, crowd_density(rho[i], cf[i], knee, stretch))
        else:
            ue[i] = u0[i] * shape(law, rho[i])


# ------------------------------------------------------------------ walls
@nb.njit(cache=False, inline="always")
def _proj(px, py, ax, ay, bx, by):
    dx = bx - ax
    dy = by - ay
    return ((px - ax) * dx + (py - ay) * dy) / (dx * dx + dy * dy)


@nb.njit(cache=False)
def wall_contact(px, py, s, piece, next_seg):
    """Contact point of (px, py) with the straight wall piece of segment ``s``, if ``s``
    owns it. Returns (owns, cx, cy).

    The contact with a straight piece (a run of collinear mesh edges) is the projection onto
    the whole piece; in its interior it is owned by the segment whose parameter range
    contains it. A corner shared by two pieces is counted once, by the segment starting
    there, and not at all when the previous piece has an interior contact (then that is the
    contact); where the piece ends at an exit (a door jamb) its last segment owns the corner.
    """
    ax, ay, bx, by = piece[s, 0], piece[s, 1], piece[s, 2], piece[s, 3]
    T = _proj(px, py, ax, ay, bx, by)
    if T > 0.0 and T < 1.0:
        if T >= piece[s, 4] and T < piece[s, 5]:
            return True, ax + T * (bx - ax), ay + T * (by - ay)
        return False, 0.0, 0.0
    if T <= 0.0:
        if piece[s, 4] != 0.0:
            return False, 0.0, 0.0  # not the first segment of the piece
        qax = piece[s, 6]
        if qax == qax:  # a previous wall piece exists (not NaN)
            Tq = _proj(px, py, qax, piece[s, 7], piece[s, 8], piece[s, 9])
            if Tq > 0.0 and Tq < 1.0:
                return False, 0.0, 0.0
        return True, ax, ay
    # T >= 1: the end corner belongs to the next piece, unless an exit follows (a jamb)
    if piece[s, 5] == 1.0 and next_seg[s] < 0:
        return True, bx, by
    return False, 0.0, 0.0


@nb.njit(cache=False)
def wall_accel(x, v, n, piece, next_seg, x0, y0, inv_cell, gnx, gny, cell_ptr,
               cell_seg, rc_w, rad, A, B, k, kappa, m, F, rs):
    """Add the wall accelerations of every pedestrian to ``F`` (cut-off ``rc_w`` [m]; body
    radii ``rad`` [m], social radii ``rs`` [m])."""
    rc2 = rc_w * rc_w
    invB = 1.0 / B
    inv_m = 1.0 / m
    for i in range(n):
        px = x[i, 0]
        py = x[i, 1]
        ci = min(max(int((px - x0) * inv_cell), 0), gnx - 1)
        cj = min(max(int((py - y0) * inv_cell), 0), gny - 1)
        c = ci * gny + cj
        for a in range(cell_ptr[c], cell_ptr[c + 1]):
            s = cell_seg[a]
            owns, qx, qy = wall_contact(px, py, s, piece, next_seg)
            if not owns:
                continue
            dx = px - qx
            dy = py - qy
            d2 = dx * dx + dy * dy
            if d2 >= rc2 or d2 == 0.0:
                continue
            # the pair force with a resting partner of radius 0 at the contact point q:
            # friction against the wall is -kappa (r_i - d) <v_i, t> t
            fx, fy = pair_force(dx, dy, math.sqrt(d2), -v[i, 0], -v[i, 1], rad[i], A, invB,
                                k, kappa, rs[i])
            F[i, 0] += fx * inv_m
            F[i, 1] += fy * inv_m


# ------------------------------------------------------------------ tracing in the mesh
@nb.njit(cache=False, inline="always")
def _bary(points, triangles, t, px, py):
    a, b, c = triangles[t, 0], triangles[t, 1], triangles[t, 2]
    ax, ay = points[a, 0], points[a, 1]
    bx, by = points[b, 0], points[b, 1]
    cx, cy = points[c, 0], points[c, 1]
    det = (bx - ax) * (cy - ay) - (cx - ax) * (by - ay)
    l1 = ((px - ax) * (cy - ay) - (cx - ax) * (py - ay)) / det
    l2 = ((bx - ax) * (py - ay) - (px - ax) * (by - ay)) / det
    return 1.0 - l1 - l2, l1, l2


@nb.njit(cache=False)
def trace(points, triangles, nbr, t0, ax, ay, bx, by):
    """Follow the segment A -> B through the mesh, starting in triangle ``t0`` (containing A).

    Returns ``(t, local_edge, s)``: the triangle containing B and ``local_edge = -1``; or,
    when the segment leaves the mesh, the last triangle, the local index of the boundary edge
    it crosses and the fraction ``s`` of A -> B at the crossing.
    """
    t = t0
    for _ in range(100000):
        b0, b1, b2 = _bary(points, triangles, t, bx, by)
        if b0 >= -1e-12 and b1 >= -1e-12 and b2 >= -1e-12:
            return t, -1, 1.0
        a0, a1, a2 = _bary(points, triangles, t, ax, ay)
        best = -1
        best_s = np.inf
        for i in range(3):
            li = b0 if i == 0 else (b1 if i == 1 else b2)
            if li < 0.0:
                ai = a0 if i == 0 else (a1 if i == 1 else a2)
                den = ai - li
                s = ai / den if den > 0.0 else 0.0
                if s < 0.0:
                    s = 0.0
                if s < best_s:
                    best_s = s
                    best = i
        nt = nbr[t, best]
        if nt < 0:
            return t, best, best_s
        t = nt
    return t, -2, 0.0


@nb.njit(cache=False)
def follow(points, triangles, nbr, tri, x, n, P):
    """Update the triangle of every pedestrian by walking from its previous triangle.
    A pedestrian (temporarily) outside the mesh keeps the last triangle it was in. ``P`` is
    a packed direction table (:func:`~pedmesh.eikonal.direction._pack`); its affine maps
    settle the common case, a pedestrian well inside its triangle, without a division."""
    for i in range(n):
        t0 = tri[i]
        if _inside_packed(P, t0, x[i, 0], x[i, 1], INSIDE_MARGIN):
            continue
        b0, b1, b2 = _bary(points, triangles, t0, x[i, 0], x[i, 1])
        if b0 >= -1e-12 and b1 >= -1e-12 and b2 >= -1e-12:
            continue  # still in the same triangle (the common case)
        # walk from the current triangle's centroid so the walk is well defined
        a, b, c = triangles[t0, 0], triangles[t0, 1], triangles[t0, 2]
        cx = (points[a, 0] + points[b, 0] + points[c, 0]) / 3.0
        cy = (points[a, 1] + points[b, 1] + points[c, 1]) / 3.0
        t, e, s = trace(points, triangles, nbr, t0, cx, cy, x[i, 0], x[i, 1])
        tri[i] = t


# ------------------------------------------------------------------ one SSP-RK3 step
@nb.njit(cache=False)
def accel(x, v, n, tri, points, triangles, nbr, dpack, pi, pj, n_near, n_far,
          piece, next_seg, wx0, wy0, winv, wnx, wny, wptr, wseg,
          rc_f, rc_d, rc_w, rad, A, B, k, kappa, m, R, tau, u0, law,
          const_u, use_const, F, rho, e, with_density, toff, tbuf, space, rs, wmap, wgeo,
          cf, ue):
    """Acceleration of every pedestrian: pair forces (over the pair list), walls and the
    desired-velocity term (with the densities ``rho`` evaluated here if ``with_density``,
    else as they are). Per pedestrian i: body radius ``rad[i]`` [m], free speed ``u0[i]``
    [m/s] (0 before its premovement time), U_e = u0[i] g(rho) with g the speed law array
    ``law`` (:mod:`pedmesh.speed`), and its route: row ``tri[i] + toff[i]`` of the stacked
    direction tables ``dpack`` (one table per target group; ``tbuf`` (n,) work). ``space``
    = (shrink [m], t_space [s]) of the speed-dependent space requirement
    (:func:`social_radii` of the desired speeds at the densities ``rho`` as they are when
    the forces start, into the work array ``rs``); shrink 0: the social radii are the body
    radii (the paper's model). ``space[2]``: the field of vision (lambda, 1: isotropic);
    ``space[3]``, ``space[4]``: the crowding stretch and knee [ped/m^2] of
    :func:`crowd_density` (stretch 1: off), with the free-width map ``wmap`` and ``wgeo`` =
    (x0, y0, 1/cell, queue width, crowd width) (:mod:`pedmesh.models.sfm.crowding`; work arrays
    ``cf``, ``ue``)."""
    crowd = space[3] > 1.0
    if crowd:
        crowd_factors(x, n, wmap, wgeo[0], wgeo[1], wgeo[2], wgeo[3], wgeo[4], cf)
    soc = rad
    # the desired speeds of the space requirement serve the driving term too, unless the
    # densities are evaluated again below
    have_ue = space[0] > 0.0 and not with_density
    if space[0] > 0.0:
        cs = math.sqrt(const_u[0] * const_u[0] + const_u[1] * const_u[1]) if use_const else -1.0
        desired_speeds(n, u0, law, rho, cs, crowd, cf, space[4], space[3], ue)
        social_radii(n, rad, ue, space[0], space[1], crowd, cf, rs)
        soc = rs
    pair_accel_list(x, v, n, pi, pj, n_near, n_far, rc_f, rc_d, rad, A, B, k, kappa, m,
                    R, F, rho, with_density, soc, space[2], e, space[6:8])
    wall_accel(x, v, n, piece, next_seg, wx0, wy0, winv, wnx, wny, wptr, wseg,
               rc_w, rad, A * space[5], B, k, kappa, m, F, soc)
    inv_tau = 1.0 / tau
    if use_const:
        for i in range(n):
            F[i, 0] += (const_u[0] - v[i, 0]) * inv_tau
            F[i, 1] += (const_u[1] - v[i, 1]) * inv_tau
        return
    follow(points, triangles, nbr, tri, x, n, dpack)
    for i in range(n):
        tbuf[i] = tri[i] + toff[i] if tri[i] >= 0 else -1
    _interpolate(dpack, tbuf[:n], x[:n], e)
    if not have_ue:
        desired_speeds(n, u0, law, rho, -1.0, crowd, cf, space[4], space[3], ue)
    for i in range(n):
        F[i, 0] += (ue[i] * e[i, 0] - v[i, 0]) * inv_tau
        F[i, 1] += (ue[i] * e[i, 1] - v[i, 1]) * inv_tau


# ------------------------------------------------------------------ exits and reflection
@nb.njit(cache=False)
def settle(x_old, x, v, tri, n, points, triangles, nbr, tri_edges, edge_kind, edge_owner,
           edge_normals, exit_of, exit_frac, P):
    """After a step: remove pedestrians whose step crossed an exit, reflect those whose step
    crossed a wall (displacement and velocity, as in the paper), and update triangles.

    ``exit_of[i]`` is set to the exit number (or -1) and ``exit_frac[i]`` to the fraction of
    the step at which the exit was crossed; a pedestrian who crossed an exit is left at the
    crossing point (on the exit). Returns the number of reflections. A step that
    ends well inside the triangle it started in (tested with the affine maps of the packed
    table ``P``) crosses nothing and is left as it is.
    """
    n_reflect = 0
    for i in range(n):
        exit_of[i] = -1
        if _inside_packed(P, tri[i], x[i, 0], x[i, 1], INSIDE_MARGIN):
            continue
        ax, ay = x_old[i, 0], x_old[i, 1]
        bx, by = x[i, 0], x[i, 1]
        t = tri[i]
        s_total = 0.0
        for bounce in range(8):
            t, le, s = trace(points, triangles, nbr, t, ax, ay, bx, by)
            if le == -1:
                break
            if le == -2:  # walk failed (should not happen): stay where it was
                bx, by = x_old[i, 0], x_old[i, 1]
                t = tri[i]
                break
            ed = tri_edges[t, le]
            if edge_kind[ed] == EXIT_KIND:
                exit_of[i] = edge_owner[ed]
                exit_frac[i] = s_total + (1.0 - s_total) * s
                # a leaver ends on the exit, at the point where it crossed
                bx = ax + s * (bx - ax)
                by = ay + s * (by - ay)
                break
            # reflect the remaining displacement and the velocity about the wall line
            nx_, ny_ = edge_normals[ed, 0], edge_normals[ed, 1]
            qx = ax + s * (bx - ax)
            qy = ay + s * (by - ay)
            dn = (bx - qx) * nx_ + (by - qy) * ny_
            bx -= 2.0 * dn * nx_
            by -= 2.0 * dn * ny_
            vn = v[i, 0] * nx_ + v[i, 1] * ny_
            if vn > 0.0:
                v[i, 0] -= 2.0 * vn * nx_
                v[i, 1] -= 2.0 * vn * ny_
            # continue from just inside the crossing point
            ax = qx - 1e-9 * nx_
            ay = qy - 1e-9 * ny_
            s_total = s_total + (1.0 - s_total) * s
            n_reflect += 1
            if bounce == 7:  # a corner trap: stay where it was
                bx, by = x_old[i, 0], x_old[i, 1]
                t = tri[i]
        x[i, 0] = bx
        x[i, 1] = by
        tri[i] = t
    return n_reflect


# ------------------------------------------------------------------ densities on the mesh
@nb.njit(cache=False)
def density_at(q, nq, x, n, cell_start, cell_order, cx0, cy0, cinv, cnx, cny, R, rc_d, out):
    """Gaussian kernel density (eq3, eq4) of the pedestrians at points ``q`` [ped/m^2]."""
    w0 = 1.0 / (math.pi * R * R)
    invR2 = 1.0 / (R * R)
    rc2 = rc_d * rc_d
    reach = int(rc_d * cinv) + 1
    for p in range(nq):
        px, py = q[p, 0], q[p, 1]
        ci = int((px - cx0) * cinv)
        cj = int((py - cy0) * cinv)
        acc = 0.0
        for ii in range(max(ci - reach, 0), min(ci + reach, cnx - 1) + 1):
            for jj in range(max(cj - reach, 0), min(cj + reach, cny - 1) + 1):
                c = ii * cny + jj
                for a in range(cell_start[c], cell_start[c + 1]):
                    i = cell_order[a]
                    dx = x[i, 0] - px
                    dy = x[i, 1] - py
                    d2 = dx * dx + dy * dy
                    if d2 < rc2:
                        acc += w0 * math.exp(-d2 * invR2)
        out[p] = acc


@nb.njit(cache=False)
def rk3_step(x, v, n, dt, tri, points, triangles, nbr, dpack,
             cell_start, cell_order, cx0, cy0, cinv, cnx, cny,
             piece, next_seg, wx0, wy0, winv, wnx, wny, wptr, wseg,
             rc_f, rc_d, rc_w, rad, A, B, k, kappa, m, R, tau, u0, law,
             const_u, use_const, xs, vs, F, rho, rho_out, e, pi, pj, skin, density_stages,
             toff, tbuf, space, rs, wmap, wgeo, cf, ue):
    """One Shu-Osher SSP-RK3 step of (x, v) in place; ``tri`` follows the stage positions.
    ``rho_out`` receives the kernel densities at the start of the step; they set U_e in all
    three stages if ``density_stages`` is 1, else the density is re-evaluated at each stage.

    The pairs closer than the force cut-off plus ``skin`` (with ``density_stages`` 3 also
    those within the density cut-off plus ``skin``) are listed once per step from a cell
    list and reused by the three stages (the list is rebuilt for a stage in the rare case
    that someone moved more than skin/2 since). Returns the number of listed pairs, or -1 if
    ``pi``/``pj`` are too small (the caller enlarges them and repeats the step).
    """
    every = density_stages == 3
    # with the density held over the step it is computed while listing the pairs, and the
    # list needs the near pairs only (those within the force cut-off plus the skin)
    rc_list = max(rc_f + skin, rc_d + skin) if every else rc_f + skin
    build_cells(x, n, cx0, cy0, cinv, cnx, cny, cell_start, cell_order)
    n_near, n_far = build_pairs(x, n, cell_start, cell_order, cnx, cny, rc_list, rc_f + skin,
                                pi, pj, rho, rc_d, R, not every, e, space[6:8])
    if n_near < 0:
        return -1
    # stage 1: u1 = u + dt L(u)
    accel(x, v, n, tri, points, triangles, nbr, dpack, pi, pj, n_near, n_far, piece,
          next_seg, wx0, wy0, winv, wnx, wny, wptr, wseg, rc_f, rc_d, rc_w, rad, A, B, k, kappa,
          m, R, tau, u0, law, const_u, use_const, F, rho, e, every, toff, tbuf, space, rs, wmap,
          wgeo, cf, ue)
    for i in range(n):
        rho_out[i] = rho[i]
        for d in range(2):
            xs[i, d] = x[i, d] + dt * v[i, d]
            vs[i, d] = v[i, d] + dt * F[i, d]
    # stage 2: u2 = 3/4 u + 1/4 (u1 + dt L(u1))
    n_near, n_far, rebuilt = _refresh_pairs(x, xs, n, skin, cell_start, cell_order, cx0, cy0,
                                            cinv, cnx, cny, rc_f, rc_d, R, pi, pj, rho, n_near,
                                            n_far, False, e, space[6:8])
    if n_near < 0:
        return -1
    accel(xs, vs, n, tri, points, triangles, nbr, dpack, pi, pj, n_near, n_far, piece,
          next_seg, wx0, wy0, winv, wnx, wny, wptr, wseg, rc_f, rc_d, rc_w, rad, A, B, k, kappa,
          m, R, tau, u0, law, const_u, use_const, F, rho, e, every, toff, tbuf, space, rs, wmap,
          wgeo, cf, ue)
    for i in range(n):
        for d in range(2):
            x1 = xs[i, d]
            v1 = vs[i, d]
            xs[i, d] = 0.75 * x[i, d] + 0.25 * (x1 + dt * v1)
            vs[i, d] = 0.75 * v[i, d] + 0.25 * (v1 + dt * F[i, d])
    # stage 3: u_new = 1/3 u + 2/3 (u2 + dt L(u2)); a list rebuilt for stage 2 has no skin
    n_near, n_far, rebuilt = _refresh_pairs(x, xs, n, skin, cell_start, cell_order, cx0, cy0,
                                            cinv, cnx, cny, rc_f, rc_d, R, pi, pj, rho, n_near,
                                            n_far, rebuilt, e, space[6:8])
    if n_near < 0:
        return -1
    accel(xs, vs, n, tri, points, triangles, nbr, dpack, pi, pj, n_near, n_far, piece,
          next_seg, wx0, wy0, winv, wnx, wny, wptr, wseg, rc_f, rc_d, rc_w, rad, A, B, k, kappa,
          m, R, tau, u0, law, const_u, use_const, F, rho, e, every, toff, tbuf, space, rs, wmap,
          wgeo, cf, ue)
    for i in range(n):
        for d in range(2):
            x[i, d] = x[i, d] / 3.0 + 2.0 / 3.0 * (xs[i, d] + dt * vs[i, d])
            v[i, d] = v[i, d] / 3.0 + 2.0 / 3.0 * (vs[i, d] + dt * F[i, d])
    return n_near + n_far


@nb.njit(cache=False)
def _refresh_pairs(x0, x, n, skin, cell_start, cell_order, cx0, cy0, cinv, cnx, cny, rc_f, rc_d,
                   R, pi, pj, rho, n_near, n_far, force, e, cone):
    """Keep the pair list (built with skin at ``x0``) if nobody moved more than skin/2 since,
    else (or if ``force``) rebuild it for the positions ``x`` without skin, valid for this
    stage only. Returns ``(n_near, n_far, rebuilt)``."""
    lim = 0.25 * skin * skin
    for i in range(n):
        dx = x[i, 0] - x0[i, 0]
        dy = x[i, 1] - x0[i, 1]
        if force or dx * dx + dy * dy > lim:
            build_cells(x, n, cx0, cy0, cinv, cnx, cny, cell_start, cell_order)
            n_near, n_far = build_pairs(x, n, cell_start, cell_order, cnx, cny,
                                        max(rc_f, rc_d), rc_f, pi, pj, rho, rc_d, R, False,
                                        e, cone)
            return n_near, n_far, True
    return n_near, n_far, False


@nb.njit(cache=False)
def first_bad(x, v, n, vmax2):
    """Index of the first pedestrian with a non-finite state or a speed^2 above ``vmax2``
    (-1 if none)."""
    for i in range(n):
        s2 = v[i, 0] * v[i, 0] + v[i, 1] * v[i, 1]
        if not (s2 <= vmax2) or x[i, 0] != x[i, 0] or x[i, 1] != x[i, 1]:
            return i
    return -1
