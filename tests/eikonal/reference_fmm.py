"""A slow, plain-Python fast-marching method: the reference the compiled kernel is tested
against. Written independently of pedmesh.eikonal.fmm_kernels: heapq with lazy deletion, the
Kimmel-Sethian local solver in its law-of-cosines form, and its own obtuse-angle walk."""

from __future__ import annotations

import heapq
import math

import numpy as np


def ks_local(xc, xa, xb, ta, tb, f):
    """Kimmel-Sethian update of C from A, B (law-of-cosines form)."""
    if ta > tb:
        xa, xb, ta, tb = xb, xa, tb, ta
    a = math.dist(xc, xb)
    b = math.dist(xc, xa)
    cos = ((xa[0] - xc[0]) * (xb[0] - xc[0]) + (xa[1] - xc[1]) * (xb[1] - xc[1])) / (a * b)
    u = tb - ta
    A = a * a + b * b - 2 * a * b * cos
    B = 2 * b * u * (a * cos - b)
    C = b * b * (u * u - f * f * a * a * (1 - cos * cos))
    disc = B * B - 4 * A * C
    if disc >= 0 and cos > 0:
        t = (-B + math.sqrt(disc)) / (2 * A)
        if u < t and a * cos <= b * (t - u) / t <= a / cos:
            return ta + t
    return min(ta + f * b, tb + f * a)


def split_vertex(pts, tri, nbr, t, i, max_steps=24):
    """Vertex D splitting the obtuse angle at corner i of triangle t, None if not obtuse,
    -1 if the walk fails."""
    C, A, B = tri[t][i], tri[t][(i + 1) % 3], tri[t][(i + 2) % 3]
    ca = pts[A] - pts[C]
    cb = pts[B] - pts[C]
    if ca @ cb >= 0:
        return None
    ua = ca / np.linalg.norm(ca)
    ub = cb / np.linalg.norm(cb)
    # the acute cone: directions within 90 degrees of both CA and CB; its bisector
    r = np.array([ub[1], -ub[0]]) + np.array([-ua[1], ua[0]])
    P, Q, cur = A, B, t
    for _ in range(max_steps):
        j = [jj for jj in range(3) if tri[cur][jj] not in (P, Q)][0]
        nt = nbr[cur][j]
        if nt < 0:
            return -1
        V = [v for v in tri[nt] if v not in (P, Q)][0]
        d = pts[V] - pts[C]
        if d @ ua >= 0 and d @ ub >= 0:
            return V
        if r[0] * d[1] - r[1] * d[0] > 0:
            Q = V
        else:
            P = V
        cur = nt
    return -1


def reference_fmm(mesh, f_tri, fixed, rays=None):
    """phi at the vertices. ``fixed`` maps exit vertex -> value; ``rays`` maps a vertex to
    a list of (target, cost) straight-ray candidates."""
    pts = mesh.points
    tri = mesh.triangles.tolist()
    nbr = mesh.triangle_neighbors.tolist()
    n = len(pts)
    # update stencils per target vertex: (A, B, triangle) real or virtual
    stencils = [[] for _ in range(n)]
    for t in range(len(tri)):
        for i in range(3):
            C, A, B = tri[t][i], tri[t][(i + 1) % 3], tri[t][(i + 2) % 3]
            D = split_vertex(pts, tri, nbr, t, i)
            if D is None or D == -1:
                stencils[C].append((A, B, t))
            else:
                stencils[C].append((A, D, t))
                stencils[C].append((D, B, t))
    around = [[] for _ in range(n)]  # triangles around each vertex
    for t, (a, b, c) in enumerate(tri):
        for v in (a, b, c):
            around[v].append(t)
    users = [[] for _ in range(n)]  # stencils (of any target) that use each vertex
    for c in range(n):
        for A, B, t in stencils[c]:
            users[A].append((c, B, A, B, t))
            users[B].append((c, A, A, B, t))
    T = np.full(n, np.inf)
    done = np.zeros(n, bool)
    heap = []
    for v, val in fixed.items():
        T[v] = val
        heapq.heappush(heap, (val, v))
    while heap:
        tv, v = heapq.heappop(heap)
        if done[v] or tv > T[v]:
            continue
        done[v] = True
        cands = []
        # edge updates inside each triangle around v
        for t in around[v]:
            for c in tri[t]:
                if c != v and not done[c]:
                    cands.append((c, tv + f_tri[t] * math.dist(pts[v], pts[c])))
        # triangle updates: stencils whose other upwind vertex is already accepted
        for c, other, A, B, t in users[v]:
            if not done[c] and done[other]:
                cands.append((c, ks_local(pts[c], pts[A], pts[B], T[A], T[B], f_tri[t])))
        for c, t_new in cands:
            if c not in fixed and t_new < T[c]:
                T[c] = t_new
                heapq.heappush(heap, (t_new, c))
        for c, cost in (rays or {}).get(v, []):
            if not done[c] and c not in fixed and tv + cost < T[c]:
                T[c] = tv + cost
                heapq.heappush(heap, (T[c], c))
    return T
