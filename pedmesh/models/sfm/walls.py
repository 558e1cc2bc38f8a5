"""Walls of the social force model, taken from the mesh's boundary edges.

Every wall and obstacle edge of the mesh is a wall segment; exit edges exert no force. The
segments are oriented along the boundary with the walkable area on their left, and each
knows its neighbours at both end points, so that a pedestrian near a corner shared by two
edges feels that corner once (see :func:`wall_contacts` in the kernels). A static grid lists,
for every cell, the segments that can be within the wall cut-off of a point in the cell.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...mesh.triangle_mesh import BoundaryKind, TriMesh

__all__ = ["WallSet", "clearance_factor", "ROUTE_WALL_COST"]


@dataclass(frozen=True)
class WallSet:
    """Wall segments of a mesh and their lookup grid.

    Attributes
    ----------
    p0, p1
        (w, 2) end points [m]; the walkable area is on the left of p0 -> p1.
    prev_seg, next_seg
        (w,) the wall segment ending at p0 / starting at p1, or -1 where the boundary
        continues as an exit edge.
    piece
        (w, 10) the straight wall piece (maximal run of collinear segments) each segment
        belongs to: ``pa_x, pa_y, pb_x, pb_y`` its end points, ``ts0, ts1`` the segment's
        parameter range on it, ``prev_pa_x, prev_pa_y, prev_pb_x, prev_pb_y`` the piece
        before its start corner (NaN where an exit precedes it). A pedestrian's contact with
        a straight wall is the projection onto the whole piece, owned by the one segment
        whose range contains it, so mesh edges splitting a wall never add up.
    x0, y0, inv_cell, nx, ny, cell_ptr, cell_seg
        The grid: segment lists (CSR) of cells of size ``1/inv_cell`` [m].
    """

    p0: np.ndarray
    p1: np.ndarray
    prev_seg: np.ndarray
    next_seg: np.ndarray
    piece: np.ndarray
    x0: float
    y0: float
    inv_cell: float
    nx: int
    ny: int
    cell_ptr: np.ndarray
    cell_seg: np.ndarray

    @classmethod
    def from_mesh(cls, mesh: TriMesh, cutoff: float, *, merge: bool = False) -> "WallSet":
        """Wall segments of ``mesh`` with a grid for a wall force cut-off ``cutoff`` [m].
        ``merge``: each straight wall piece one segment (the same forces, far fewer
        segments to go through on a fine mesh: the social force model's route mesh; the
        forces of several pieces may then be added in another order)."""
        b = mesh.boundary_edges
        e = mesh.edges[b]
        n_out = mesh.edge_normals[b]
        d = mesh.points[e[:, 1]] - mesh.points[e[:, 0]]
        # walkable area on the left <=> outward normal on the right
        left = d[:, 0] * n_out[:, 1] - d[:, 1] * n_out[:, 0] < 0
        a = np.where(left, e[:, 0], e[:, 1])
        c = np.where(left, e[:, 1], e[:, 0])
        # chained by the vertices the edges stand for (a building's open atlas: the two
        # copies of a flat connector's stair-edge ends are one)
        ka, kc = mesh._vertex_keys(a), mesh._vertex_keys(c)
        kind = mesh.edge_kind[b]
        solid = (kind == BoundaryKind.WALL) | (kind == BoundaryKind.OBSTACLE)
        n = mesh.n_points
        # boundary successor of every boundary vertex, and the wall index of each edge
        seg_of_start = np.full(n, -1, np.int64)
        wall_ids = np.full(len(b), -1, np.int64)
        wall_ids[solid] = np.arange(solid.sum())
        seg_of_start[ka] = wall_ids
        seg_of_end = np.full(n, -1, np.int64)
        seg_of_end[kc] = wall_ids
        a, c, ka, kc = a[solid], c[solid], ka[solid], kc[solid]
        p0 = np.ascontiguousarray(mesh.points[a])
        p1 = np.ascontiguousarray(mesh.points[c])
        prev_seg = seg_of_end[ka]  # the segment ending where this one starts (-1: exit)
        next_seg = seg_of_start[kc]
        if merge:
            p0, p1, prev_seg, next_seg = _merged(p0, p1, prev_seg, next_seg)
        piece = _pieces(p0, p1, prev_seg, next_seg)
        # grid
        lo = mesh.points.min(axis=0) - cutoff
        hi = mesh.points.max(axis=0) + cutoff
        cell = max(cutoff, float(np.max(hi - lo)) / 2048.0)
        inv = 1.0 / cell
        nx = int((hi[0] - lo[0]) * inv) + 1
        ny = int((hi[1] - lo[1]) * inv) + 1
        bmin = np.minimum(p0, p1) - cutoff
        bmax = np.maximum(p0, p1) + cutoff
        i0 = np.clip(((bmin[:, 0] - lo[0]) * inv).astype(np.int64), 0, nx - 1)
        i1 = np.clip(((bmax[:, 0] - lo[0]) * inv).astype(np.int64), 0, nx - 1)
        j0 = np.clip(((bmin[:, 1] - lo[1]) * inv).astype(np.int64), 0, ny - 1)
        j1 = np.clip(((bmax[:, 1] - lo[1]) * inv).astype(np.int64), 0, ny - 1)
        cells, segs = [], []
        for s in range(len(p0)):
            ii, jj = np.meshgrid(np.arange(i0[s], i1[s] + 1), np.arange(j0[s], j1[s] + 1),
                                 indexing="ij")
            cells.append((ii * ny + jj).ravel())
            segs.append(np.full(ii.size, s))
        if cells:
            cells = np.concatenate(cells)
            segs = np.concatenate(segs)
        else:
            cells = np.zeros(0, np.int64)
            segs = np.zeros(0, np.int64)
        order = np.argsort(cells, kind="stable")
        ptr = np.zeros(nx * ny + 1, np.int64)
        np.cumsum(np.bincount(cells, minlength=nx * ny), out=ptr[1:])
        return cls(p0, p1, prev_seg.astype(np.int64), next_seg.astype(np.int64), piece,
                   float(lo[0]), float(lo[1]), inv, nx, ny, ptr,
                   np.ascontiguousarray(segs[order], dtype=np.int64))

    @property
    def n_segments(self) -> int:
        return len(self.p0)


def _collinear(p0, p1, s, t) -> bool:
    """Segment t continues segment s in a straight line (same direction)."""
    ds = p1[s] - p0[s]
    dt = p1[t] - p0[t]
    cross = ds[0] * dt[1] - ds[1] * dt[0]
    return abs(cross) <= 1e-9 * np.hypot(*ds) * np.hypot(*dt) and float(ds @ dt) > 0


def _runs(p0, p1, prev_seg, next_seg) -> list[list[int]]:
    """The maximal runs of collinear segments (the straight wall pieces), each in boundary
    order."""
    w = len(p0)
    starts = [s for s in range(w) if prev_seg[s] < 0 or not _collinear(p0, p1, prev_seg[s], s)]
    start_set = set(starts)
    taken = np.zeros(w, bool)
    runs = []
    for s0 in starts:
        run = [s0]
        taken[s0] = True
        while next_seg[run[-1]] >= 0 and next_seg[run[-1]] != s0 and \
                _collinear(p0, p1, run[-1], next_seg[run[-1]]) and \
                not taken[next_seg[run[-1]]] and next_seg[run[-1]] not in start_set:
            run.append(next_seg[run[-1]])
            taken[run[-1]] = True
        runs.append(run)
    return runs


def _merged(p0, p1, prev_seg, next_seg):
    """Each straight run of segments as one segment: (p0, p1, prev_seg, next_seg) of the
    merged set (a closed ring without a corner, impossible for a polygon, is left as it
    is)."""
    runs = _runs(p0, p1, prev_seg, next_seg)
    if sum(len(r) for r in runs) != len(p0):
        return p0, p1, prev_seg, next_seg
    of = np.full(len(p0), -1, np.int64)
    for k, run in enumerate(runs):
        of[run] = k
    first = np.array([r[0] for r in runs], np.int64)
    last = np.array([r[-1] for r in runs], np.int64)
    q0 = np.ascontiguousarray(p0[first])
    q1 = np.ascontiguousarray(p1[last])
    prev_m = np.where(prev_seg[first] >= 0, of[np.maximum(prev_seg[first], 0)], -1)
    next_m = np.where(next_seg[last] >= 0, of[np.maximum(next_seg[last], 0)], -1)
    return q0, q1, prev_m.astype(np.int64), next_m.astype(np.int64)


def _pieces(p0, p1, prev_seg, next_seg) -> np.ndarray:
    w = len(p0)
    out = np.full((w, 10), np.nan)
    if w == 0:
        return out
    starts = [s for s in range(w) if prev_seg[s] < 0 or not _collinear(p0, p1, prev_seg[s], s)]
    piece_of = np.full(w, -1, np.int64)
    ends = []
    for k, s0 in enumerate(starts):
        run = [s0]
        while next_seg[run[-1]] >= 0 and next_seg[run[-1]] != s0 and \
                _collinear(p0, p1, run[-1], next_seg[run[-1]]) and \
                piece_of[next_seg[run[-1]]] < 0 and next_seg[run[-1]] not in starts:
            run.append(next_seg[run[-1]])
        pa, pb = p0[run[0]], p1[run[-1]]
        d = pb - pa
        L2 = float(d @ d)
        for s in run:
            piece_of[s] = k
            out[s, 0:2] = pa
            out[s, 2:4] = pb
            out[s, 4] = float((p0[s] - pa) @ d) / L2
            out[s, 5] = float((p1[s] - pa) @ d) / L2
        out[run[0], 4] = 0.0
        out[run[-1], 5] = 1.0
        ends.append(run)
    # the piece before each piece's start corner
    for run in ends:
        q = prev_seg[run[0]]
        if q >= 0:
            for s in run:
                out[s, 6:10] = out[q, 0:4]
    return np.ascontiguousarray(out)


#: the route cost's factor on a wall with ``route_clearance`` (1 + ROUTE_WALL_COST at d = 0)
ROUTE_WALL_COST = 3.0


def clearance_factor(mesh: TriMesh, clearance: float) -> np.ndarray:
    """(n,) the route cost's factor at the mesh's vertices with the clearance ``clearance``
    [m] (the parameter ``route_clearance``): ``1 + 3 (1 - d / clearance)^2`` within
    ``clearance`` of the nearest wall or obstacle edge (``d`` [m] the distance to it), 1
    beyond; exits do not count. The factor is a smooth bump of width ``clearance``, which the
    route mesh resolves (:mod:`pedmesh.mesh.route_mesh` grades it along the walls)."""
    from ...mesh.distance import SegmentDistance

    walls = mesh.edges[mesh.wall_edges()]
    if len(walls) == 0:
        return np.ones(mesh.n_points)
    d = SegmentDistance(mesh.points[walls])(mesh.points)
    s = np.clip(1.0 - np.asarray(d, float) / float(clearance), 0.0, 1.0)
    return 1.0 + ROUTE_WALL_COST * s * s
