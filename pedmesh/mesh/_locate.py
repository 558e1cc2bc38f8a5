"""Compiled point location in a triangle mesh by uniform-grid bucketing.

Each triangle is registered in every grid cell its bounding box overlaps (CSR lists); a query
point tests only the triangles of its cell. The grid has about one cell per triangle, so a
query tests a handful of triangles: O(1) per point.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from .._arrays import readonly

#: A point is inside a triangle when all barycentric coordinates are >= -BARY_TOL.
BARY_TOL = 1e-12


@nb.njit(cache=True, nogil=True)
def _build_buckets(pts, tri, x0, y0, inv_cell, nx, ny):
    m = tri.shape[0]
    counts = np.zeros(nx * ny + 1, np.int64)
    lo = np.empty((m, 2), np.int64)
    hi = np.empty((m, 2), np.int64)
    for t in range(m):
        xmin = min(pts[tri[t, 0], 0], pts[tri[t, 1], 0], pts[tri[t, 2], 0])
        xmax = max(pts[tri[t, 0], 0], pts[tri[t, 1], 0], pts[tri[t, 2], 0])
        ymin = min(pts[tri[t, 0], 1], pts[tri[t, 1], 1], pts[tri[t, 2], 1])
        ymax = max(pts[tri[t, 0], 1], pts[tri[t, 1], 1], pts[tri[t, 2], 1])
        i0 = max(int((xmin - x0) * inv_cell), 0)
        i1 = min(int((xmax - x0) * inv_cell), nx - 1)
        j0 = max(int((ymin - y0) * inv_cell), 0)
        j1 = min(int((ymax - y0) * inv_cell), ny - 1)
        lo[t, 0], lo[t, 1], hi[t, 0], hi[t, 1] = i0, j0, i1, j1
        for i in range(i0, i1 + 1):
            for j in range(j0, j1 + 1):
                counts[i * ny + j + 1] += 1
    ptr = np.cumsum(counts)
    fill = ptr[:-1].copy()
    idx = np.empty(ptr[-1], np.int64)
    for t in range(m):
        for i in range(lo[t, 0], hi[t, 0] + 1):
            for j in range(lo[t, 1], hi[t, 1] + 1):
                c = i * ny + j
                idx[fill[c]] = t
                fill[c] += 1
    return ptr, idx


@nb.njit(cache=True, nogil=True)
def _inside(pts, tri, t, px, py, tol):
    ax, ay = pts[tri[t, 0], 0], pts[tri[t, 0], 1]
    bx, by = pts[tri[t, 1], 0], pts[tri[t, 1], 1]
    cx, cy = pts[tri[t, 2], 0], pts[tri[t, 2], 1]
    a2 = (bx - ax) * (cy - ay) - (cx - ax) * (by - ay)
    lim = -tol * a2
    if (cx - bx) * (py - by) - (cy - by) * (px - bx) < lim:
        return False
    if (ax - cx) * (py - cy) - (ay - cy) * (px - cx) < lim:
        return False
    if (bx - ax) * (py - ay) - (by - ay) * (px - ax) < lim:
        return False
    return True


@nb.njit(cache=True, nogil=True)
def _locate(pts, tri, ptr, idx, x0, y0, inv_cell, nx, ny, q, tol, out):
    for k in range(q.shape[0]):
        px, py = q[k, 0], q[k, 1]
        out[k] = -1
        fi = (px - x0) * inv_cell
        fj = (py - y0) * inv_cell
        if not (fi > -1.0 and fj > -1.0 and fi < nx + 1.0 and fj < ny + 1.0):
            continue  # also rejects NaN
        i = min(max(int(fi), 0), nx - 1)
        j = min(max(int(fj), 0), ny - 1)
        c = i * ny + j
        for s in range(ptr[c], ptr[c + 1]):
            t = idx[s]
            if _inside(pts, tri, t, px, py, tol):
                out[k] = t
                break


class TriangleLocator:
    """Find the triangle containing each of many points (see module docstring)."""

    def __init__(self, points: np.ndarray, triangles: np.ndarray) -> None:
        self.points = np.ascontiguousarray(points, dtype=np.float64)
        self.triangles = np.ascontiguousarray(triangles, dtype=np.int64)
        lo = self.points.min(axis=0)
        hi = self.points.max(axis=0)
        span = np.maximum(hi - lo, 1e-12)
        m = len(self.triangles)
        cell = float(np.sqrt(span[0] * span[1] / max(m, 1)))
        cell = max(cell, float(span.max()) / 4096.0)
        self.x0, self.y0 = float(lo[0]), float(lo[1])
        self.inv_cell = 1.0 / cell
        self.nx = int(span[0] / cell) + 1
        self.ny = int(span[1] / cell) + 1
        self.ptr, self.idx = _build_buckets(
            self.points, self.triangles, self.x0, self.y0, self.inv_cell, self.nx, self.ny
        )

    def locate(self, query: np.ndarray, tol: float = BARY_TOL) -> np.ndarray:
        q = readonly(np.ascontiguousarray(np.asarray(query, dtype=np.float64).reshape(-1, 2)))
        out = np.empty(len(q), np.int64)
        _locate(
            self.points, self.triangles, self.ptr, self.idx,
            self.x0, self.y0, self.inv_cell, self.nx, self.ny, q, tol, out,
        )
        return out
