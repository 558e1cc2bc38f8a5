"""Compiled kernels of the unstructured fast-marching method (Kimmel-Sethian).

Data layout (built once per mesh by :mod:`pedmesh.eikonal.fmm`), all CSR by vertex and laid
out so that accepting a vertex reads one contiguous block per list:

* *corners*: for every triangle ``t`` around vertex ``v``, row ``s`` in
  ``vt_ptr[v]:vt_ptr[v+1]`` of ``vt_corner`` is ``(t, A, B, D_A, D_B)``: A, B the next two
  corners of ``t`` counter-clockwise from ``v``, and ``D_A``, ``D_B`` the vertices splitting
  the obtuse angle at A, B (or -1: the angle is not obtuse, or its split walk failed).
* *split targets*: the obtuse corners a vertex ``D`` splits, row ``s`` in
  ``ds_ptr[D]:ds_ptr[D+1]`` of ``ds_corner`` being ``(t, C, A, B)``: the obtuse corner C of
  triangle ``t`` and its next two corners A, B counter-clockwise. C is updated through the
  virtual triangles (C, A, D) and (C, D, B).
* *corner rays*: for exit end points and reflex boundary corners, the nearby vertices
  ``ray_idx[k]`` visible from them (``k`` in ``ray_ptr[v]:ray_ptr[v+1]``) and the travel cost
  ``ray_cost[k]`` along the straight segment. When such a vertex is accepted, each gets the
  candidate ``T_v + cost(ray)`` (the cost of a real path), which removes most of the error
  the expansion fans at those points create.

Much of the march's time went into cache misses on a vertex's rows when it is accepted:
the heap's next vertex is known one step ahead, so its corner rows are prefetched while the
current vertex is processed, and a vertex's list pointers when it enters the heap.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from llvmlite import ir
from numba.core import cgutils, types
from numba.extending import intrinsic

# heap position codes (pos[v] >= 0 is a heap slot)
FAR = -1
ACCEPTED = -2


# ---------------------------------------------------------------- cache prefetch
@intrinsic
def _prefetch(typingctx, arr, i):
    """Hint the CPU to load row ``i`` of ``arr`` into cache (``llvm.prefetch``: a no-op for
    the results, never faults, so ``i`` may be out of range)."""
    if not isinstance(arr, types.Array) or not isinstance(i, types.Integer):
        return None

    def codegen(context, builder, sig, args):
        aryty, ity = sig.args
        ary = context.make_array(aryty)(context, builder, args[0])
        idx = context.cast(builder, args[1], ity, types.intp)
        offset = builder.mul(idx, builder.extract_value(ary.strides, 0))
        ptr = builder.gep(builder.bitcast(ary.data, cgutils.voidptr_t), [offset])
        i32 = ir.IntType(32)
        fnty = ir.FunctionType(ir.VoidType(), [cgutils.voidptr_t, i32, i32, i32])
        fn = cgutils.get_or_insert_function(builder.module, fnty, "llvm.prefetch.p0i8")
        # read access, high temporal locality, data cache
        builder.call(fn, [ptr, i32(0), i32(3), i32(1)])
        return context.get_dummy_value()

    return types.void(arr, i), codegen


@nb.njit(cache=True, nogil=True)
def _prefetch_probe(a):
    _prefetch(a, 1)
    return a[0]


def _prefetch_works() -> bool:
    """Whether this numba/llvmlite compiles the prefetch hint (it is only a hint: without
    it the march is the same, about 1.4x slower). Cached after the first import."""
    try:
        _prefetch_probe(np.zeros(2))
        return True
    except Exception:  # pragma: no cover - depends on the installed llvmlite
        return False


if not _prefetch_works():  # pragma: no cover
    @nb.njit(inline="always")
    def _prefetch(arr, i):  # noqa: F811 - the no-op fallback
        pass


# ---------------------------------------------------------------- indexed 4-ary heap
@nb.njit(cache=True, nogil=True, inline="always")
def _sift_up(hv, hk, pos, i, v, key, ordered):
    """Place vertex ``v`` with ``key`` at slot ``i`` or above (``ordered``: equal keys in
    the order of their vertices, see :func:`march`)."""
    while i > 0:
        p = (i - 1) >> 2
        kp = hk[p]
        if kp < key:
            break
        if kp == key and (not ordered or hv[p] < v):
            break
        w = hv[p]
        hv[i] = w
        hk[i] = kp
        pos[w] = i
        i = p
    hv[i] = v
    hk[i] = key
    pos[v] = i


@nb.njit(cache=True, nogil=True, inline="always")
def _sift_down_last(hv, hk, pos, size, ordered):
    """Move the element in slot ``size`` (just removed from the end) down from the root
    (``ordered``: equal keys in the order of their vertices)."""
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
        if kb > key:
            break
        w = hv[best]
        if ordered:  # of the children with the least key, the least vertex
            for j in range(c, e):  # (all four: a trip count that does not vary)
                if (hk[j] == kb) & (hv[j] < w):
                    best = j
                    w = hv[j]
            if kb == key and w > v:
                break
        elif kb == key:
            break
        hv[i] = w
        hk[i] = kb
        pos[w] = i
        i = best
    hv[i] = v
    hk[i] = key
    pos[v] = i


# ---------------------------------------------------------------- local solver
@nb.njit(cache=True, nogil=True, inline="always")
def triangle_update(cx, cy, cz, ax, ay, az, bx, by, bz, ta, tb, f):
    """Arrival time at C = (cx, cy, cz) from a planar front through A (time ``ta``) and B
    (``tb``), all three in one plane (z = 0 for a room; a building's surface is planar in
    each triangle, so its 3-D coordinates give the same update as the triangle's own 2-D
    chart).

    With E the edge vectors (A - C, B - C) and Q = (E E^T)^-1, the front's gradient g has
    E g = (ta, tb) - T_C and ``|g| = f`` (the slowness [s/m]): a quadratic in T_C. Its larger
    root is accepted when the characteristic reaches C from inside the triangle, i.e. the
    weights w = Q (T_C - (ta, tb)) are >= 0; otherwise the better edge update is returned.
    Geometry is recomputed from the coordinates: cheaper than loading stored matrices.
    """
    eax = ax - cx
    eay = ay - cy
    eaz = az - cz
    ebx = bx - cx
    eby = by - cy
    ebz = bz - cz
    gaa = eax * eax + eay * eay + eaz * eaz
    gbb = ebx * ebx + eby * eby + ebz * ebz
    gab = eax * ebx + eay * eby + eaz * ebz
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
#: the rank of a vertex not accepted (yet): larger than every acceptance rank
UNRANKED = np.iinfo(np.int32).max


@nb.njit(cache=True, nogil=True)
def triangle_means(c, triangles, out):
    """``out[t]`` = the mean of the vertex values ``c`` at triangle ``t``'s corners, summed
    in numpy's order (``c[triangles].mean(axis=1)`` bit for bit, without its (m, 3) copy:
    a route mesh of 54,000 triangles in 0.1 ms instead of 1 ms)."""
    for t in range(triangles.shape[0]):
        out[t] = (c[triangles[t, 0]] + c[triangles[t, 1]] + c[triangles[t, 2]]) / 3.0


@nb.njit(cache=True, nogil=True)
def march(
    T, fixed_vertices, fixed_values, pts, vt_ptr, vt_corner, ds_ptr, ds_corner,
    ray_ptr, ray_idx, ray_cost, f_tri, ordered, order,
):
    """Fast marching from the fixed (exit) vertices; fills ``T`` in place and returns the
    number of vertices accepted. ``pts`` (n, 3) [m]: a room's vertices with z = 0, or a
    building surface's in 3-D.

    ``vt_corner`` and ``ds_corner`` are the corner and split-target rows described in the
    module docstring, ``ray_cost[k]`` the cost of corner ray ``k`` and ``f_tri`` the
    slowness per triangle [s/m]. Unreached vertices keep ``inf``. ``ordered``: vertices of
    equal value are accepted in the order of their numbers (else in the heap's order, which
    depends on the march's history); then the march is a function of the costs alone, which
    :func:`march_from` needs. ``order`` (n,) int32, or empty: filled with the vertices in
    the order they were accepted.
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
            _sift_up(hv, hk, pos, size, v, T[v], ordered)
            size += 1
        fixed[v] = True
    none = np.empty(0, np.int32)  # (no rank, no sources)
    if ordered:  # (each a copy of the loop compiled for its tie rule)
        return _march_loop(T, pos, none, fixed, hv, hk, size, 0, none, pts, vt_ptr,
                           vt_corner, ds_ptr, ds_corner, ray_ptr, ray_idx, ray_cost, f_tri,
                           True, order)
    return _march_loop(T, pos, none, fixed, hv, hk, size, 0, none, pts, vt_ptr, vt_corner,
                       ds_ptr, ds_corner, ray_ptr, ray_idx, ray_cost, f_tri, False, order)


@nb.njit(cache=True, nogil=True)
def march_from(
    T, phi0, rank0, order0, k0, pos, fixed, mark, rev_ptr, rev_idx, pts, vt_ptr, vt_corner,
    ds_ptr, ds_corner, ray_ptr, ray_idx, ray_cost, f_tri, order,
):
    """The ordered :func:`march` for the costs ``f_tri``, ``ray_cost`` from the state after
    its first ``k0`` acceptances, where those are known to be the first ``k0`` of an earlier
    ordered march: ``phi0``, the place of each vertex in its order ``rank0``
    (:data:`UNRANKED` if never accepted) and its order ``order0``. That holds for a value
    ``m`` such that the earlier march accepted ``k0`` vertices before the first at or above
    ``m``, when every triangle whose cost differs from the earlier march's has all its
    vertices at ``phi0 >= m`` and every corner ray whose cost differs has ``phi0`` at its
    source plus the lower of its two costs ``>= m``: those updates then never bring a value
    below ``m`` in either march (a vertex below it uses none of them), so the values below
    ``m`` are offered the same updates and accepted in the same order (the order is a
    function of the values, ties by vertex number). Fills ``T`` (``phi0`` for the first
    ``k0``) and returns the number of vertices accepted.

    The first ``k0`` count as accepted; the updates they would have offered to the others
    are offered again (with the new costs, and each with the corners accepted before it,
    by ``rank0``): the sources are the accepted neighbours of the others (``rev_ptr``,
    ``rev_idx``: CSR by vertex of the vertices that offer it updates through the split
    rows and the corner rays; the triangle neighbours from the corner rows). Then the
    march goes on. ``pos`` (n,) int32 all ``ACCEPTED``, ``fixed`` (n,) bool (the exit
    vertices, which must be among the first ``k0``) and ``mark`` (n,) bool all False are
    work arrays, left as they were: the work grows with the vertices not among the first
    ``k0``, not with the mesh.
    """
    n = T.shape[0]
    for v in range(n):
        T[v] = phi0[v]
    src = np.empty(n, np.int32)
    ns = 0
    for k in range(k0, order0.shape[0]):
        c = order0[k]
        T[c] = np.inf
        pos[c] = FAR
    for k in range(k0, order0.shape[0]):
        c = order0[k]
        for s in range(vt_ptr[c], vt_ptr[c + 1]):
            for r in range(1, 3):
                v = vt_corner[s, r]
                if pos[v] == ACCEPTED and not mark[v]:
                    mark[v] = True
                    src[ns] = v
                    ns += 1
        for s in range(rev_ptr[c], rev_ptr[c + 1]):
            v = rev_idx[s]
            if pos[v] == ACCEPTED and not mark[v]:
                mark[v] = True
                src[ns] = v
                ns += 1
    for k in range(ns):
        mark[src[k]] = False
    hv = np.empty(n, np.int32)
    hk = np.empty(n, np.float64)
    cnt = _march_loop(T, pos, rank0, fixed, hv, hk, 0, k0, src[:ns], pts, vt_ptr, vt_corner,
                      ds_ptr, ds_corner, ray_ptr, ray_idx, ray_cost, f_tri, True, order)
    for k in range(k0, order0.shape[0]):  # (unreached ones, had there been any)
        pos[order0[k]] = ACCEPTED
    return cnt


@nb.njit(cache=True, nogil=True, inline="always")
def _march_loop(
    T, pos, rank, fixed, hv, hk, size, cnt, sources, pts, vt_ptr, vt_corner, ds_ptr,
    ds_corner, ray_ptr, ray_idx, ray_cost, f_tri, ordered, order,
):
    """The march: accept the heap's least vertex, offer its updates to the others, until
    the heap is empty; returns the number accepted (``cnt`` before). First the accepted
    ``sources`` (at ``T``) offer theirs again, as when they were accepted: a corner ``o``
    counts as accepted then if ``rank[o] < rank[v]`` (``pos`` says which vertices take no
    more updates)."""
    record = order.shape[0] > 0
    n_src = sources.shape[0]
    k_src = 0
    rv = 0
    while True:
        replay = k_src < n_src
        if replay:
            v = sources[k_src]
            k_src += 1
            tv = T[v]
            rv = rank[v]
        elif size > 0:
            v = hv[0]
            tv = hk[0]
            pos[v] = ACCEPTED
            if record:
                order[cnt] = v
            cnt += 1
            size -= 1
            if size > 0:
                _sift_down_last(hv, hk, pos, size, ordered)
                # the likely next vertex: fetch its corner rows while v is processed
                nxt = hv[0]
                p0 = vt_ptr[nxt]
                p1 = vt_ptr[nxt + 1]
                _prefetch(vt_corner, p0)
                _prefetch(vt_corner, (p0 + p1) >> 1)
                _prefetch(vt_corner, p1 - 1)
        else:
            break
        vx = pts[v, 0]
        vy = pts[v, 1]
        vz = pts[v, 2]
        # Every candidate for a vertex c is offered inline below (lower T[c], then insert
        # or decrease-key): helper functions taking arrays are 1.4-2.5x slower in numba. A
        # vertex entering the heap gets its list pointers prefetched.
        # the triangles (v, A, B) around v: update A, then B (each with the third corner o)
        for s in range(vt_ptr[v], vt_ptr[v + 1]):
            c = vt_corner[s, 1]
            o = vt_corner[s, 2]
            c_done = pos[c] == ACCEPTED
            o_done = pos[o] == ACCEPTED
            if c_done and o_done:
                continue
            c_acc = c_done
            o_acc = o_done
            if replay:  # (accepted before v)
                c_acc = c_done and rank[c] < rv
                o_acc = o_done and rank[o] < rv
            f = f_tri[vt_corner[s, 0]]
            cx = pts[c, 0]
            cy = pts[c, 1]
            cz = pts[c, 2]
            ox = pts[o, 0]
            oy = pts[o, 1]
            oz = pts[o, 2]
            for r in range(2):
                if r == 1:  # swap roles: B is the target, A the third corner
                    c, o, c_acc, o_acc, c_done = o, c, o_acc, c_acc, o_done
                    cx, cy, cz, ox, oy, oz = ox, oy, oz, cx, cy, cz
                if c_done:
                    continue
                d = vt_corner[s, 3 + r]  # the vertex splitting the obtuse angle at C, or -1
                if o_acc and d < 0:
                    cand = triangle_update(cx, cy, cz, vx, vy, vz, ox, oy, oz, tv, T[o], f)
                else:
                    cand = tv + f * math.sqrt((vx - cx) ** 2 + (vy - cy) ** 2
                                              + (vz - cz) ** 2)  # edge update
                    if d >= 0 and pos[d] == ACCEPTED and (not replay or rank[d] < rv):
                        # the virtual triangle (C, v, D)
                        cv = triangle_update(cx, cy, cz, vx, vy, vz, pts[d, 0], pts[d, 1],
                                             pts[d, 2], tv, T[d], f)
                        if cv < cand:
                            cand = cv
                if cand < T[c] and not fixed[c]:
                    T[c] = cand
                    pc = pos[c]
                    if pc == FAR:
                        _prefetch(vt_ptr, c)
                        _prefetch(ds_ptr, c)
                        _prefetch(ray_ptr, c)
                        _sift_up(hv, hk, pos, size, c, cand, ordered)
                        size += 1
                    else:
                        _sift_up(hv, hk, pos, pc, c, cand, ordered)
        # v as the split vertex D of obtuse corners C: virtual triangles (C, A, v), (C, v, B)
        for s in range(ds_ptr[v], ds_ptr[v + 1]):
            c = ds_corner[s, 1]
            if pos[c] == ACCEPTED:
                continue
            cx = pts[c, 0]
            cy = pts[c, 1]
            cz = pts[c, 2]
            f = f_tri[ds_corner[s, 0]]
            cand = np.inf
            for r in range(2, 4):
                o = ds_corner[s, r]  # A, then B
                if pos[o] == ACCEPTED and (not replay or rank[o] < rv):
                    cv = triangle_update(cx, cy, cz, vx, vy, vz, pts[o, 0], pts[o, 1],
                                         pts[o, 2], tv, T[o], f)
                    if cv < cand:
                        cand = cv
            if cand < T[c] and not fixed[c]:
                T[c] = cand
                pc = pos[c]
                if pc == FAR:
                    _prefetch(vt_ptr, c)
                    _prefetch(ds_ptr, c)
                    _prefetch(ray_ptr, c)
                    _sift_up(hv, hk, pos, size, c, cand, ordered)
                    size += 1
                else:
                    _sift_up(hv, hk, pos, pc, c, cand, ordered)
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
                    _prefetch(vt_ptr, c)
                    _prefetch(ds_ptr, c)
                    _prefetch(ray_ptr, c)
                    _sift_up(hv, hk, pos, size, c, cand, ordered)
                    size += 1
                else:
                    _sift_up(hv, hk, pos, pc, c, cand, ordered)
    return cnt


# ---------------------------------------------------------------- set-up helpers
@nb.njit(cache=True, nogil=True)
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
