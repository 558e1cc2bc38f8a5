"""Compiled kernels of the social force model.

All kernels work on flat arrays of the ``n`` active pedestrians (rows ``0..n-1``). Neighbours
come from a cell list (counting sort into square cells at least as large as the search
radius) searched over half of the 3x3 stencil, so every pair is visited once and its force
is added to one pedestrian and subtracted from the other: Newton's third law holds to
round-off, and the search is O(n).

The per-step work runs on numba's threads (``prange``; the caller sets their number with
``numba.set_num_threads``), and its results are bitwise the same on any number of threads,
and the same as those of the serial loops these kernels replaced. Each thread writes only
its own pedestrians, and every sum is taken in the serial loop's order. The per-pedestrian
work (walls, route, driving term, Runge-Kutta stages, wall crossings and exits) is split
by pedestrian. The pair work is split by cell: each thread takes a run of consecutive cells
(a *block*, :func:`pair_blocks`) and repeats the serial loop over its own cells, adding a
pair's terms only to its own pedestrians; a pedestrian's terms from pairs in the cells just
before its block (at most one row of cells back: the half stencil reaches ``ny + 1`` cells
ahead) are added first, by its own thread going through those pairs again (the block's
*halo*). So each pedestrian's forces and density are summed term by term in the serial
order (:func:`list_pairs`, :func:`pair_accel_blocks`), and the pair list is the serial one.
On one thread there is one block and no halo: the serial loops themselves.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from ..._threads import ensure_tbb

ensure_tbb()  # (before numba's first parallel loop: pedmesh._threads)

from ...eikonal.direction import _inside_packed, _interpolate  # noqa: E402
from ...speed import shape  # noqa: E402
from .crowding import crowd_factor_at  # noqa: E402
from .forces import NO_CONE, cone_weights, pair_force, pair_terms, unit_direction  # noqa: E402
from .hinge_kernels import hinge_accel, hinge_density  # noqa: E402

EXIT_KIND = 3  # BoundaryKind.EXIT
#: barycentric margin of the division-free "still inside its triangle" test; anything
#: closer to an edge goes through the exact test and the walk, as before
INSIDE_MARGIN = 1e-9
#: pedestrians per chunk of the per-pedestrian loops that call the direction interpolation
#: once per chunk
CHUNK = 256


# ------------------------------------------------------------------ cell list
@nb.njit(cache=True, nogil=True, inline="always")
def _cell_of(px, py, x0, y0, inv_cell, nx, ny):
    ci = int((px - x0) * inv_cell)
    cj = int((py - y0) * inv_cell)
    ci = min(max(ci, 0), nx - 1)
    cj = min(max(cj, 0), ny - 1)
    return ci * ny + cj


@nb.njit(parallel=True, cache=True, nogil=True)
def build_cells(x, n, x0, y0, inv_cell, nx, ny, cell_start, cell_order):
    """Counting sort of pedestrians into cells; ``cell_start`` has nx*ny+1 entries. Within
    a cell the pedestrians are in the order of their rows."""
    nc = nx * ny
    cell_of = np.empty(n, np.int64)
    for i in nb.prange(n):
        cell_of[i] = _cell_of(x[i, 0], x[i, 1], x0, y0, inv_cell, nx, ny)
    for c in range(nc + 1):
        cell_start[c] = 0
    for i in range(n):
        cell_start[cell_of[i] + 1] += 1
    for c in range(nc):
        cell_start[c + 1] += cell_start[c]
    fill = cell_start[:nc].copy()
    for i in range(n):
        c = cell_of[i]
        cell_order[fill[c]] = i
        fill[c] += 1


@nb.njit(cache=True, nogil=True)
def update_cells(x, n, x0, y0, inv_cell, nx, ny, cell_start, cell_order):
    """:func:`build_cells` into arrays that hold a cell list already (of other positions,
    from either function; zeros: of nobody), the same result: only the entries of
    ``cell_start`` between the lowest and the highest cell with someone in it, then or now,
    are rewritten (below them it is 0, above them the head count), so that the work grows
    with the crowd's extent, not with the grid (a building's atlas is mostly empty)."""
    nc = nx * ny
    prev = cell_start[nc]
    cell_of = np.empty(n, np.int64)
    lo, hi = nc, -1  # the cells with someone in them now
    for i in range(n):
        c = _cell_of(x[i, 0], x[i, 1], x0, y0, inv_cell, nx, ny)
        cell_of[i] = c
        lo = min(lo, c)
        hi = max(hi, c)
    a, b = lo, hi
    if prev > 0:  # and then: the first with cell_start[c + 1] > 0, the last with < prev
        a = min(a, np.searchsorted(cell_start, 0, side="right") - 1)
        b = max(b, np.searchsorted(cell_start, prev, side="left") - 1)
    if n != prev:
        b = nc - 1
    if b < a:
        return
    for c in range(a + 1, b + 2):
        cell_start[c] = 0
    for i in range(n):
        cell_start[cell_of[i] + 1] += 1
    for c in range(a + 1, b + 1):
        cell_start[c + 1] += cell_start[c]
    if n == 0:
        return
    fill = cell_start[lo:hi + 1].copy()
    for i in range(n):
        c = cell_of[i] - lo
        cell_order[fill[c]] = i
        fill[c] += 1


# ------------------------------------------------------------------ pair list + density
@nb.njit(cache=True, nogil=True, inline="always")
def _stencil_cell(ci, cj, q, nx, ny):
    """Cell ``q`` of the half stencil of cell (ci, cj): q = 0 the cell itself, then
    (+1,-1), (+1,0), (+1,+1), (0,+1); -1 if it lies outside the grid."""
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
        return -1
    return ni * ny + nj


@nb.njit(cache=True, nogil=True, inline="always")
def _cell_work(ci, cj, cell_start, nx, ny):
    """The distances the pair search tests for the pedestrians of cell (``ci``, ``cj``):
    each with the later ones of its own cell and with everyone in the four other cells of
    its half stencil (plus one per pedestrian, for an empty stencil)."""
    c = ci * ny + cj
    m = cell_start[c + 1] - cell_start[c]
    if m == 0:
        return 0
    near = 0
    for q in range(1, 5):
        c2 = _stencil_cell(ci, cj, q, nx, ny)
        if c2 >= 0:
            near += cell_start[c2 + 1] - cell_start[c2]
    return m * (m - 1) // 2 + m * near + m


@nb.njit(parallel=True, cache=True, nogil=True)
def pair_blocks(n, cell_start, cell_order, nx, ny, nblocks):
    """Cut the cells into ``nblocks`` runs of consecutive cells with about equal work:
    ``lay`` (nblocks + 1, 5) int64 with block b's first cell in ``lay[b, 0]``
    (``lay[nblocks, 0]`` = the number of cells); the other columns are filled by
    :func:`list_pairs`. ``pos`` (n,): each pedestrian's place in the cell order (the
    inverse of ``cell_order``): a block's pedestrians are the places ``cell_start[lay[b,
    0]] ...``, and its thread sums into arrays by place, so that two threads never write
    to the same stretch of memory (empty for one block, which sums by row).

    A cell's work is the number of distances its pedestrians test (:func:`_cell_work`):
    it grows with the square of the local density, so a crowd packed at a door would
    leave one thread with most of it if the cells were cut by head count. Where the cut
    falls changes no result (the sums are taken in the serial order on any blocks)."""
    nc = nx * ny
    lay = np.zeros((nblocks + 1, 5), np.int64)
    if nblocks > 1:
        # each cell's work and each row's sum on the threads; block b then starts at the
        # first cell with the work before it >= b / nblocks of the total, found by going
        # through the rows' sums and only the cells of the rows where a cut falls
        work = np.empty(nc, np.int64)
        row = np.empty(nx, np.int64)
        for ri in nb.prange(nx):
            ci = np.int64(ri)
            s = 0
            for cj in range(ny):
                w = _cell_work(ci, cj, cell_start, nx, ny)
                work[ci * ny + cj] = w
                s += w
            row[ci] = s
        total = 0
        for ci in range(nx):
            total += row[ci]
        b = 1
        done = 0
        for ci in range(nx):
            if b < nblocks and (done + row[ci]) * nblocks >= b * total:
                for c in range(ci * ny, (ci + 1) * ny):
                    while b < nblocks and done * nblocks >= b * total:
                        lay[b, 0] = c
                        b += 1
                    done += work[c]
            else:
                done += row[ci]
        while b < nblocks:
            lay[b, 0] = nc
            b += 1
    lay[nblocks, 0] = nc
    pos = np.empty(n if nblocks > 1 else 0, np.int64)  # (one block sums by row)
    if nblocks > 1:
        for a in nb.prange(n):
            pos[cell_order[a]] = a
    return lay, pos


@nb.njit(cache=True, nogil=True, inline="always")
def _block_of(lay, c):
    """The block of cell ``c`` (the last one starting at or before it)."""
    b = np.searchsorted(lay[:, 0], c, side="right") - 1
    while lay[b + 1, 0] <= c:  # (skip empty blocks)
        b += 1
    return b


@nb.njit(parallel=True, cache=True, nogil=True)
def list_pairs(x, n, cell_start, cell_order, nx, ny, rc, rc_near, pi, pj, rho, rc_d, R,
               with_density, lay, pos, e, cone):
    """:func:`build_pairs` on threads, one block of cells (:func:`pair_blocks`) each.

    Block b searches its own cells in the serial order and stores its pairs in its share
    ``b cap / B ... (b + 1) cap / B`` of ``pi``/``pj`` (B blocks; near ones from the front,
    far ones from the back); the shares are then moved together into one list in block
    order, which is the serial search's list. A pedestrian's density gets its terms as a
    partner ``j`` from pairs whose ``i`` lies in a lower cell, up to ``ny + 1`` cells
    before its own: block b first goes through those pairs of the cells just before its
    first one (its *halo*, to add their terms to its own pedestrians only), then through
    its own cells, adding a pair's term to ``j`` only if ``j`` is its own. So every
    density is summed in the serial order: the self term, then the terms in the order the
    serial search added them.

    Fills ``lay[b, 1]`` (block b's first near pair), ``lay[b, 2]`` (its far pairs before
    block b's), ``lay[b, 3]`` (the first near pair of its halo), ``lay[b, 4]`` (the far
    pairs before those of its halo). ``pos``: from :func:`pair_blocks`. Returns ``(n_near,
    n_far)``, or ``(-1, -1)`` if the list, or a block's share of ``pi``/``pj``, is too
    small. ``e``, ``cone``: the desired directions and the density cone
    (:func:`~pedmesh.models.sfm.forces.cone_weights`; ``NO_CONE``: the isotropic kernel).
    """
    rc2 = rc * rc
    rn2 = rc_near * rc_near
    rd2 = rc_d * rc_d
    w0 = 1.0 / (math.pi * R * R)
    invR2 = 1.0 / (R * R)
    cap = pi.shape[0]
    nblocks = lay.shape[0] - 1
    counts = np.zeros((nblocks, 3), np.int64)  # near, far, 1 if the share overflowed
    # several blocks sum the densities by place in the cell order (a block's own places
    # are one stretch of memory), one sums them into rho
    many = nblocks > 1
    racc = np.empty(n if with_density and many else 0)
    acc = racc if many else rho
    # each block's halo starts at cell hc[b]; the near and far pairs before it in the block
    # that holds it: halo[b] (only cells with someone in them are visited: on a large grid,
    # e.g. a building's atlas, most are empty)
    hc = np.empty(nblocks, np.int64)
    for b in range(nblocks):
        hc[b] = max(lay[b, 0] - ny - 1, 0)
    halo = np.zeros((nblocks, 2), np.int64)
    for bb in nb.prange(nblocks):
        b = np.int64(bb)
        c0 = lay[b, 0]
        c1 = lay[b + 1, 0]
        lo = (b * cap) // nblocks
        size = ((b + 1) * cap) // nblocks - lo
        if with_density:
            for a in range(cell_start[c0], cell_start[c1]):
                acc[a if many else cell_order[a]] = w0
        if with_density:  # the halo: the terms its pedestrians get from the cells before
            for c in range(max(c0 - ny - 1, 0), c0):
                ci = c // ny
                cj = c % ny
                for q in range(1, 5):
                    c2 = _stencil_cell(ci, cj, q, nx, ny)
                    if c2 < c0 or c2 >= c1:
                        continue
                    for a in range(cell_start[c], cell_start[c + 1]):
                        i = cell_order[a]
                        xi = x[i, 0]
                        yi = x[i, 1]
                        for b2 in range(cell_start[c2], cell_start[c2 + 1]):
                            j = cell_order[b2]
                            dx = xi - x[j, 0]
                            dy = yi - x[j, 1]
                            d2 = dx * dx + dy * dy
                            if d2 < rd2:
                                _, wj = cone_weights(dx, dy, d2, cone, 0.0, 0.0, e[j, 0],
                                                     e[j, 1])
                                acc[b2 if many else j] += w0 * math.exp(-d2 * invR2) * wj
        m_near = 0
        m_far = 0
        pb = 0  # the next halo start not yet passed
        c = c0
        while c < c1:
            s0 = cell_start[c]
            s1 = cell_start[c + 1]
            if s0 == s1:  # an empty cell: on to the next one with someone in it
                c += np.searchsorted(cell_start[c:c1 + 1], s0, side="right") - 1
                continue
            while pb < nblocks and hc[pb] <= c:
                if hc[pb] >= c0:
                    halo[pb, 0] = m_near
                    halo[pb, 1] = m_far
                pb += 1
            ci = c // ny
            cj = c % ny
            for q in range(5):
                c2 = _stencil_cell(ci, cj, q, nx, ny)
                if c2 < 0:
                    continue
                mine = c2 < c1  # are the partners in this stencil cell this block's own?
                t1 = cell_start[c2 + 1]
                for a in range(s0, s1):
                    i = cell_order[a]
                    xi = x[i, 0]
                    yi = x[i, 1]
                    rhoi = 0.0
                    t0 = a + 1 if q == 0 else cell_start[c2]
                    for b2 in range(t0, t1):
                        j = cell_order[b2]
                        dx = xi - x[j, 0]
                        dy = yi - x[j, 1]
                        d2 = dx * dx + dy * dy
                        if with_density and d2 < rd2:
                            w = w0 * math.exp(-d2 * invR2)
                            wi, wj = cone_weights(dx, dy, d2, cone, e[i, 0], e[i, 1],
                                                  e[j, 0], e[j, 1])
                            rhoi += w * wi
                            if mine:
                                acc[b2 if many else j] += w * wj
                        if d2 < rn2:
                            if m_near + m_far < size:
                                pi[lo + m_near] = i
                                pj[lo + m_near] = j
                            m_near += 1
                        elif d2 < rc2 and not with_density:
                            m_far += 1
                            if m_near + m_far <= size:
                                pi[lo + size - m_far] = i
                                pj[lo + size - m_far] = j
                    if with_density:
                        acc[a if many else i] += rhoi
            c += 1
        while pb < nblocks and hc[pb] < c1:
            if hc[pb] >= c0:
                halo[pb, 0] = m_near
                halo[pb, 1] = m_far
            pb += 1
        counts[b, 0] = m_near
        counts[b, 1] = m_far
        counts[b, 2] = 1 if m_near + m_far > size else 0
    # the blocks' pairs before each block, and the list's length
    tot_near = 0
    tot_far = 0
    bad = False
    for b in range(nblocks):
        lay[b, 1] = tot_near
        lay[b, 2] = tot_far
        tot_near += counts[b, 0]
        tot_far += counts[b, 1]
        bad = bad or counts[b, 2] != 0
    lay[nblocks, 1] = tot_near
    lay[nblocks, 2] = tot_far
    if with_density and many:
        for i in nb.prange(n):
            rho[i] = racc[pos[i]]
    if bad or tot_near + tot_far > cap:
        return -1, -1
    # move the shares together: the far pairs through a copy (they may lie where near ones
    # go), the near ones forward in block order (each only ever moves towards the front)
    if nblocks > 1:
        far = np.empty((tot_far, 2), np.int64)
        if tot_far > 0:  # (none with the density held over a step: no parallel loop)
            for bb in nb.prange(nblocks):
                b = np.int64(bb)
                hi = ((b + 1) * cap) // nblocks
                for t in range(1, counts[b, 1] + 1):
                    far[lay[b, 2] + t - 1, 0] = pi[hi - t]
                    far[lay[b, 2] + t - 1, 1] = pj[hi - t]
        for b in range(1, nblocks):
            lo = (b * cap) // nblocks
            dst = lay[b, 1]
            for t in range(counts[b, 0]):
                pi[dst + t] = pi[lo + t]
                pj[dst + t] = pj[lo + t]
        if tot_far > 0:
            for t in nb.prange(tot_far):
                pi[cap - 1 - t] = far[t, 0]
                pj[cap - 1 - t] = far[t, 1]
    # each block's halo: the pairs from the ny + 1 cells before its first one (a few
    # searches: no parallel loop)
    for b in range(nblocks):
        c0 = lay[b, 0]
        hc = max(c0 - ny - 1, 0)
        if hc >= c0:
            lay[b, 3] = lay[b, 1]
            lay[b, 4] = lay[b, 2]
            continue
        h = _block_of(lay, hc)
        lay[b, 3] = lay[h, 1] + halo[b, 0]
        lay[b, 4] = lay[h, 2] + halo[b, 1]
    return tot_near, tot_far


def build_pairs(x, n, cell_start, cell_order, nx, ny, rc, rc_near, pi, pj, rho, rc_d, R,
                with_density, e=None, cone=None):
    """All pairs closer than ``rc``, each once (i from the lower cell), split in two groups:
    the *near* pairs (closer than ``rc_near``) fill ``pi``/``pj`` from the front, the *far*
    ones from the back. Returns ``(n_near, n_far)``, or ``(-1, -1)`` if ``pi``/``pj`` are
    too small (for the list, or for one thread's share of it). The cells must be at least
    ``rc`` wide.

    The pair forces only act within the near group (``rc_near`` = force cut-off + skin), so
    the far group needs the density kernel alone. With ``with_density`` the Gaussian kernel
    densities (cut-off ``rc_d``, self term included) at these positions go into ``rho`` on
    the way, and the far pairs are not stored (``n_far = 0``).

    The list is in the order of the serial search: cell by cell, in a cell stencil cell by
    stencil cell (the cell itself, then (+1,-1), (+1,0), (+1,+1), (0,+1)), in it pedestrian
    ``i`` by pedestrian (in the cell's order) and their partners ``j`` in cell order; the
    far pairs in that order from the back. On numba's threads (:func:`list_pairs`), with the
    same list and densities on any number.
    """
    lay, pos = pair_blocks(n, cell_start, cell_order, nx, ny, nb.get_num_threads())
    if e is None:  # (the isotropic kernel)
        e, cone = np.zeros((max(n, 1), 2)), NO_CONE
    return list_pairs(x, n, cell_start, cell_order, nx, ny, rc, rc_near, pi, pj, rho, rc_d,
                      R, with_density, lay, pos, e, cone)


def pair_accel_list(x, v, n, pi, pj, n_near, n_far, rc_f, rc_d, rad, A, B, k, kappa, m, R, F,
                    rho, with_density, rs, lam, e, cone=None):
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

    The serial loop over the list (one block of :func:`pair_accel_blocks`, which takes
    the list's blocks from :func:`list_pairs` to give the same on threads).
    """
    lay = np.zeros((2, 5), np.int64)
    lay[1, 0] = 1
    lay[1, 1] = n_near
    lay[1, 2] = n_far
    one_cell = np.array([0, n], np.int64)
    cone = NO_CONE if cone is None else cone
    pair_accel_blocks(x, v, n, pi, pj, n_near, n_far, lay, np.empty(0, np.int64), one_cell,
                      rc_f, rc_d, rad, A, B, k, kappa, m, R, F, rho, with_density, rs, lam, e,
                      cone)


@nb.njit(parallel=True, cache=True, nogil=True)
def pair_accel_blocks(x, v, n, pi, pj, n_near, n_far, lay, pos, cell_start, rc_f, rc_d, rad,
                      A, B, k, kappa, m, R, F, rho, with_density, rs, lam, e, cone):
    """:func:`pair_accel_list` on threads, over a list from :func:`list_pairs` (``lay``,
    ``pos``, and the cells ``cell_start`` it was made from): block b starts its own
    pedestrians' sums (F from 0, rho from the self term), goes through its halo's pairs
    (adding their terms to its own pedestrians, the partners j), then through its own
    pairs (adding to i, and to j if j is its own), the near ones and then, for the density,
    the far ones, whose halo comes after its own (the serial loop visits the far group from
    the back). Each sum is taken in the serial loop's order, on any number of threads."""
    w0 = 1.0 / (math.pi * R * R)
    invR2 = 1.0 / (R * R)
    invB = 1.0 / B
    inv_m = 1.0 / m
    rc_f2 = rc_f * rc_f
    rc_d2 = rc_d * rc_d
    cap = pi.shape[0]
    nblocks = lay.shape[0] - 1
    # several blocks sum by place in the cell order (a block's own places are one stretch
    # of memory), one into F and rho
    many = nblocks > 1
    Fp = np.empty((n, 2)) if many else F
    rp = np.empty(n if with_density else 0) if many else rho
    for bb in nb.prange(nblocks):
        b = np.int64(bb)
        a0 = cell_start[lay[b, 0]]
        a1 = cell_start[lay[b + 1, 0]]
        for a in range(a0, a1):  # (by place; one block: every row)
            Fp[a, 0] = 0.0
            Fp[a, 1] = 0.0
            if with_density:
                rp[a] = w0
        first = lay[b, 1]  # (the halo's pairs come before)
        for p in range(lay[b, 3], lay[b + 1, 1]):
            i = pi[p]
            j = pj[p]
            own_i = p >= first
            aj = pos[j] if many else j
            own_j = not many or (aj >= a0 and aj < a1)
            if not own_j and not own_i:
                continue
            ai = pos[i] if many else i
            dx = x[i, 0] - x[j, 0]
            dy = x[i, 1] - x[j, 1]
            d2 = dx * dx + dy * dy
            if with_density and d2 < rc_d2:
                w = w0 * math.exp(-d2 * invR2)
                wi, wj = cone_weights(dx, dy, d2, cone, e[i, 0], e[i, 1], e[j, 0], e[j, 1])
                if own_i:
                    rp[ai] += w * wi
                if own_j:
                    rp[aj] += w * wj
            if d2 < rc_f2 and d2 > 0.0:
                aix, aiy, ajx, ajy = pair_terms(
                    dx, dy, math.sqrt(d2), v[j, 0] - v[i, 0], v[j, 1] - v[i, 1],
                    rad[i] + rad[j], rs[i] + rs[j], A, invB, k, kappa, inv_m, lam, e[i, 0],
                    e[i, 1], e[j, 0], e[j, 1])
                if own_i:
                    Fp[ai, 0] += aix
                    Fp[ai, 1] += aiy
                if own_j:
                    Fp[aj, 0] -= ajx
                    Fp[aj, 1] -= ajy
        if not with_density:
            continue
        # the far group from the back: this block's own pairs, then its halo's
        last = cap - lay[b, 2]  # (the halo's pairs come after)
        for p in range(cap - lay[b + 1, 2], cap - lay[b, 4]):
            i = pi[p]
            j = pj[p]
            own_i = p < last
            aj = pos[j] if many else j
            own_j = not many or (aj >= a0 and aj < a1)
            if not own_j and not own_i:
                continue
            dx = x[i, 0] - x[j, 0]
            dy = x[i, 1] - x[j, 1]
            d2 = dx * dx + dy * dy
            if d2 < rc_d2:
                w = w0 * math.exp(-d2 * invR2)
                wi, wj = cone_weights(dx, dy, d2, cone, e[i, 0], e[i, 1], e[j, 0], e[j, 1])
                if own_i:
                    rp[pos[i] if many else i] += w * wi
                if own_j:
                    rp[aj] += w * wj
    if not many:
        return
    for i in nb.prange(n):
        F[i, 0] = Fp[pos[i], 0]
        F[i, 1] = Fp[pos[i], 1]
        if with_density:
            rho[i] = rp[pos[i]]


# ------------------------------------------------------------------ space requirement
@nb.njit(cache=True, nogil=True, inline="always")
def _social_radius(rad_i, ue_i, shrink, h, crowd, cf_i):
    s = rad_i - (shrink * cf_i if crowd else shrink) + h * ue_i
    return s if s < rad_i else rad_i


@nb.njit(cache=True, nogil=True)
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
        rs[i] = _social_radius(rad[i], ue[i], shrink, h, crowd, cf[i])


@nb.njit(cache=True, nogil=True, inline="always")
def crowd_density(rho, c, knee, stretch):
    """The density [ped/m^2] at which the speed law is read for a pedestrian with crowding
    factor ``c`` (:mod:`pedmesh.models.sfm.crowding`): above ``knee`` the law's dense part is
    stretched by ``1 + c (stretch - 1)``, so a crowding person (c = 1) still wants to move
    at densities where a queueing one (c = 0) stands."""
    if rho <= knee or c <= 0.0:
        return rho
    return knee + (rho - knee) / (1.0 + c * (stretch - 1.0))


@nb.njit(cache=True, nogil=True, inline="always")
def _desired_speed(u0_i, law, rho_i, const_speed, crowd, cf_i, knee, stretch):
    if const_speed >= 0.0:
        return const_speed
    if crowd:
        return u0_i * shape(law, crowd_density(rho_i, cf_i, knee, stretch))
    return u0_i * shape(law, rho_i)


@nb.njit(cache=True, nogil=True)
def desired_speeds(n, u0, law, rho, const_speed, crowd, cf, knee, stretch, ue):
    """Desired speeds [m/s] into ``ue``: ``u0[i] g(rho[i])`` (the density read through
    :func:`crowd_density` if ``crowd``), or ``const_speed`` if that is >= 0."""
    for i in range(n):
        ue[i] = _desired_speed(u0[i], law, rho[i], const_speed, crowd, cf[i], knee, stretch)
@nb.njit(cache=True, nogil=True, inline="always")
def _proj(px, py, ax, ay, bx, by):
    dx = bx - ax
    dy = by - ay
    return ((px - ax) * dx + (py - ay) * dy) / (dx * dx + dy * dy)


@nb.njit(cache=True, nogil=True)
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



@nb.njit(cache=True, nogil=True, inline="always")
def _wall_one(i, x, v, piece, next_seg, x0, y0, inv_cell, gnx, gny, cell_ptr, cell_seg, rc2,
              rad, A, invB, k, kappa, inv_m, F, rs):
    """Add pedestrian i's wall accelerations to ``F[i]``, segment by segment."""
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


@nb.njit(parallel=True, cache=True, nogil=True)
def wall_accel(x, v, n, piece, next_seg, x0, y0, inv_cell, gnx, gny, cell_ptr,
               cell_seg, rc_w, rad, A, B, k, kappa, m, F, rs):
    """Add the wall accelerations of every pedestrian to ``F`` (cut-off ``rc_w`` [m]; body
    radii ``rad`` [m], social radii ``rs`` [m])."""
    rc2 = rc_w * rc_w
    invB = 1.0 / B
    inv_m = 1.0 / m
    for i in nb.prange(n):
        _wall_one(i, x, v, piece, next_seg, x0, y0, inv_cell, gnx, gny, cell_ptr, cell_seg,
                  rc2, rad, A, invB, k, kappa, inv_m, F, rs)


# ------------------------------------------------------------------ tracing in the mesh
@nb.njit(cache=True, nogil=True, inline="always")
def _bary(points, triangles, t, px, py):
    a, b, c = triangles[t, 0], triangles[t, 1], triangles[t, 2]
    ax, ay = points[a, 0], points[a, 1]
    bx, by = points[b, 0], points[b, 1]
    cx, cy = points[c, 0], points[c, 1]
    det = (bx - ax) * (cy - ay) - (cx - ax) * (by - ay)
    l1 = ((px - ax) * (cy - ay) - (cx - ax) * (py - ay)) / det
    l2 = ((bx - ax) * (py - ay) - (px - ax) * (by - ay)) / det
    return 1.0 - l1 - l2, l1, l2


@nb.njit(cache=True, nogil=True)
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



@nb.njit(cache=True, nogil=True, inline="always")
def _follow_one(i, points, triangles, nbr, tri, x, P):
    t0 = tri[i]
    if _inside_packed(P, t0, x[i, 0], x[i, 1], INSIDE_MARGIN):
        return
    b0, b1, b2 = _bary(points, triangles, t0, x[i, 0], x[i, 1])
    if b0 >= -1e-12 and b1 >= -1e-12 and b2 >= -1e-12:
        return  # still in the same triangle (the common case)
    # walk from the current triangle's centroid so the walk is well defined
    a, b, c = triangles[t0, 0], triangles[t0, 1], triangles[t0, 2]
    cx = (points[a, 0] + points[b, 0] + points[c, 0]) / 3.0
    cy = (points[a, 1] + points[b, 1] + points[c, 1]) / 3.0
    t, e, s = trace(points, triangles, nbr, t0, cx, cy, x[i, 0], x[i, 1])
    tri[i] = t


@nb.njit(parallel=True, cache=True, nogil=True)
def follow(points, triangles, nbr, tri, x, n, P):
    """Update the triangle of every pedestrian by walking from its previous triangle.
    A pedestrian (temporarily) outside the mesh keeps the last triangle it was in. ``P`` is
    a packed direction table (:func:`~pedmesh.eikonal.direction._pack`); its affine maps
    settle the common case, a pedestrian well inside its triangle, without a division."""
    for i in nb.prange(n):
        _follow_one(i, points, triangles, nbr, tri, x, P)


# ------------------------------------------------------------------ one SSP-RK3 step
@nb.njit(parallel=True, cache=True, nogil=True)
def accel(x, v, n, tri, points, triangles, nbr, dpack, pi, pj, n_near, n_far,
          piece, next_seg, wx0, wy0, winv, wnx, wny, wptr, wseg,
          rc_f, rc_d, rc_w, rad, A, B, k, kappa, m, R, tau, u0, law,
          const_u, use_const, F, rho, e, with_density, toff, tbuf, space, rs, wmap, wgeo,
          cf, ue, lay, pos, cell_start, hinge):
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
    ``cf``, ``ue``). ``space[5]``: the walls' social repulsion as a share of A (1: Helbing's,
    0: walls push on contact only); ``space[6:8]``: the density cone (exponent, norm) of
    :func:`~pedmesh.models.sfm.forces.cone_weights` (0: the isotropic kernel) with which
    ``rho`` is evaluated here. ``lay``, ``pos``, ``cell_start``: the blocks of the pair list and the
    cells it was made from (:func:`list_pairs`). ``hinge``: the pairs across a
    building's stair edges (indices, shifts and their number;
    :mod:`pedmesh.models.sfm.hinge_kernels`; none in a room), added after the others.

    Three parallel loops: over the pedestrians (crowding factors, social radii), over the
    blocks of the pair list (:func:`pair_accel_blocks`), over the pedestrians (walls,
    triangle, direction, desired speed and driving term, in the order the serial kernels
    added them).
    """
    crowd = space[3] > 1.0
    soc = rad
    # the desired speeds of the space requirement serve the driving term too, unless the
    # densities are evaluated again below
    have_ue = space[0] > 0.0 and not with_density
    cs = -1.0
    if use_const:
        cs = math.sqrt(const_u[0] * const_u[0] + const_u[1] * const_u[1])
    if crowd or space[0] > 0.0:
        h = 0.5 * space[1]
        span = wgeo[4] - wgeo[3]
        for i in nb.prange(n):
            if crowd:
                cf[i] = crowd_factor_at(x[i, 0], x[i, 1], wmap, wgeo[0], wgeo[1], wgeo[2],
                                        wgeo[3], span)
            if space[0] > 0.0:
                ue[i] = _desired_speed(u0[i], law, rho[i], cs, crowd, cf[i], space[4],
                                       space[3])
                rs[i] = _social_radius(rad[i], ue[i], space[0], h, crowd, cf[i])
    if space[0] > 0.0:
        soc = rs
    cone = space[6:8]
    pair_accel_blocks(x, v, n, pi, pj, n_near, n_far, lay, pos, cell_start, rc_f, rc_d, rad,
                      A, B, k, kappa, m, R, F, rho, with_density, soc, space[2], e, cone)
    hi_, hj_, hs_, nh = hinge
    if nh > 0:
        hinge_accel(x, v, nh, hi_, hj_, hs_, rc_f, rc_d, rad, A, B, k, kappa, m, R, F, rho,
                    with_density, soc, space[2], e, cone)
    A_wall = A * space[5]
    rc2 = rc_w * rc_w
    invB = 1.0 / B
    inv_m = 1.0 / m
    inv_tau = 1.0 / tau
    # chunks of pedestrians, each with one call of the direction interpolation
    nch = (n + CHUNK - 1) // CHUNK
    for ch in nb.prange(nch):
        lo = ch * CHUNK
        hi = min(lo + CHUNK, n)
        for i in range(lo, hi):
            _wall_one(i, x, v, piece, next_seg, wx0, wy0, winv, wnx, wny, wptr, wseg, rc2,
                      rad, A_wall, invB, k, kappa, inv_m, F, soc)
            if use_const:
                F[i, 0] += (const_u[0] - v[i, 0]) * inv_tau
                F[i, 1] += (const_u[1] - v[i, 1]) * inv_tau
            else:
                _follow_one(i, points, triangles, nbr, tri, x, dpack)
                tbuf[i] = tri[i] + toff[i] if tri[i] >= 0 else -1
        if use_const:
            continue
        _interpolate(dpack, tbuf[lo:hi], x[lo:hi], e[lo:hi])
        for i in range(lo, hi):
            if not have_ue:
                ue[i] = _desired_speed(u0[i], law, rho[i], -1.0, crowd, cf[i], space[4],
                                       space[3])
            F[i, 0] += (ue[i] * e[i, 0] - v[i, 0]) * inv_tau
            F[i, 1] += (ue[i] * e[i, 1] - v[i, 1]) * inv_tau
            # the direction the density cone and the field of vision read: unit (on a stair
            # the interpolated one carries the stair's speed factor, for the driving term)
            e[i, 0], e[i, 1] = unit_direction(e[i, 0], e[i, 1])


# ------------------------------------------------------------------ exits and reflection
@nb.njit(cache=True, nogil=True, inline="always")
def _settle_one(i, x_old, x, v, tri, points, triangles, nbr, tri_edges, edge_kind, edge_owner,
                edge_normals, exit_of, exit_frac, P):
    """:func:`settle` for pedestrian i; returns its number of reflections."""
    n_reflect = 0
    exit_of[i] = -1
    if _inside_packed(P, tri[i], x[i, 0], x[i, 1], INSIDE_MARGIN):
        return 0
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


@nb.njit(parallel=True, cache=True, nogil=True)
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
    for i in nb.prange(n):
        n_reflect += _settle_one(i, x_old, x, v, tri, points, triangles, nbr, tri_edges,
                                 edge_kind, edge_owner, edge_normals, exit_of, exit_frac, P)
    return n_reflect


# ------------------------------------------------------------------ densities on the mesh
@nb.njit(cache=True, nogil=True, inline="always")
def _cell_span(p, origin, inv_cell, ncell, reach):
    """The first and last cell index (clamped to the grid) within ``reach`` cells of the
    cell holding the coordinate ``p`` [m] (floored: a point left of the grid is in no cell,
    and its span starts at the grid's first)."""
    c = int(math.floor((p - origin) * inv_cell))
    return max(c - reach, 0), min(c + reach, ncell - 1)


@nb.njit(parallel=True, cache=True, nogil=True)
def density_at(q, nq, x, n, cell_start, cell_order, cx0, cy0, cinv, cnx, cny, R, rc_d, out):
    """Gaussian kernel density (eq3, eq4) of the pedestrians at points ``q`` [ped/m^2]."""
    w0 = 1.0 / (math.pi * R * R)
    invR2 = 1.0 / (R * R)
    rc2 = rc_d * rc_d
    reach = int(rc_d * cinv) + 1
    for p in nb.prange(nq):
        px, py = q[p, 0], q[p, 1]
        i0, i1 = _cell_span(px, cx0, cinv, cnx, reach)
        j0, j1 = _cell_span(py, cy0, cinv, cny, reach)
        acc = 0.0
        for ii in range(i0, i1 + 1):
            for jj in range(j0, j1 + 1):
                c = ii * cny + jj
                for a in range(cell_start[c], cell_start[c + 1]):
                    i = cell_order[a]
                    dx = x[i, 0] - px
                    dy = x[i, 1] - py
                    d2 = dx * dx + dy * dy
                    if d2 < rc2:
                        acc += w0 * math.exp(-d2 * invR2)
        out[p] = acc


# ------------------------------------------------------------------ people beyond the exits
#: columns of the ghost table (:func:`ghost_density`, :func:`walk_ghosts`): position [m],
#: velocity [m/s], walking direction, desired speed [m/s], distance walked [m], the speed
#: [m/s] at which they left (they never want to walk slower beyond the exit)
GHOST_COLUMNS = 9


@nb.njit(cache=True, nogil=True)
def ghost_density(g, ng, x, e, cell_start, cell_order, cx0, cy0, cinv, cnx, cny, R, rc_d,
                  cone, rho):
    """Add to ``rho`` the Gaussian kernel terms (with the density cone of the directions
    ``e``) of the ``ng`` people beyond the exits in ``g`` (:data:`GHOST_COLUMNS`), found
    through the cell list; one thread, ghost by ghost, so the sums' order is fixed."""
    w0 = 1.0 / (math.pi * R * R)
    invR2 = 1.0 / (R * R)
    rc2 = rc_d * rc_d
    reach = int(rc_d * cinv) + 1
    for k in range(ng):
        px, py = g[k, 0], g[k, 1]
        i0, i1 = _cell_span(px, cx0, cinv, cnx, reach)
        j0, j1 = _cell_span(py, cy0, cinv, cny, reach)
        for ii in range(i0, i1 + 1):
            for jj in range(j0, j1 + 1):
                c = ii * cny + jj
                for a in range(cell_start[c], cell_start[c + 1]):
                    i = cell_order[a]
                    dx = x[i, 0] - px
                    dy = x[i, 1] - py
                    d2 = dx * dx + dy * dy
                    if d2 < rc2:
                        wi, _ = cone_weights(dx, dy, d2, cone, e[i, 0], e[i, 1], 0.0, 0.0)
                        rho[i] += w0 * math.exp(-d2 * invR2) * wi


@nb.njit(cache=True, nogil=True)
def walk_ghosts(g, ng, dt, tau, reach, law, space, R, rc_d, rho):
    """One step ``dt`` [s] of the people beyond the exits (rows of ``g``,
    :data:`GHOST_COLUMNS`), walking on as those of a crowd in open space do: each reads the
    kernel density (its own share and, through the density cone ``space[6:8]``, the others
    beyond the exits ahead of it), wants the speed of the law ``law`` at it (read as a
    crowding person's where ``space[3]`` stretches it: beyond an exit there is room), but
    never less than the speed it left with, along its direction, its velocity relaxing to
    that in ``tau`` [s] (explicit Euler: they only count in densities). Who walked
    ``reach`` [m] is dropped, the others kept in order; returns their number. ``rho``: work
    space of at least ``ng``."""
    w0 = 1.0 / (math.pi * R * R)
    invR2 = 1.0 / (R * R)
    rc2 = rc_d * rc_d
    cone = space[6:8]
    for k in range(ng):
        rho[k] = w0
    for k in range(ng):
        for j in range(k + 1, ng):
            dx = g[k, 0] - g[j, 0]
            dy = g[k, 1] - g[j, 1]
            d2 = dx * dx + dy * dy
            if d2 < rc2:
                wk, wj = cone_weights(dx, dy, d2, cone, g[k, 4], g[k, 5], g[j, 4], g[j, 5])
                w = w0 * math.exp(-d2 * invR2)
                rho[k] += w * wk
                rho[j] += w * wj
    crowd = space[3] > 1.0
    w = 0
    a = dt / tau
    for k in range(ng):
        u = max(_desired_speed(g[k, 6], law, rho[k], -1.0, crowd, 1.0, space[4], space[3]),
                g[k, 8])
        vx = g[k, 2] + a * (u * g[k, 4] - g[k, 2])
        vy = g[k, 3] + a * (u * g[k, 5] - g[k, 3])
        walked = g[k, 7] + dt * math.sqrt(vx * vx + vy * vy)
        if walked >= reach:
            continue
        g[w, 0] = g[k, 0] + dt * vx
        g[w, 1] = g[k, 1] + dt * vy
        g[w, 2] = vx
        g[w, 3] = vy
        g[w, 4] = g[k, 4]
        g[w, 5] = g[k, 5]
        g[w, 6] = g[k, 6]
        g[w, 7] = walked
        g[w, 8] = g[k, 8]
        w += 1
    return w


@nb.njit(parallel=True, cache=True, nogil=True)
def rk3_step(x, v, n, dt, tri, points, triangles, nbr, dpack,
             cell_start, cell_order, cx0, cy0, cinv, cnx, cny,
             piece, next_seg, wx0, wy0, winv, wnx, wny, wptr, wseg,
             rc_f, rc_d, rc_w, rad, A, B, k, kappa, m, R, tau, u0, law,
             const_u, use_const, xs, vs, F, rho, rho_out, e, pi, pj, skin, density_stages,
             toff, tbuf, space, rs, wmap, wgeo, cf, ue, hinge, ghosts, n_ghosts, nblocks=1,
             cells_built=False):
    """One Shu-Osher SSP-RK3 step of (x, v) in place; ``tri`` follows the stage positions.
    ``rho_out`` receives the kernel densities at the start of the step; they set U_e in all
    three stages if ``density_stages`` is 1, else the density is re-evaluated at each stage.

    The pairs closer than the force cut-off plus ``skin`` (with ``density_stages`` 3 also
    those within the density cut-off plus ``skin``) are listed once per step from a cell
    list and reused by the three stages (the list is rebuilt for a stage in the rare case
    that someone moved more than skin/2 since). Returns the number of listed pairs, or -1 if
    ``pi``/``pj`` are too small (the caller enlarges them and repeats the step).

    The pair work is split into ``nblocks`` blocks of cells (:func:`pair_blocks`; one per
    thread, the caller's ``numba.get_num_threads()``); the result is the same for any.
    ``hinge``: the pairs across a building's stair edges (:func:`accel`). ``cells_built``:
    the cell list already holds the positions ``x`` (a building's step lists its pairs
    across stair edges from it first). ``ghosts``: the first ``n_ghosts`` rows are people
    beyond the exits (:func:`ghost_density`), counted in the densities at the step's start
    (with ``density_stages`` 1 only).
    """
    every = density_stages == 3
    # with the density held over the step it is computed while listing the pairs, and the
    # list needs the near pairs only (those within the force cut-off plus the skin)
    rc_list = max(rc_f + skin, rc_d + skin) if every else rc_f + skin
    if not cells_built:
        build_cells(x, n, cx0, cy0, cinv, cnx, cny, cell_start, cell_order)
    lay, pos = pair_blocks(n, cell_start, cell_order, cnx, cny, nblocks)
    cone = space[6:8]
    n_near, n_far = list_pairs(x, n, cell_start, cell_order, cnx, cny, rc_list, rc_f + skin,
                               pi, pj, rho, rc_d, R, not every, lay, pos, e, cone)
    if n_near < 0:
        return -1
    if hinge[3] > 0 and not every:  # the densities across a building's stair edges
        hinge_density(x, hinge[3], hinge[0], hinge[1], hinge[2], rc_d, R, rho, e, cone)
    if n_ghosts > 0:  # those just out through an exit (exit_ghosts; density_stages 1)
        ghost_density(ghosts, n_ghosts, x, e, cell_start, cell_order, cx0, cy0, cinv, cnx, cny,
                      R, rc_d, cone, rho)
    # stage 1: u1 = u + dt L(u)
    accel(x, v, n, tri, points, triangles, nbr, dpack, pi, pj, n_near, n_far, piece,
          next_seg, wx0, wy0, winv, wnx, wny, wptr, wseg, rc_f, rc_d, rc_w, rad, A, B, k, kappa,
          m, R, tau, u0, law, const_u, use_const, F, rho, e, every, toff, tbuf, space, rs, wmap,
          wgeo, cf, ue, lay, pos, cell_start, hinge)
    for i in nb.prange(n):
        rho_out[i] = rho[i]
        for d in range(2):
            xs[i, d] = x[i, d] + dt * v[i, d]
            vs[i, d] = v[i, d] + dt * F[i, d]
    # stage 2: u2 = 3/4 u + 1/4 (u1 + dt L(u1)); (bool(False), not False: numba types a
    # constant argument as a type of its own and would compile the callee once more for it)
    n_near, n_far, rebuilt, lay, pos = _refresh_pairs(
        x, xs, n, skin, cell_start, cell_order, cx0, cy0, cinv, cnx, cny, rc_f, rc_d, R, pi, pj,
        rho, n_near, n_far, bool(False), lay, pos, e, cone)
    if n_near < 0:
        return -1
    accel(xs, vs, n, tri, points, triangles, nbr, dpack, pi, pj, n_near, n_far, piece,
          next_seg, wx0, wy0, winv, wnx, wny, wptr, wseg, rc_f, rc_d, rc_w, rad, A, B, k, kappa,
          m, R, tau, u0, law, const_u, use_const, F, rho, e, every, toff, tbuf, space, rs, wmap,
          wgeo, cf, ue, lay, pos, cell_start, hinge)
    for i in nb.prange(n):
        for d in range(2):
            x1 = xs[i, d]
            v1 = vs[i, d]
            xs[i, d] = 0.75 * x[i, d] + 0.25 * (x1 + dt * v1)
            vs[i, d] = 0.75 * v[i, d] + 0.25 * (v1 + dt * F[i, d])
    # stage 3: u_new = 1/3 u + 2/3 (u2 + dt L(u2)); a list rebuilt for stage 2 has no skin
    n_near, n_far, rebuilt, lay, pos = _refresh_pairs(
        x, xs, n, skin, cell_start, cell_order, cx0, cy0, cinv, cnx, cny, rc_f, rc_d, R, pi, pj,
        rho, n_near, n_far, rebuilt, lay, pos, e, cone)
    if n_near < 0:
        return -1
    accel(xs, vs, n, tri, points, triangles, nbr, dpack, pi, pj, n_near, n_far, piece,
          next_seg, wx0, wy0, winv, wnx, wny, wptr, wseg, rc_f, rc_d, rc_w, rad, A, B, k, kappa,
          m, R, tau, u0, law, const_u, use_const, F, rho, e, every, toff, tbuf, space, rs, wmap,
          wgeo, cf, ue, lay, pos, cell_start, hinge)
    for i in nb.prange(n):
        for d in range(2):
            x[i, d] = x[i, d] / 3.0 + 2.0 / 3.0 * (xs[i, d] + dt * vs[i, d])
            v[i, d] = v[i, d] / 3.0 + 2.0 / 3.0 * (vs[i, d] + dt * F[i, d])
    return n_near + n_far


@nb.njit(cache=True, nogil=True)
def _refresh_pairs(x0, x, n, skin, cell_start, cell_order, cx0, cy0, cinv, cnx, cny, rc_f, rc_d,
                   R, pi, pj, rho, n_near, n_far, force, lay, pos, e, cone):
    """Keep the pair list (built with skin at ``x0``; its blocks ``lay``, ``pos``) if
    nobody moved more than skin/2 since, else (or if ``force``) rebuild it for the positions
    ``x`` without skin, valid for this stage only. Returns ``(n_near, n_far, rebuilt, lay,
    pos)``."""
    lim = 0.25 * skin * skin
    for i in range(n):
        dx = x[i, 0] - x0[i, 0]
        dy = x[i, 1] - x0[i, 1]
        if force or dx * dx + dy * dy > lim:
            build_cells(x, n, cx0, cy0, cinv, cnx, cny, cell_start, cell_order)
            lay, pos = pair_blocks(n, cell_start, cell_order, cnx, cny, lay.shape[0] - 1)
            n_near, n_far = list_pairs(x, n, cell_start, cell_order, cnx, cny,
                                       max(rc_f, rc_d), rc_f, pi, pj, rho, rc_d, R, bool(False),
                                       lay, pos, e, cone)  # (bool(): as in rk3_step)
            return n_near, n_far, True, lay, pos
    return n_near, n_far, False, lay, pos


@nb.njit(cache=True, nogil=True)
def compact(exit_of, n, x, v, rad, u0, u_eff, tpre, toff, e, ids, tri, rho):
    """Drop the pedestrians who left (``exit_of[i] >= 0``) from the first ``n`` rows of the
    per-pedestrian arrays, the others moved up in their order (what ``arr[:m] =
    arr[keep]`` does for each array, in one pass from the first leaver); returns their
    number ``m``."""
    w = 0
    while w < n and exit_of[w] < 0:
        w += 1
    for i in range(w, n):
        if exit_of[i] >= 0:
            continue
        x[w, 0] = x[i, 0]
        x[w, 1] = x[i, 1]
        v[w, 0] = v[i, 0]
        v[w, 1] = v[i, 1]
        e[w, 0] = e[i, 0]
        e[w, 1] = e[i, 1]
        rad[w] = rad[i]
        u0[w] = u0[i]
        u_eff[w] = u_eff[i]
        tpre[w] = tpre[i]
        toff[w] = toff[i]
        ids[w] = ids[i]
        tri[w] = tri[i]
        rho[w] = rho[i]
        w += 1
    return w


@nb.njit(cache=True, nogil=True)
def first_bad(x, v, n, vmax2):
    """Index of the first pedestrian with a non-finite state or a speed^2 above ``vmax2``
    (-1 if none)."""
    for i in range(n):
        s2 = v[i, 0] * v[i, 0] + v[i, 1] * v[i, 1]
        if not (s2 <= vmax2) or x[i, 0] != x[i, 0] or x[i, 1] != x[i, 1]:
            return i
    return -1
