"""Exact distances [m] from many points to the nearest of a set of segments (points are
segments of length zero), in a compiled kernel over a uniform grid of the segments.

The meshers' size fields ask for the distance to the nearest exit, corner or wall at every
triangle's centroid in every refinement pass (a building's route mesh: about two million
points); GEOS's nearest-neighbour search on an STR tree did that at 2-10 microseconds a
point. The distance of a point to a segment is computed as GEOS computes it (the projection
parameter ``r``; the end point's distance for ``r`` outside (0, 1), else the perpendicular
distance ``|s| sqrt(len2)``), so the numbers, and the meshes graded by them, are the same
bits (tests/mesh/test_distance.py).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from .._arrays import readonly

__all__ = ["SegmentDistance"]

#: up to this many segments every point is measured against every segment (a grid of one
#: cell)
BRUTE_MAX = 48
#: grid cells per segment (the grid's cell is the side of bounding box area / (this * s))
CELLS_PER_SEGMENT = 1.0


@nb.njit(cache=True, nogil=True, inline="always")
def _point_segment(px, py, ax, ay, bx, by):
    if ax == bx and ay == by:
        dx = px - ax
        dy = py - ay
        return math.sqrt(dx * dx + dy * dy)
    len2 = (bx - ax) * (bx - ax) + (by - ay) * (by - ay)
    r = ((px - ax) * (bx - ax) + (py - ay) * (by - ay)) / len2
    if r <= 0.0:
        dx = px - ax
        dy = py - ay
        return math.sqrt(dx * dx + dy * dy)
    if r >= 1.0:
        dx = px - bx
        dy = py - by
        return math.sqrt(dx * dx + dy * dy)
    s = ((ay - py) * (bx - ax) - (ax - px) * (by - ay)) / len2
    return abs(s) * math.sqrt(len2)


@nb.njit(cache=True, nogil=True, inline="always")
def _cell_min(best, p, i, seg, start, items, c):
    for k in range(start[c], start[c + 1]):
        j = items[k]
        d = _point_segment(p[i, 0], p[i, 1], seg[j, 0], seg[j, 1], seg[j, 2], seg[j, 3])
        if d < best:
            best = d
    return best


@nb.njit(cache=True, nogil=True, parallel=True)
def _gridded(p, seg, x0, y0, cell, nx, ny, start, items, out):
    # rings of cells about the point's (clamped) cell: after ring r every segment not yet
    # seen lies at least r cells away, so at least r * cell from the point
    # (a point outside the grid's box, at D from it: at least sqrt(D^2 + (r cell)^2))
    for i in nb.prange(len(p)):
        fx = (p[i, 0] - x0) / cell
        fy = (p[i, 1] - y0) / cell
        dx = max(-fx, fx - nx, 0.0) * cell
        dy = max(-fy, fy - ny, 0.0) * cell
        d2 = dx * dx + dy * dy
        ci = int(min(max(fx, 0.0), nx - 1.0))
        cj = int(min(max(fy, 0.0), ny - 1.0))
        best = np.inf
        r = 0
        while True:
            for a in range(max(ci - r, 0), min(ci + r, nx - 1) + 1):
                if a == ci - r or a == ci + r:
                    for b in range(max(cj - r, 0), min(cj + r, ny - 1) + 1):
                        best = _cell_min(best, p, i, seg, start, items, a * ny + b)
                else:
                    if cj - r >= 0:
                        best = _cell_min(best, p, i, seg, start, items, a * ny + cj - r)
                    if cj + r <= ny - 1:
                        best = _cell_min(best, p, i, seg, start, items, a * ny + cj + r)
            # (a margin for the rounding of the bound: never stops early on a tie)
            if best < math.sqrt(d2 + (r * cell) ** 2) * (1.0 - 1e-9):
                break
            if ci - r <= 0 and cj - r <= 0 and ci + r >= nx - 1 and cj + r >= ny - 1:
                break
            r += 1
        out[i] = best


class SegmentDistance:
    """The distance [m] from points to the nearest of ``segments`` ((s, 2, 2) [m]; a segment
    whose ends coincide is a point): ``SegmentDistance(segments)(xy)`` gives (p,) distances
    for (p, 2) points, inf when there are no segments."""

    def __init__(self, segments) -> None:
        self.seg = np.ascontiguousarray(np.asarray(segments, np.float64).reshape(-1, 4))
        #: (x0, y0, cell, nx, ny, start, items) of the grid of the segments' boxes
        self.grid = self._bin(self.seg) if len(self.seg) else None

    def __len__(self) -> int:
        return len(self.seg)

    @staticmethod
    def _bin(seg: np.ndarray):
        lo = np.minimum(seg[:, :2], seg[:, 2:])
        hi = np.maximum(seg[:, :2], seg[:, 2:])
        x0, y0 = lo.min(axis=0)
        x1, y1 = hi.max(axis=0)
        if len(seg) <= BRUTE_MAX:  # one cell: every segment for every point
            cell = max(x1 - x0, y1 - y0, 1e-6)
            nx = ny = 1
        else:
            area = max((x1 - x0) * (y1 - y0), 1e-12)
            cell = max(math.sqrt(area / (CELLS_PER_SEGMENT * len(seg))), 1e-6,
                       max(x1 - x0, y1 - y0) / 4096.0)
            nx = int((x1 - x0) // cell) + 1
            ny = int((y1 - y0) // cell) + 1
        i0 = np.clip(((lo[:, 0] - x0) // cell).astype(np.int64), 0, nx - 1)
        i1 = np.clip(((hi[:, 0] - x0) // cell).astype(np.int64), 0, nx - 1)
        j0 = np.clip(((lo[:, 1] - y0) // cell).astype(np.int64), 0, ny - 1)
        j1 = np.clip(((hi[:, 1] - y0) // cell).astype(np.int64), 0, ny - 1)
        # every cell a segment's bounding box touches lists the segment
        ni = i1 - i0 + 1
        nj = j1 - j0 + 1
        count = ni * nj
        owner = np.repeat(np.arange(len(seg)), count)
        k = np.arange(int(count.sum())) - np.repeat(np.cumsum(count) - count, count)
        cells = (i0[owner] + k // nj[owner]) * ny + j0[owner] + k % nj[owner]
        order = np.argsort(cells, kind="stable")
        items = owner[order].astype(np.int64)
        start = np.searchsorted(cells[order], np.arange(nx * ny + 1)).astype(np.int64)
        return float(x0), float(y0), float(cell), nx, ny, start, items

    def __call__(self, xy) -> np.ndarray:
        p = readonly(np.ascontiguousarray(np.asarray(xy, np.float64).reshape(-1, 2)))
        out = np.empty(len(p))
        if self.grid is None:
            out.fill(np.inf)
        else:
            _gridded(p, self.seg, *self.grid, out)
        return out
