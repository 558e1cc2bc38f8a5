"""Compiled kernels of the unstructured fast-marching method (Kimmel-Sethian).

Data layout (built once per mesh by :mod:`pedmesh.eikonal.fmm`):

* *dependencies*, CSR by trigger vertex: when vertex ``v`` is accepted, every row ``k`` in
  ``dep_ptr[v]:dep_ptr[v+1]`` names a target vertex ``dep_target[k]`` whose triangle update
  uses ``v`` and ``dep_other[k]``. The row stores the update's metric already oriented with
  ``v`` first: ``dep_q[k] = (q_vv, q_vo, q_oo)`` is the inverse Gram matrix of the edge
  vectors (v - C, o - C), and ``dep_tri[k]`` the triangle whose cost applies.
* *edges*, CSR by vertex: neighbours, edge length and the (one or two) triangles beside the
  edge, for the Dijkstra-type update along an edge.
* *corner rays*, CSR by vertex: for exit end points and reflex boundary corners, the nearby
  vertices visible from them and the travel cost along the straight segment. When such a
  vertex is accepted, each gets the candidate ``T_v + cost(ray)`` (the cost of a real
  path), which removes most of the error the expansion fans at those points create.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

# heap position codes (pos[v] >= 0 is a heap slot)
FAR = -1
ACCEPTED = -2


# ---------------------------------------------------------------- indexed 4-ary heap
@nb.njit(cache=True, inline="always")
def _sift_up(hv, hk, pos, i, v, key):
    """Place vertex ``v`` with ``key`` at slot ``i`` or above."""
    while i > 0:
        p = (i - 1) >> 2
        kp = hk[p]
        if kp <= key:
            break
        w = hv[p]
        hv[i] = w
        hk[i] = kp
        pos[w] = i
        i = p
    hv[i] = v
    hk[i] = key
    pos[v] = i


@nb.njit(cache=True, inline="always")
def _sift_down_last(hv, hk, pos, size):
    """Move the element in slot ``size`` (just removed from the end) down from the root."""
    v = hv[size]
    key = hk[size]
    i = 0
    while True:
        c = 4 * i + 1
        if c >= size:
            break
        best = c
        kb = hk[c]
        e = c + 4 if c + 4 < size else size
        for j in range(c + 1, e):
            if hk[j] < kb:
                kb = hk[j]
                best = j
        if kb >= key:
            break
        w = hv[best]
        hv[i] = w
        hk[i] = kb
        pos[w] = i
        i = best
    hv[i] = v
    hk[i] = key
    pos[v] = i


# ---------------------------------------------------------------- local solver
@nb.njit(cache=True, inline="always")
def triangle_update(cx, cy, ax, ay, bx, by, ta, tb, f):
    """Arrival time at C = (cx, cy) from a planar front through A (time ``ta``) and B (``tb``).

    With E the edge vectors (A - C, B - C) and Q = (E E^T)^-1, the front's gradient g has
    E g = (ta, tb) - T_C and |g| = f (the slowness [s/m]): a quadratic in T_C. Its larger
    root is accepted when the characteristic reaches C from inside the triangle, i.e. the
    weights w = Q (T_C - (ta, tb)) are >= 0; otherwise the better edge update is returned.
    Geometry is recomputed from the coordinates: cheaper than loading stored matrices.
    """
    eax = ax - cx
    eay = ay - cy
    ebx = bx - cx
    eby = by - cy
    gaa = eax * eax + eay * eay
    gbb = ebx * ebx + eby * eby
    gab = eax * ebx + eay * eby
    inv = 1.0 / (gaa * gbb - gab * gab)
    qaa = gbb * inv
    qab = -gab * inv
    qbb = gaa * inv
    u = tb - ta
    a = qaa + 2.0 * qab + qbb
    b = (qab + qbb) * u
    c = qbb * u * u - f * f
    disc = b * b - a * c
    if disc >= 0.0:
        s = (b + math.sqrt(disc)) / a
        wa = qaa * s + qab * (s - u)
        wb = qab * s + qbb * (s - u)
        if wa >= 0.0 and wb >= 0.0:
            return ta + s
    ea = ta + f * math.sqrt(gaa)
    eb = tb + f * math.sqrt(gbb)
    return ea if ea < eb else eb


# ---------------------------------------------------------------- the march
@nb.njit(cache=True)
def march(
    T, fixed_vertices, fixed_values, pts, tri, tsplit,
    vt_ptr, vt_tri, vt_loc, ds_ptr, ds_tri, ds_loc,
    ray_ptr, ray_idx, ray_cost, f_tri,
):
    """Fast marching from the fixed (exit) vertices; fills ``T`` in place.

    ``tsplit[t, i]`` is the vertex D splitting the obtuse corner ``i`` of triangle ``t``
    (C, with A, B the next two corners counter-clockwise; the corner is then updated through
    the virtual triangles (C, A, D) and (C, D, B)) or -1. ``vt_*`` is the vertex-to-triangle
    adjacency with the vertex's local index, ``ds_*`` lists by vertex D the (triangle,
    corner) pairs it splits. ``ray_cost[k]`` is the cost of corner ray ``k`` and ``f_tri``
    the slowness per triangle [s/m]. Unreached vertices keep ``inf``.
    """
    n = T.shape[0]
    pos = np.full(n, FAR, np.int32)
    fixed = np.zeros(n, np.bool_)
    hv = np.empty(n, np.int32)
    hk = np.empty(n, np.float64)
    size = 0
    for i in range(n):
        T[i] = np.inf
    for j in range(fixed_vertices.shape[0]):
        v = fixed_vertices[j]
        if fixed_values[j] < T[v]:
            T[v] = fixed_values[j]
    for j in range(fixed_vertices.shape[0]):
        v = fixed_vertices[j]
        if pos[v] == FAR:
            _sift_up(hv, hk, pos, size, v, T[v])
            size += 1
        fixed[v] = True
    # Every candidate for a vertex c is offered inline below (lower T[c], then insert or
    # decrease-key): a helper function that returns the heap size is 1.5x slower in numba.
    while size > 0:
        v = hv[0]
        tv = hk[0]
        pos[v] = ACCEPTED
        size -= 1
        if size > 0:
            _sift_down_last(hv, hk, pos, size)
        vx = pts[v, 0]
        vy = pts[v, 1]
        # the triangles around v: update their two other corners
        for s in range(vt_ptr[v], vt_ptr[v + 1]):
            t = vt_tri[s]
            iv = vt_loc[s]
            f = f_tri[t]
            for r in range(1, 3):
                ic = (iv + r) % 3  # target corner C
                c = tri[t, ic]
                if pos[c] == ACCEPTED:
                    continue
                cx = pts[c, 0]
                cy = pts[c, 1]
                o = tri[t, (iv + 3 - r) % 3]  # the third corner
                d = tsplit[t, ic]
                if pos[o] == ACCEPTED and d < 0:
                    cand = triangle_update(cx, cy, vx, vy, pts[o, 0], pts[o, 1], tv, T[o], f)
                else:
                    cand = tv + f * math.sqrt((vx - cx) ** 2 + (vy - cy) ** 2)  # edge update
                    if d >= 0 and pos[d] == ACCEPTED:  # virtual triangle (C, v, D)
                        cv = triangle_update(cx, cy, vx, vy, pts[d, 0], pts[d, 1], tv, T[d], f)
                        if cv < cand:
                            cand = cv
                if cand < T[c] and not fixed[c]:
                    T[c] = cand
                    pc = pos[c]
                    if pc == FAR:
                        _sift_up(hv, hk, pos, size, c, cand)
                        size += 1
                    else:
                        _sift_up(hv, hk, pos, pc, c, cand)
        # v as the split vertex D of obtuse corners: virtual triangles (C, A, v), (C, v, B)
        for s in range(ds_ptr[v], ds_ptr[v + 1]):
            t = ds_tri[s]
            ic = ds_loc[s]
            c = tri[t, ic]
            if pos[c] == ACCEPTED:
                continue
            cx = pts[c, 0]
            cy = pts[c, 1]
            f = f_tri[t]
            cand = np.inf
            for r in range(1, 3):
                o = tri[t, (ic + r) % 3]  # A, then B
                if pos[o] == ACCEPTED:
                    cv = triangle_update(cx, cy, vx, vy, pts[o, 0], pts[o, 1], tv, T[o], f)
                    if cv < cand:
                        cand = cv
            if cand < T[c] and not fixed[c]:
                T[c] = cand
                pc = pos[c]
                if pc == FAR:
                    _sift_up(hv, hk, pos, size, c, cand)
                    size += 1
                else:
                    _sift_up(hv, hk, pos, pc, c, cand)
        # straight rays from exit end points and reflex corners
        for k in range(ray_ptr[v], ray_ptr[v + 1]):
            c = ray_idx[k]
            if pos[c] == ACCEPTED:
                continue
            cand = tv + ray_cost[k]
            if cand < T[c] and not fixed[c]:
                T[c] = cand
                pc = pos[c]
                if pc == FAR:
                    _sift_up(hv, hk, pos, size, c, cand)
                    size += 1
                else:
                    _sift_up(hv, hk, pos, pc, c, cand)
    return T


# ---------------------------------------------------------------- set-up helpers
@nb.njit(cache=True)
def find_split_vertices(points, tri, nbr, max_steps):
    """Kimmel-Sethian split of every obtuse angle.

    For triangle ``t`` with an obtuse angle at local vertex ``i`` (C, with A, B the next
    vertices counter-clockwise), walk across the edge opposite C along the bisector of the
    cone of directions making angles <= 90 degrees with both CA and CB, until a vertex D in
    that cone is found. Returns ``split[t, i]`` = D, or -1 where the angle is not obtuse,
    and -2 where the walk hit a boundary edge or ran out of steps (plain update fallback).
    """
    m = tri.shape[0]
    split = np.full((m, 3), -1, np.int64)
    for t in range(m):
        for i in range(3):
            C = tri[t, i]
            A = tri[t, (i + 1) % 3]
            B = tri[t, (i + 2) % 3]
            ax = points[A, 0] - points[C, 0]
            ay = points[A, 1] - points[C, 1]
            bx = points[B, 0] - points[C, 0]
            by = points[B, 1] - points[C, 1]
            if ax * bx + ay * by >= 0.0:
                continue  # not obtuse
            la = math.sqrt(ax * ax + ay * ay)
            lb = math.sqrt(bx * bx + by * by)
            uax, uay = ax / la, ay / la
            ubx, uby = bx / lb, by / lb
            # cone boundaries: uB turned clockwise, uA turned counter-clockwise
            rx = uby - uay
            ry = -ubx + uax
            rn = math.sqrt(rx * rx + ry * ry)
            rx /= rn
            ry /= rn
            P, Q = A, B
            cur = t
            found = -2
            for _ in range(max_steps):
                # neighbour of cur across edge PQ
                j = 0
                for jj in range(3):
                    if tri[cur, jj] != P and tri[cur, jj] != Q:
                        j = jj
                nt = nbr[cur, j]
                if nt < 0:
                    break
                V = tri[nt, 0]
                for jj in range(3):
                    if tri[nt, jj] != P and tri[nt, jj] != Q:
                        V = tri[nt, jj]
                dx = points[V, 0] - points[C, 0]
                dy = points[V, 1] - points[C, 1]
                if dx * uax + dy * uay >= 0.0 and dx * ubx + dy * uby >= 0.0:
                    found = V
                    break
                if rx * dy - ry * dx > 0.0:
                    Q = V  # V lies on B's side of the ray: it leaves through edge PV
                else:
                    P = V
                cur = nt
            split[t, i] = found
    return split
