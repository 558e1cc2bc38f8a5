"""Queueing or crowding: the free width of the space around a pedestrian [m].

Adrian, Seyfried & Sieben (J. R. Soc. Interface 17, 2020, 20190871) and Adrian et al.
(Collective Dynamics 5, 2020, A50) let crowds walk to an entrance through corridors 1.2 to
5.6 m wide: in a narrow corridor people queue, in a wide one they crowd, and the density in
front of the entrance rises with the corridor's width; the change from queueing to crowding
lies between 1.2 m and 2.3 m. The social force model takes this in as a crowding factor
``c`` in [0, 1] of each pedestrian, from the free width ``W`` of the space around them:
``c = clip((W - queue_width) / (crowd_width - queue_width), 0, 1)``.

``W(x)`` is twice the largest distance to a wall (or an obstacle, or the room's outline)
found within ``reach`` [m] of ``x``: the width of a corridor anywhere in it, and at least
``2 reach`` in an open hall. It is computed once per room on a raster of the walkable area
(a Euclidean distance transform and a maximum filter, :mod:`scipy.ndimage`) and looked up
per pedestrian in compiled code.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba as nb
import numpy as np

from ... import parameters as P

__all__ = ["WidthMap", "width_map", "crowd_factors", "QUEUE_WIDTH_M", "CROWD_WIDTH_M",
           "WIDTH_REACH_M"]

#: [m] corridors this narrow or narrower queue (Adrian et al. 2020: 1.2 m; the default of
#: the parameter ``queue_width``)
QUEUE_WIDTH_M = P.get("queue_width").default
#: [m] spaces this wide or wider crowd (Adrian et al. 2020: 2.3 m; ``crowd_width``)
CROWD_WIDTH_M = P.get("crowd_width").default
#: [m] how far around a pedestrian the free width is looked for
WIDTH_REACH_M = 1.0
#: [m] raster cell of the width map (coarser for very large rooms: at most MAX_CELLS cells)
WIDTH_CELL_M = 0.1
MAX_CELLS = 8_000_000


@dataclass(frozen=True)
class WidthMap:
    """The free width [m] on a raster: ``width[i, j]`` at x = x0 + (i + 1/2) cell, y = y0 +
    (j + 1/2) cell (0 outside the walkable area)."""

    width: np.ndarray
    x0: float
    y0: float
    cell: float

    def at(self, points: np.ndarray) -> np.ndarray:
        """The free width [m] at ``points`` (k, 2) [m] (the nearest raster cell's)."""
        p = np.asarray(points, float).reshape(-1, 2)
        out = np.empty(len(p))
        _lookup(p, len(p), self.width, self.x0, self.y0, 1.0 / self.cell, out)
        return out


def width_map(walkable, *, reach: float = WIDTH_REACH_M, cell: float = WIDTH_CELL_M
              ) -> WidthMap:
    """The free width map of a walkable area (a shapely polygon [m], holes are obstacles)."""
    import shapely
    from scipy import ndimage

    x0, y0, x1, y1 = walkable.bounds
    area = (x1 - x0 + 2 * cell) * (y1 - y0 + 2 * cell)
    cell = max(cell, math.sqrt(area / MAX_CELLS))
    x0, y0 = x0 - cell, y0 - cell
    nx = int(math.ceil((x1 - x0) / cell)) + 2
    ny = int(math.ceil((y1 - y0) / cell)) + 2
    gx = x0 + (np.arange(nx) + 0.5) * cell
    gy = y0 + (np.arange(ny) + 0.5) * cell
    X, Y = np.meshgrid(gx, gy, indexing="ij")
    inside = shapely.contains_xy(walkable, X, Y)
    # distance to the nearest cell centre outside, less half a cell: to the wall between
    dist = np.maximum(ndimage.distance_transform_edt(inside) * cell - 0.5 * cell, 0.0)
    k = int(math.ceil(reach / cell))
    ii, jj = np.mgrid[-k:k + 1, -k:k + 1]
    disc = ii * ii + jj * jj <= k * k
    wmax = ndimage.maximum_filter(dist, footprint=disc, mode="constant", cval=0.0)
    width = np.where(inside, 2.0 * wmax, 0.0)
    return WidthMap(np.ascontiguousarray(width), float(x0), float(y0), float(cell))


@nb.njit(cache=True, nogil=True)
def _lookup(p, n, width, x0, y0, inv, out):
    nx, ny = width.shape
    for i in range(n):
        a = min(max(int((p[i, 0] - x0) * inv), 0), nx - 1)
        b = min(max(int((p[i, 1] - y0) * inv), 0), ny - 1)
        out[i] = width[a, b]


@nb.njit(cache=True, nogil=True, inline="always")
def crowd_factor_at(px, py, width, x0, y0, inv, w_queue, span):
    """The crowding factor in [0, 1] of a pedestrian at (px, py) (``span``: the crowd width
    less the queue width)."""
    nx, ny = width.shape
    a = min(max(int((px - x0) * inv), 0), nx - 1)
    b = min(max(int((py - y0) * inv), 0), ny - 1)
    f = (width[a, b] - w_queue) / span
    return 0.0 if f < 0.0 else (1.0 if f > 1.0 else f)


@nb.njit(cache=True, nogil=True)
def crowd_factors(x, n, width, x0, y0, inv, w_queue, w_crowd, c):
    """The crowding factors ``c[i]`` in [0, 1] of pedestrians at ``x`` (see the module)."""
    span = w_crowd - w_queue
    for i in range(n):
        c[i] = crowd_factor_at(x[i, 0], x[i, 1], width, x0, y0, inv, w_queue, span)
