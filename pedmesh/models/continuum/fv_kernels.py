"""Compiled kernels of the finite-volume core: first-order edge states, positivity limiting,
flux blending (FCT), divergence and time-step estimates. Model-specific fluxes and sources
live in the model modules."""

from __future__ import annotations

import numba as nb
import numpy as np

from ..._threads import ensure_tbb

ensure_tbb()  # (before numba's first parallel loop: pedmesh._threads)

#: compile options of the finite-volume kernels: ``error_model="numpy"`` drops the
#: ZeroDivisionError check numba puts on every float division (a branch per division that
#: also keeps LLVM from vectorising; the kernels guard their divisions themselves), and
#: ``contract`` lets multiply-adds become fused multiply-adds (one rounding instead of two);
#: ``nogil``: a kernel lets go of Python's lock while it runs, so that the run's output
#: thread (:mod:`pedmesh.run.background`) writes meanwhile instead of waiting for the step
FAST = dict(cache=True, nogil=True, error_model="numpy", fastmath={"contract"})
#: the same for kernels whose loops run on all cores (``numba.prange``). Every such loop
#: writes only its own item (a cell or an edge) and reads what no iteration writes: sums
#: over a cell's edges are gathered per cell (in increasing edge index, the order the
#: serial scatter used), never scattered by edge, so there is no race and the result is
#: bitwise the same with any number of threads
PAR = dict(FAST, parallel=True)
#: the parallel loops deal blocks of BLOCK items (cells or edges) out to NCHUNK chunks in
#: turn: the occupied cells, where the work is, lie together in index order, and two
#: contiguous halves would leave one core idle while the other does the crowd
NCHUNK = 16
BLOCK = 512


@nb.njit(**FAST, inline="always")
def sum_in_order(part, nc):
    """The sum of the chunks' partial sums ``part[:nc]``, added in order (a parallel
    loop's sum that is the same on any number of threads)."""
    out = 0.0
    for c in range(nc):
        out += part[c]
    return out


@nb.njit(**FAST, inline="always")
def short_block(n):
    """The block size for a loop of ``n`` costly items (the wall and exit edges, ~100 to a
    few thousand): at most :data:`BLOCK`, small enough that every chunk gets a block (with
    :data:`BLOCK` a room's hundred exit edges were one block, all on one thread). Only for
    loops whose items each write their own output (no sum over blocks)."""
    return max(1, min(BLOCK, (n + NCHUNK - 1) // NCHUNK))


@nb.njit(**FAST, inline="always")
def zhang_shu_theta(r, mn, rho_eps):
    """Zhang-Shu factor in [0, 1] that scales a cell's point densities about its average
    ``r`` so that the smallest, ``mn``, becomes ``rho_eps`` (0 if the average is not above
    the minimum)."""
    th = (r - rho_eps) / (r - mn) if r > mn else 0.0
    return min(max(th, 0.0), 1.0)


@nb.njit(**PAR)
def positivity_limit(Ve, slot, Vi, qbar, rho_eps, rho_cut, cact):
    """Zhang-Shu scaling of the density at the 6 edge points (rows ``slot[i, :]`` of ``Ve``
    (k, nv)) and the 3 interior points ``Vi`` (m, 3, nv) of every active cell (``cact``) so
    that it is >= rho_eps (where the cell average allows), and first order for all
    variables in cells with an average density below ``rho_cut`` [ped/m^2]. In place."""
    m, _, nv = Vi.shape
    n_i = m
    for c_ in nb.prange(NCHUNK):  # blocks dealt out in turn (load balance)
        for b_ in range(c_, ((n_i) + BLOCK - 1) // BLOCK, NCHUNK):
            for i in range(b_ * BLOCK, min(n_i, (b_ + 1) * BLOCK)):
                if not cact[i]:
                    continue
                r = qbar[i, 0]
                if r < rho_cut:
                    for v in range(nv):
                        for p in range(6):
                            Ve[slot[i, p], v] = qbar[i, v]
                        for p in range(3):
                            Vi[i, p, v] = qbar[i, v]
                    continue
                mn = Vi[i, 0, 0]
                for p in range(1, 3):
                    mn = min(mn, Vi[i, p, 0])
                for p in range(6):
                    mn = min(mn, Ve[slot[i, p], 0])
                if mn < rho_eps:
                    th = zhang_shu_theta(r, mn, rho_eps)
                    for p in range(6):
                        k = slot[i, p]
                        Ve[k, 0] = r + th * (Ve[k, 0] - r)
                    for p in range(3):
                        Vi[i, p, 0] = r + th * (Vi[i, p, 0] - r)


@nb.njit(**PAR)
def gather_cells(Q, e2t, edges, qL, qR, live):
    """First-order edge states: the cell averages on both sides (boundary: qR = qL), at
    each Gauss point of ``qL``/``qR`` (k, g, nv) (g = 1: one state per edge), of the live
    edges (``live`` (n_edges,))."""
    for a in nb.prange(edges.shape[0]):
        e = edges[a]
        if not live[e]:
            continue
        L = e2t[e, 0]
        R = e2t[e, 1]
        if R < 0:
            R = L
        for g in range(qL.shape[1]):
            for v in range(Q.shape[1]):
                qL[a, g, v] = Q[L, v]
                qR[a, g, v] = Q[R, v]


@nb.njit(**PAR)
def integrate_edges(Fpts, lengths, edges, F, live):
    """Edge fluxes F[edges] = l_e/2 (F_g0 + F_g1) from point fluxes (k, 2, nv), or
    F[edges] = l_e F_g0 from one point flux per edge (k, 1, nv); 0 on edges that are not
    ``live``."""
    two = Fpts.shape[1] == 2
    for a in nb.prange(edges.shape[0]):
        e = edges[a]
        if not live[e]:
            for v in range(Fpts.shape[2]):
                F[e, v] = 0.0
            continue
        for v in range(Fpts.shape[2]):
            if two:
                F[e, v] = 0.5 * lengths[e] * (Fpts[a, 0, v] + Fpts[a, 1, v])
            else:
                F[e, v] = lengths[e] * Fpts[a, 0, v]


@nb.njit(**PAR)
def edge_max(a, edges, out, live):
    """out[edges[k]] = max over the row a[k] (the wave speeds at an edge's points); 0 on
    edges that are not ``live``."""
    for k in nb.prange(edges.shape[0]):
        if not live[edges[k]]:
            out[edges[k]] = 0.0
            continue
        v = a[k, 0]
        for g in range(1, a.shape[1]):
            v = max(v, a[k, g])
        out[edges[k]] = v


@nb.njit(**PAR)
def velocity_bounds(Q, nbr, rho_cut, lo, hi, active, cact):
    """Per-cell bounds of each velocity component over the cell and its face neighbours
    (stage start), for the velocity limiter of pressureless transport. Cells with a
    near-vacuum neighbourhood, and cells outside the active set ``cact``, get
    ``active = False``."""
    m = Q.shape[0]
    n_i = m
    for c_ in nb.prange(NCHUNK):  # blocks dealt out in turn (load balance)
        for b_ in range(c_, ((n_i) + BLOCK - 1) // BLOCK, NCHUNK):
            for i in range(b_ * BLOCK, min(n_i, (b_ + 1) * BLOCK)):
                active[i] = cact[i]
                if not cact[i]:
                    continue
                for d in range(2):
                    lo[i, d] = np.inf
                    hi[i, d] = -np.inf
                for k in range(4):
                    j = np.int64(i) if k == 3 else nbr[i, k]
                    if j < 0:
                        continue
                    if Q[j, 0] < rho_cut:
                        active[i] = False
                        break
                    for d in range(2):
                        u = Q[j, 1 + d] / Q[j, 0]
                        if u < lo[i, d]:
                            lo[i, d] = u
                        if u > hi[i, d]:
                            hi[i, d] = u


@nb.njit(**PAR)
def active_set(Q, nbr, e2t, eps, rings, cact, live):
    """The active set of a step: the cells with a density above ``eps`` [ped/m^2] and those
    within ``rings`` face neighbours of them (``cact`` (m,)), and the live edges, whose
    cells are all active (``live`` (n_edges,)). Returns the number of active cells.

    Each pass is a map over the cells or edges, on the threads, ``rings + 1`` of them (a
    parallel region costs about 14 us on Example 2's 5,400 cells, the work of a pass about
    1 us): the first ring reads the densities directly, the rings alternate between
    ``cact`` and a work array so that the last writes ``cact``, the last also counts, and
    one pass marks the live edges."""
    m = Q.shape[0]
    nb_ = (m + BLOCK - 1) // BLOCK
    counts = np.zeros(NCHUNK, np.int64)
    new = np.empty(m, np.bool_)
    if rings <= 0:
        for c_ in nb.prange(NCHUNK):
            k = 0
            for b_ in range(c_, nb_, NCHUNK):
                for i in range(b_ * BLOCK, min(m, (b_ + 1) * BLOCK)):
                    on = Q[i, 0] > eps
                    cact[i] = on
                    k += on
            counts[c_] = k
    else:
        # ring 1 into the array the parity makes the last ring write to cact
        first = cact if rings % 2 == 1 else new
        for c_ in nb.prange(NCHUNK):
            k = 0
            for b_ in range(c_, nb_, NCHUNK):
                for i in range(b_ * BLOCK, min(m, (b_ + 1) * BLOCK)):
                    on = Q[i, 0] > eps
                    if not on:
                        for j_ in range(3):
                            j = nbr[i, j_]
                            if j >= 0 and Q[j, 0] > eps:
                                on = True
                                break
                    first[i] = on
                    k += on
            counts[c_] = k
        for r_ in range(1, rings):
            src, dst = (new, cact) if (rings - r_) % 2 == 1 else (cact, new)
            for c_ in nb.prange(NCHUNK):
                k = 0
                for b_ in range(c_, nb_, NCHUNK):
                    for i in range(b_ * BLOCK, min(m, (b_ + 1) * BLOCK)):
                        on = src[i]
                        if not on:
                            for j_ in range(3):
                                j = nbr[i, j_]
                                if j >= 0 and src[j]:
                                    on = True
                                    break
                        dst[i] = on
                        k += on
                counts[c_] = k
    n_e = e2t.shape[0]
    for c_ in nb.prange(NCHUNK):
        for b_ in range(c_, (n_e + BLOCK - 1) // BLOCK, NCHUNK):
            for e in range(b_ * BLOCK, min(n_e, (b_ + 1) * BLOCK)):
                r = e2t[e, 1]
                live[e] = cact[e2t[e, 0]] and (r < 0 or cact[r])
    return counts.sum()


def cell_edges(mesh) -> np.ndarray:
    """(m, 3) the edges of every cell in increasing index: the order in which the gathering
    kernels below sum a cell's edge terms (the order the former scatter loops over the
    edges added them, so that the sums are bitwise those of the serial code)."""
    return np.ascontiguousarray(np.sort(mesh.triangle_edges, axis=1)).astype(np.int64)


@nb.njit(**PAR)
def fct_blend(FH, FL, e2t, t2e, inv_areas, Q, dt, rho_eps, F, theta, use_vel, vlo, vhi,
              vactive, UL, P, R_, dQ, cact, live):
    """Flux-corrected transport: F = FL + theta (FH - FL) per edge (all components), with
    theta chosen so that after a forward-Euler stage every cell keeps

    * density >= rho_eps (or its low-order value if that is lower), and, with ``use_vel``,
    * each velocity component within ``[vlo, vhi]`` of its cell (the bounds the first-order
      scheme respects for pressureless transport), in cells with ``vactive``.

    Each constraint is linear in the conserved state (``m_d - lo rho >= 0``, ``hi rho - m_d
    >= 0``), so Zalesak's recipe applies: per cell and constraint the available margin of
    the low-order update over the decreases the antidiffusive fluxes would cause, and per
    edge the smallest factor of the cells it would decrease. ``FH``, ``FL`` (k, nv) are edge
    fluxes integrated over the edges, oriented L -> R; ``t2e`` (m, 3) each cell's edges
    (:func:`cell_edges`); ``inv_areas`` = ``1/|T_i|`` [1/m^2]. ``UL`` (nv, m), ``P`` and ``R_``
    (5, m) are work arrays. ``dQ`` (m, nv) receives the divergence of F, as
    :func:`divergence` computes it. Three parallel passes: cells (margins), edges (factors
    and blended fluxes), cells (divergence). Only the active cells ``cact`` and the
    ``live`` edges (both cells active) take part; the others get zero flux and change.
    """
    ne, nv = FH.shape
    m = inv_areas.shape[0]
    nc = 5 if (use_vel and nv == 3) else 1
    if nc == 1:
        _fct_density(FH, FL, e2t, t2e, inv_areas, Q, dt, rho_eps, F, theta, UL[0], P[0],
                     R_[0], dQ, cact, live)
        return
    # per cell: the low-order update, and per constraint c (g = a . U with a given by
    # (c, i)) the decreases the antidiffusive fluxes would cause, then the factor R_
    n_i = m
    for c_ in nb.prange(NCHUNK):  # blocks dealt out in turn (load balance)
        for b_ in range(c_, ((n_i) + BLOCK - 1) // BLOCK, NCHUNK):
            for i in range(b_ * BLOCK, min(n_i, (b_ + 1) * BLOCK)):
                if not cact[i]:
                    continue
                for v in range(nv):
                    UL[v, i] = Q[i, v]
                for c in range(nc):
                    P[c, i] = 0.0
                for k in range(3):
                    e = t2e[i, k]
                    sgn = 1.0 if e2t[e, 0] == i else -1.0  # flux out of i is +sgn F
                    for v in range(nv):
                        UL[v, i] -= sgn * (FL[e, v] * dt) * inv_areas[i]
                    for c in range(nc):
                        if c > 0 and not vactive[i]:
                            continue
                        da = _constraint_dot(c, i, FH, FL, e, vlo, vhi)
                        dec = sgn * da * dt * inv_areas[i]  # decrease of g_i
                        if dec > 0.0:
                            P[c, i] += dec
                for c in range(nc):
                    R_[c, i] = 1.0
                    if P[c, i] > 0.0:
                        if c == 0:
                            g = UL[0, i] - rho_eps
                        else:
                            d = (c - 1) // 2
                            if (c - 1) % 2 == 0:
                                g = UL[1 + d, i] - vlo[i, d] * UL[0, i]
                            else:
                                g = vhi[i, d] * UL[0, i] - UL[1 + d, i]
                        if g < 0.0:
                            g = 0.0
                        R_[c, i] = min(1.0, g / P[c, i])
    n_e = ne
    for c_ in nb.prange(NCHUNK):  # blocks dealt out in turn (load balance)
        for b_ in range(c_, ((n_e) + BLOCK - 1) // BLOCK, NCHUNK):
            for e in range(b_ * BLOCK, min(n_e, (b_ + 1) * BLOCK)):
                if not live[e]:
                    theta[e] = 1.0
                    for v in range(nv):
                        F[e, v] = 0.0
                    continue
                th = 1.0
                for side in range(2):
                    i = e2t[e, side]
                    if i < 0:
                        continue
                    sgn = 1.0 if side == 0 else -1.0
                    for c in range(nc):
                        if c > 0 and not vactive[i]:
                            continue
                        if sgn * _constraint_dot(c, i, FH, FL, e, vlo, vhi) > 0.0 and R_[c, i] < th:
                            th = R_[c, i]
                theta[e] = th
                for v in range(nv):
                    F[e, v] = FL[e, v] + th * (FH[e, v] - FL[e, v])
    _gather_divergence(F, e2t, t2e, inv_areas, dQ, cact)


@nb.njit(**PAR)
def _fct_density(FH, FL, e2t, t2e, inv_areas, Q, dt, rho_eps, F, theta, UL, P, R_, dQ, cact,
                 live):
    """:func:`fct_blend` with the density constraint alone (the common case), its loops
    over constraints and sides written out."""
    ne, nv = FH.shape
    m = inv_areas.shape[0]
    n_i = m
    for c_ in nb.prange(NCHUNK):  # blocks dealt out in turn (load balance)
        for b_ in range(c_, ((n_i) + BLOCK - 1) // BLOCK, NCHUNK):
            for i in range(b_ * BLOCK, min(n_i, (b_ + 1) * BLOCK)):
                if not cact[i]:
                    continue
                ul = Q[i, 0]
                pi = 0.0
                for k in range(3):
                    e = t2e[i, k]
                    f = FL[e, 0] * dt
                    d = (FH[e, 0] - FL[e, 0]) * dt  # > 0: the correction takes density from L
                    if e2t[e, 0] == i:
                        ul -= f * inv_areas[i]
                        if d > 0.0:
                            pi += d * inv_areas[i]
                    else:
                        ul += f * inv_areas[i]
                        if d < 0.0:
                            pi -= d * inv_areas[i]
                UL[i] = ul
                P[i] = pi
                r = 1.0
                if pi > 0.0:
                    g = ul - rho_eps
                    if g < 0.0:
                        g = 0.0
                    r = min(1.0, g / pi)
                R_[i] = r
    n_e = ne
    for c_ in nb.prange(NCHUNK):  # blocks dealt out in turn (load balance)
        for b_ in range(c_, ((n_e) + BLOCK - 1) // BLOCK, NCHUNK):
            for e in range(b_ * BLOCK, min(n_e, (b_ + 1) * BLOCK)):
                if not live[e]:
                    theta[e] = 1.0
                    for v in range(nv):
                        F[e, v] = 0.0
                    continue
                L = e2t[e, 0]
                R = e2t[e, 1]
                d = FH[e, 0] - FL[e, 0]
                th = 1.0
                if d > 0.0:
                    th = R_[L]
                elif d < 0.0 and R >= 0:
                    th = R_[R]
                theta[e] = th
                for v in range(nv):
                    F[e, v] = FL[e, v] + th * (FH[e, v] - FL[e, v])
    _gather_divergence(F, e2t, t2e, inv_areas, dQ, cact)


@nb.njit(**FAST, inline="always")
def _constraint_dot(c, i, FH, FL, e, vlo, vhi):
    """a_c(i) . (FH - FL)_e for constraint c of cell i."""
    ar = FH[e, 0] - FL[e, 0]
    if c == 0:
        return ar
    d = (c - 1) // 2
    am = FH[e, 1 + d] - FL[e, 1 + d]
    if (c - 1) % 2 == 0:
        return am - vlo[i, d] * ar
    return vhi[i, d] * ar - am


@nb.njit(**PAR)
def _gather_divergence(F, e2t, t2e, inv_areas, out, cact):
    m, nv = out.shape
    n_i = m
    for c_ in nb.prange(NCHUNK):  # blocks dealt out in turn (load balance)
        for b_ in range(c_, ((n_i) + BLOCK - 1) // BLOCK, NCHUNK):
            for i in range(b_ * BLOCK, min(n_i, (b_ + 1) * BLOCK)):
                for v in range(nv):
                    out[i, v] = 0.0
                if not cact[i]:
                    continue
                for k in range(3):
                    e = t2e[i, k]
                    if e2t[e, 0] == i:
                        for v in range(nv):
                            out[i, v] -= F[e, v] * inv_areas[i]
                    else:
                        for v in range(nv):
                            out[i, v] += F[e, v] * inv_areas[i]


@nb.njit(**FAST)
def divergence(F, e2t, t2e, inv_areas, out, cact):
    """out_i = ``-(1/|T_i|)`` sum over its edges ``t2e[i]`` of the outward edge flux (F oriented
    L -> R) for the active cells ``cact``, 0 elsewhere; ``inv_areas`` = ``1/|T_i|``."""
    _gather_divergence(F, e2t, t2e, inv_areas, out, cact)


@nb.njit(**PAR)
def cfl_dt(alpha_edge, lengths, e2t, t2e, areas, cfl, cact):
    """dt = cfl * ``min_i 2|T_i| / sum_e`` l_e alpha_e over the active cells ``cact`` (the
    positivity bound of first-order Rusanov is cfl = 1); ``t2e`` (m, 3) each cell's edges
    (:func:`cell_edges`)."""
    m = areas.shape[0]
    d = np.empty(m)
    n_i = m
    for c_ in nb.prange(NCHUNK):  # blocks dealt out in turn (load balance)
        for b_ in range(c_, ((n_i) + BLOCK - 1) // BLOCK, NCHUNK):
            for i in range(b_ * BLOCK, min(n_i, (b_ + 1) * BLOCK)):
                if not cact[i]:
                    d[i] = np.inf
                    continue
                s = 0.0
                for k in range(3):
                    e = t2e[i, k]
                    s += lengths[e] * alpha_edge[e]
                d[i] = 2.0 * areas[i] / s if s > 0.0 else np.inf
    best = np.inf
    for i in range(m):
        if d[i] < best:
            best = d[i]
    return cfl * best


@nb.njit(**PAR)
def add_point_mean(S, dQ, cact):
    """dQ[i] += mean of the source at the 3 interior points of cell i (S is (3 m, nv)), for
    the active cells ``cact``."""
    m, nv = dQ.shape
    for i in nb.prange(m):
        if not cact[i]:
            continue
        for v in range(nv):
            dQ[i, v] += (S[3 * i, v] + S[3 * i + 1, v] + S[3 * i + 2, v]) / 3.0


@nb.njit(**PAR)
def launch_threads(a):
    """A trivial parallel loop (``a[i] = i``): running it starts numba's threading layer."""
    for i in nb.prange(a.shape[0]):
        a[i] = i


#: the options of the kernels that must round as numpy does (no fused multiply-adds)
EXACT_PAR = dict(cache=True, nogil=True, parallel=True)


@nb.njit(**EXACT_PAR)
def stage_update(Q, dt, L, V):
    """``V = Q + dt L`` (as numpy rounds it), the cells in parallel."""
    m, nv = Q.shape
    for c_ in nb.prange(NCHUNK):
        for b_ in range(c_, (m + BLOCK - 1) // BLOCK, NCHUNK):
            for i in range(b_ * BLOCK, min(m, (b_ + 1) * BLOCK)):
                for v in range(nv):
                    V[i, v] = Q[i, v] + dt * L[i, v]


@nb.njit(**EXACT_PAR)
def copy_cells(Q, out):
    """``out[:] = Q``, the cells in parallel."""
    m, nv = Q.shape
    for c_ in nb.prange(NCHUNK):
        for b_ in range(c_, (m + BLOCK - 1) // BLOCK, NCHUNK):
            for i in range(b_ * BLOCK, min(m, (b_ + 1) * BLOCK)):
                for v in range(nv):
                    out[i, v] = Q[i, v]


@nb.njit(**EXACT_PAR)
def fingerprint(Q):
    """The sum of every entry of ``Q`` (chunks in parallel, added in order: the same on any
    number of threads): a cheap check that a state has not changed."""
    m, nv = Q.shape
    part = np.zeros(NCHUNK)
    for c_ in nb.prange(NCHUNK):
        acc = 0.0
        for b_ in range(c_, (m + BLOCK - 1) // BLOCK, NCHUNK):
            for i in range(b_ * BLOCK, min(m, (b_ + 1) * BLOCK)):
                for v in range(nv):
                    acc += Q[i, v]
        part[c_] = acc
    return sum_in_order(part, NCHUNK)


@nb.njit(**EXACT_PAR)
def heun_combine(Q, S, out):
    """``out = 0.5 Q + 0.5 S`` (as numpy rounds it), the cells in parallel; returns the
    smallest and the largest density of ``out`` and whether every entry is finite (each
    chunk's, combined: exact, whatever the number of threads)."""
    m, nv = Q.shape
    lo = np.full(NCHUNK, np.inf)
    hi = np.full(NCHUNK, -np.inf)
    ok = np.ones(NCHUNK, np.bool_)
    for c_ in nb.prange(NCHUNK):
        a, b, good = np.inf, -np.inf, True
        for b_ in range(c_, (m + BLOCK - 1) // BLOCK, NCHUNK):
            for i in range(b_ * BLOCK, min(m, (b_ + 1) * BLOCK)):
                for v in range(nv):
                    x = 0.5 * Q[i, v] + 0.5 * S[i, v]
                    out[i, v] = x
                    if not np.isfinite(x):
                        good = False
                r = out[i, 0]
                if r < a:
                    a = r
                if r > b:
                    b = r
        lo[c_] = a
        hi[c_] = b
        ok[c_] = good
    return lo.min(), hi.max(), ok.all()


@nb.njit(**FAST)
def cell_total(areas, Q):
    """``sum_i |T_i| Q[i, 0]``: the number of pedestrians in the cells [ped]. (A compiled loop,
    not ``np.dot``: OpenBLAS hands a dot product of this size to a second thread, which
    waits a full time slice, about 4 ms, when the other core is busy.)"""
    m = areas.shape[0]
    s0 = s1 = s2 = s3 = 0.0  # four partial sums: shorter error chains, and faster
    n4 = m - m % 4
    for i in range(0, n4, 4):
        s0 += areas[i] * Q[i, 0]
        s1 += areas[i + 1] * Q[i + 1, 0]
        s2 += areas[i + 2] * Q[i + 2, 0]
        s3 += areas[i + 3] * Q[i + 3, 0]
    for i in range(n4, m):
        s0 += areas[i] * Q[i, 0]
    return (s0 + s1) + (s2 + s3)
