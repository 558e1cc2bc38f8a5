"""The desired walking direction ``e = -grad(phi) / |grad(phi)|`` from a route potential.

Three flavours, all unit vectors:

* per triangle: the P1 gradient of the vertex values (piecewise constant);
* per vertex: the area-weighted mean of the gradients of the triangles around the vertex,
  corrected on the boundary: on an exit vertex the direction is the outward normal of the
  exit (pedestrians leave through it), on a wall or obstacle vertex it is turned onto the
  nearer wall direction if it pointed out of the walkable wedge at that vertex;
* at arbitrary points (pedestrians): the vertex directions interpolated barycentrically in
  the containing triangle and normalised. This field is continuous, so steering is smooth.
  In a triangle with a wall edge the component pointing into that wall is removed with
  weight ``1 - lambda`` (``lambda`` the barycentric coordinate of the vertex opposite the
  wall), so on the wall itself the direction never points into it, and the correction
  fades out across the triangle.

Where ``phi`` is infinite (no exit reachable) the direction is zero.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
import scipy.sparse as sp

from ..mesh.triangle_mesh import BoundaryKind, TriMesh

__all__ = ["DirectionField", "p1_gradients"]


def _basis_gradients(mesh: TriMesh) -> np.ndarray:
    """(m, 3, 2) gradients of the barycentric coordinates in each triangle [1/m]."""
    cache = mesh._cache
    if "p1_grad" not in cache:
        p = mesh.points[mesh.triangles]
        e = p[:, [2, 0, 1]] - p[:, [1, 2, 0]]  # edge opposite vertex i, counter-clockwise
        g = np.stack([-e[..., 1], e[..., 0]], axis=-1) / (2.0 * mesh.areas[:, None, None])
        # grad(lambda_i) points from the opposite edge towards vertex i: (-e_y, e_x)
        cache["p1_grad"] = np.ascontiguousarray(g)
    return cache["p1_grad"]


def p1_gradients(mesh: TriMesh, phi: np.ndarray) -> np.ndarray:
    """(m, 2) gradient of the P1 interpolant of vertex values ``phi`` in each triangle (0 in
    triangles with a non-finite vertex value)."""
    grad = np.empty((mesh.n_triangles, 2))
    _descent(_basis_gradients(mesh), mesh.triangles, np.asarray(phi, dtype=np.float64), grad,
             np.empty_like(grad))
    return grad


def _vertex_averaging(mesh: TriMesh) -> sp.csr_matrix:
    cache = mesh._cache
    if "vertex_avg" not in cache:
        rows = mesh.triangles.ravel()
        cols = np.repeat(np.arange(mesh.n_triangles), 3)
        w = np.repeat(mesh.areas, 3)
        M = sp.csr_matrix((w, (rows, cols)), shape=(mesh.n_points, mesh.n_triangles))
        s = np.asarray(M.sum(axis=1)).ravel()
        cache["vertex_avg"] = sp.diags(1.0 / s) @ M
    return cache["vertex_avg"]


def _boundary_wedges(mesh: TriMesh):
    """Per boundary vertex: the directions to its next and previous boundary neighbours
    (walkable area on the left, so the walkable wedge turns counter-clockwise from
    ``d_next`` to ``d_prev``); the vertices on an exit and their unit outward exit
    normals."""
    cache = mesh._cache
    if "wedges" in cache:
        return cache["wedges"]
    b = mesh.boundary_edges
    t = mesh.edge_triangles[b, 0]
    e = mesh.edges[b]
    # orient each boundary edge with the walkable area on its left (counter-clockwise)
    n_out = mesh.edge_normals[b]
    d = mesh.points[e[:, 1]] - mesh.points[e[:, 0]]
    left = d[:, 0] * n_out[:, 1] - d[:, 1] * n_out[:, 0] < 0  # outward normal on the right
    a = np.where(left, e[:, 0], e[:, 1])
    c = np.where(left, e[:, 1], e[:, 0])
    n = mesh.n_points
    nxt = np.full(n, -1, np.int64)
    prv = np.full(n, -1, np.int64)
    nxt[a] = c
    prv[c] = a
    verts = np.flatnonzero((nxt >= 0) & (prv >= 0))
    dn = mesh.points[nxt[verts]] - mesh.points[verts]
    dp = mesh.points[prv[verts]] - mesh.points[verts]
    dn /= np.hypot(dn[:, 0], dn[:, 1])[:, None]
    dp /= np.hypot(dp[:, 0], dp[:, 1])[:, None]
    # outward exit normals summed over the exit edges at each vertex
    ex = mesh.edge_kind[b] == BoundaryKind.EXIT
    exit_n = np.zeros((n, 2))
    np.add.at(exit_n, e[ex, 0], n_out[ex])
    np.add.at(exit_n, e[ex, 1], n_out[ex])
    del t
    on_exit = np.flatnonzero(np.hypot(exit_n[:, 0], exit_n[:, 1]) > 0)
    cache["wedges"] = (verts, dn, dp, on_exit, _normalise(exit_n[on_exit]))
    return cache["wedges"]


def _ccw_angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Counter-clockwise angle in [0, 2 pi) from unit vectors a to b."""
    ang = np.arctan2(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0], np.einsum("ij,ij->i", a, b))
    return np.mod(ang, 2 * np.pi)


def _normalise(v: np.ndarray) -> np.ndarray:
    """Rows of ``v`` (k, 2) scaled to unit length (zero rows stay zero)."""
    out = np.empty((v.shape[0], 2))
    _unit_rows(np.ascontiguousarray(v, dtype=np.float64), out)
    return out


@nb.njit(cache=True, nogil=True)
def _unit_rows(v, out):
    for i in range(v.shape[0]):
        x, y = v[i, 0], v[i, 1]
        nrm = math.sqrt(x * x + y * y)
        if nrm > 0.0:
            out[i, 0] = x / nrm
            out[i, 1] = y / nrm
        else:
            out[i, 0] = 0.0
            out[i, 1] = 0.0


@nb.njit(cache=True, nogil=True, parallel=True)
def _descent(bgrad, triangles, phi, grad, unit):
    """Per triangle: the P1 gradient ``grad`` of the vertex values ``phi`` (0 where a vertex
    value is not finite) and the unit descent direction ``unit`` = -grad/|grad| (0 where the
    gradient is 0). ``bgrad`` (m, 3, 2): gradients of the barycentric coordinates. The
    triangles on the threads (each writes its own rows)."""
    for t in nb.prange(triangles.shape[0]):
        p0 = phi[triangles[t, 0]]
        p1 = phi[triangles[t, 1]]
        p2 = phi[triangles[t, 2]]
        if not (math.isfinite(p0) and math.isfinite(p1) and math.isfinite(p2)):
            gx = gy = 0.0
        else:
            gx = bgrad[t, 0, 0] * p0 + bgrad[t, 1, 0] * p1 + bgrad[t, 2, 0] * p2
            gy = bgrad[t, 0, 1] * p0 + bgrad[t, 1, 1] * p1 + bgrad[t, 2, 1] * p2
        grad[t, 0] = gx
        grad[t, 1] = gy
        nrm = math.sqrt(gx * gx + gy * gy)
        if nrm > 0.0:
            unit[t, 0] = -gx / nrm
            unit[t, 1] = -gy / nrm
        else:
            unit[t, 0] = 0.0
            unit[t, 1] = 0.0


def _jamb_overrides(mesh: TriMesh) -> np.ndarray:
    """(m, 3, 2) vertex-direction overrides at door jambs, NaN elsewhere.

    At an exit end point next to a wall (a door jamb) the vertex direction is the exit's
    outward normal. Interpolating it into the triangles of the fan around the jamb that have
    no exit edge of their own would make the flow converge on the jamb vertex, which no
    finite volume can pass (mass piles up there), and would steer pedestrians into the jamb.
    In those triangles the jamb vertex uses the wall direction towards the door instead.
    """
    cache = mesh._cache
    if "jamb" in cache:
        return cache["jamb"]
    out = np.full((mesh.n_triangles, 3, 2), np.nan)
    b = mesh.boundary_edges
    kind = mesh.edge_kind[b]
    e = mesh.edges[b]
    is_exit = kind == BoundaryKind.EXIT
    solid = ~is_exit
    n_exit = np.bincount(e[is_exit].ravel(), minlength=mesh.n_points)
    n_wall = np.bincount(e[solid].ravel(), minlength=mesh.n_points)
    jambs = np.flatnonzero((n_exit == 1) & (n_wall == 1))
    if len(jambs):
        ptr, idx = mesh.vertex_triangles
        tri_has_exit = np.any(mesh.edge_kind[mesh.triangle_edges] == BoundaryKind.EXIT, axis=1)
        wall_e = e[solid]
        for v in jambs:
            k = np.flatnonzero((wall_e[:, 0] == v) | (wall_e[:, 1] == v))[0]
            u = wall_e[k, 1] if wall_e[k, 0] == v else wall_e[k, 0]
            tvec = mesh.points[v] - mesh.points[u]
            tvec /= np.hypot(*tvec)
            for t in idx[ptr[v]:ptr[v + 1]]:
                if not tri_has_exit[t]:
                    loc = int(np.flatnonzero(mesh.triangles[t] == v)[0])
                    out[t, loc] = tvec
    cache["jamb"] = out
    return out


#: Columns of the packed per-triangle table used by :func:`_interpolate`.
PACK_WIDTH = 21


@nb.njit(cache=True, nogil=True, parallel=True)
def _pack(points, triangles, vdir, tdir, wall_n, jamb, out):
    """Everything the interpolation needs about triangle ``t`` in one row ``out[t]``:

    * 0-5: the affine maps of the barycentric coordinates, lambda_1 = out[t,0] +
      out[t,1] x + out[t,2] y and lambda_2 = out[t,3] + out[t,4] x + out[t,5] y;
    * 6-11: the three corner directions (door-jamb overrides applied);
    * 12-17: the wall normals opposite the corners (0 where there is no wall edge);
    * 18-19: the triangle's own direction;
    * 20: the length of the interpolated direction (1; a building's stairs set their speed
      factor there, :func:`scale_packed`).

    One contiguous row per triangle instead of six scattered look-ups per point halves the
    cost of steering thousands of pedestrians. The triangles on the threads.
    """
    for t in nb.prange(triangles.shape[0]):
        a, b, c = triangles[t, 0], triangles[t, 1], triangles[t, 2]
        ax, ay = points[a, 0], points[a, 1]
        ux, uy = points[b, 0] - ax, points[b, 1] - ay
        wx, wy = points[c, 0] - ax, points[c, 1] - ay
        inv = 1.0 / (ux * wy - wx * uy)
        # lambda_1 = ((x - ax) wy - wx (y - ay)) / det, lambda_2 = (ux (y - ay) - (x - ax) uy) / det
        out[t, 0] = (wx * ay - ax * wy) * inv
        out[t, 1] = wy * inv
        out[t, 2] = -wx * inv
        out[t, 3] = (ax * uy - ux * ay) * inv
        out[t, 4] = -uy * inv
        out[t, 5] = ux * inv
        for k in range(3):
            v = triangles[t, k]
            if jamb[t, k, 0] == jamb[t, k, 0]:  # an override (not NaN)
                out[t, 6 + 2 * k] = jamb[t, k, 0]
                out[t, 7 + 2 * k] = jamb[t, k, 1]
            else:
                out[t, 6 + 2 * k] = vdir[v, 0]
                out[t, 7 + 2 * k] = vdir[v, 1]
            out[t, 12 + 2 * k] = wall_n[t, k, 0]
            out[t, 13 + 2 * k] = wall_n[t, k, 1]
        out[t, 18] = tdir[t, 0]
        out[t, 19] = tdir[t, 1]
        out[t, 20] = 1.0


@nb.njit(cache=True, nogil=True, inline="always")
def _inside_packed(P, t, px, py, margin):
    """Whether (px, py) lies in triangle ``t`` with every barycentric coordinate >= margin
    (from the affine maps of the packed table ``P``: no division)."""
    l1 = P[t, 0] + P[t, 1] * px + P[t, 2] * py
    l2 = P[t, 3] + P[t, 4] * px + P[t, 5] * py
    return l1 >= margin and l2 >= margin and 1.0 - l1 - l2 >= margin


@nb.njit(cache=True, nogil=True)
def _interpolate(P, tri_idx, xy, out):
    """Directions ``out[k]`` at points ``xy[k]`` in triangles ``tri_idx[k]`` (-1: outside,
    direction 0) from the packed table ``P`` of :func:`_pack`."""
    for k in range(tri_idx.shape[0]):
        t = tri_idx[k]
        out[k, 0] = 0.0
        out[k, 1] = 0.0
        if t < 0:
            continue
        px, py = xy[k, 0], xy[k, 1]
        lam1 = P[t, 0] + P[t, 1] * px + P[t, 2] * py
        lam2 = P[t, 3] + P[t, 4] * px + P[t, 5] * py
        lam0 = 1.0 - lam1 - lam2
        ex = lam0 * P[t, 6] + lam1 * P[t, 8] + lam2 * P[t, 10]
        ey = lam0 * P[t, 7] + lam1 * P[t, 9] + lam2 * P[t, 11]
        # wall edge opposite local vertex i: remove the into-wall component, fully on the
        # wall (lambda_i = 0) and fading out towards the opposite vertex
        for i in range(3):
            nx, ny = P[t, 12 + 2 * i], P[t, 13 + 2 * i]
            if nx == 0.0 and ny == 0.0:
                continue
            lam = lam0 if i == 0 else (lam1 if i == 1 else lam2)
            s = ex * nx + ey * ny
            if s > 0.0:
                w = 1.0 - min(max(lam, 0.0), 1.0)
                ex -= w * s * nx
                ey -= w * s * ny
        nrm = np.sqrt(ex * ex + ey * ey)
        if nrm <= 1e-12:
            # a ridge on a wall (e.g. the middle of a pillar face, where going left and
            # right are equally good): use the triangle's own direction, along the wall
            ex, ey = P[t, 18], P[t, 19]
            for i in range(3):
                nx, ny = P[t, 12 + 2 * i], P[t, 13 + 2 * i]
                s = ex * nx + ey * ny
                if s > 0.0:
                    ex -= s * nx
                    ey -= s * ny
            nrm = np.sqrt(ex * ex + ey * ey)
        if nrm > 1e-12:
            out[k, 0] = ex / nrm * P[t, 20]
            out[k, 1] = ey / nrm * P[t, 20]


@nb.njit(cache=True, nogil=True, parallel=True)
def _interpolate_threads(P, tri_idx, xy, out):
    """:func:`_interpolate` with the points in chunks of 1,024 on the threads (the same
    numbers: each point is its own)."""
    n = tri_idx.shape[0]
    for c in nb.prange((n + 1023) // 1024):
        lo = c * 1024
        hi = min(n, lo + 1024)
        _interpolate(P, tri_idx[lo:hi], xy[lo:hi], out[lo:hi])


def scale_packed(packed: np.ndarray, factors: np.ndarray) -> np.ndarray:
    """The packed table ``packed`` with the directions of each triangle scaled to the
    length ``factors`` (m,) (a building's stair speed factors: the desired velocity of a
    particle model is its desired speed times the interpolated direction)."""
    out = packed.copy()
    out[:, 20] = factors
    return out


def pack_directions(mesh: TriMesh, vertex_directions: np.ndarray,
                    triangle_directions: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """(m, PACK_WIDTH) packed interpolation table of a direction field (see :func:`_pack`),
    written into ``out`` if given (a route re-solved every second refills one table rather
    than have a fresh one's pages faulted in: 9 MB on Example 2's route mesh)."""
    if out is None or out.shape != (mesh.n_triangles, PACK_WIDTH):
        out = np.empty((mesh.n_triangles, PACK_WIDTH))
    _pack(mesh.points, mesh.triangles, np.ascontiguousarray(vertex_directions),
          np.ascontiguousarray(triangle_directions), _wall_normals(mesh), _jamb_overrides(mesh),
          out)
    return out


def _wall_normals(mesh: TriMesh) -> np.ndarray:
    """(m, 3, 2) outward normal of the wall/obstacle edge opposite each corner, else 0."""
    cache = mesh._cache
    if "wall_normals" not in cache:
        e = mesh.triangle_edges
        kind = mesh.edge_kind[e]
        solid = (kind == BoundaryKind.WALL) | (kind == BoundaryKind.OBSTACLE)
        out = np.where(solid[..., None], mesh.edge_normals[e], 0.0)
        cache["wall_normals"] = np.ascontiguousarray(out)
    return cache["wall_normals"]


def _boundary_slots(mesh: TriMesh) -> tuple[np.ndarray, np.ndarray]:
    """(n,) each vertex's row in :func:`_boundary_wedges`' wedges and in its exit
    directions, -1 where it has none."""
    cache = mesh._cache
    if "wedge_slots" not in cache:
        verts, _, _, on_exit, _ = _boundary_wedges(mesh)
        wedge = np.full(mesh.n_points, -1, np.int64)
        wedge[verts] = np.arange(len(verts))
        ex = np.full(mesh.n_points, -1, np.int64)
        ex[on_exit] = np.arange(len(on_exit))
        cache["wedge_slots"] = (wedge, ex)
    return cache["wedge_slots"]


def vertex_directions(mesh: TriMesh, triangle_gradients: np.ndarray, finite: np.ndarray,
                      vertices: np.ndarray | None = None, averaging=None) -> np.ndarray:
    """(k, 2) the unit directions at ``vertices`` (all by default) of the field whose P1
    gradients per triangle are ``triangle_gradients`` (m, 2): the descent of the
    area-weighted mean gradient of the triangles around each vertex, turned into the
    walkable wedge on the boundary, the exit's outward normal on an exit, 0 where phi is
    not ``finite`` (n,) bool (see the module docstring). Each vertex's direction is
    computed alone: those of a subset are those of all, bit for bit (which
    :class:`~pedmesh.eikonal.active.ActiveRoutes` relies on). ``averaging``: the rows
    ``vertices`` of :func:`_vertex_averaging` (taken from it if not given)."""
    M = _vertex_averaging(mesh)
    # (the averaging's positive row scaling does not change the normalised direction)
    if vertices is None:
        e = _normalise(M @ triangle_gradients)
        slot_w, slot_x = _boundary_slots(mesh)
        ok = finite
    else:
        e = _normalise((M[vertices] if averaging is None else averaging)
                       @ triangle_gradients)
        slot_w, slot_x = (a[vertices] for a in _boundary_slots(mesh))
        ok = finite[vertices]
    np.negative(e, out=e)
    _, dn, dp, _, exit_dir = _boundary_wedges(mesh)
    rows = np.flatnonzero(slot_w >= 0)
    dn, dp = dn[slot_w[rows]], dp[slot_w[rows]]
    ev = e[rows]
    wedge = _ccw_angle(dn, dp)
    ang = _ccw_angle(dn, ev)
    outside = (ang > wedge) & (np.hypot(ev[:, 0], ev[:, 1]) > 0)
    # turn onto the nearer wedge side: d_next (angle 0) or d_prev (angle = wedge)
    to_next = (2 * np.pi - ang) < (ang - wedge)
    ev[outside & to_next] = dn[outside & to_next]
    ev[outside & ~to_next] = dp[outside & ~to_next]
    e[rows] = ev
    on_exit = np.flatnonzero(slot_x >= 0)
    e[on_exit] = exit_dir[slot_x[on_exit]]
    e[~ok] = 0.0
    return e


class DirectionField:
    """Unit desired-direction field of a route potential (see module docstring).

    Parameters
    ----------
    mesh
        The triangle mesh.
    phi
        (n,) potential at the vertices (e.g. from :func:`~pedmesh.eikonal.solve_eikonal`).
    packed_out
        Optional (m, PACK_WIDTH) array that :attr:`packed` is written into.
    """

    def __init__(self, mesh: TriMesh, phi: np.ndarray,
                 packed_out: np.ndarray | None = None) -> None:
        self.mesh = mesh
        self._packed_out = packed_out  # (where :attr:`packed` is written, if given)
        phi = np.asarray(phi, dtype=np.float64)
        m = mesh.n_triangles
        #: (m, 2) P1 gradient of phi per triangle (0 where a vertex value is infinite).
        self.triangle_gradients = np.empty((m, 2))
        #: (m, 2) unit direction ``-grad(phi)/|grad(phi)|`` per triangle.
        self.triangle_directions = np.empty((m, 2))
        _descent(_basis_gradients(mesh), mesh.triangles, phi, self.triangle_gradients,
                 self.triangle_directions)
        #: (n, 2) unit direction at the vertices.
        self.vertex_directions = np.ascontiguousarray(
            vertex_directions(mesh, self.triangle_gradients, np.isfinite(phi)))
        self._packed: np.ndarray | None = None

    @property
    def packed(self) -> np.ndarray:
        """(m, PACK_WIDTH) per-triangle interpolation table (built on first use)."""
        if self._packed is None:
            self._packed = pack_directions(self.mesh, self.vertex_directions,
                                           self.triangle_directions, self._packed_out)
        return self._packed

    def at(self, points: np.ndarray, triangles: np.ndarray | None = None) -> np.ndarray:
        """Unit directions (p, 2) at arbitrary points [m]; zero outside the mesh.

        ``triangles`` (the containing triangle of each point) saves the point location when
        the caller already knows it.
        """
        pts = np.ascontiguousarray(np.asarray(points, dtype=np.float64).reshape(-1, 2))
        if not pts.flags.writeable:  # (the kernel's type as the social force model calls it)
            pts = pts.copy()
        tri = self.mesh.locate(pts) if triangles is None else np.asarray(triangles, np.int64)
        out = np.empty_like(pts)
        _interpolate_threads(self.packed, np.ascontiguousarray(tri), pts, out)
        return out
