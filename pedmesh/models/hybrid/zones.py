"""Where the hybrid model's agents live: a set of the mesh's triangles.

A triangle belongs to the agent zone when its centroid lies in one of the given polygons
[m] (a room file's fixed zones) or within ``near_exits`` [m] of an exit (where the crowd
is densest and the continuum's law is least sure, docs/validation/dense_crowds.md). The
density trigger, which moves cells in and out as the run goes, acts on top of this fixed
part and is not here yet.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np

from ...errors import ParameterError
from ...mesh.triangle_mesh import TriMesh

__all__ = ["zone_cells"]


def zone_cells(mesh: TriMesh, polygons: Iterable[Sequence[Sequence[float]]] = (), *,
               near_exits: float = 0.0) -> np.ndarray:
    """(m,) bool: the triangles of ``mesh`` in the agent zone, those whose centroid lies
    inside (or on) one of ``polygons`` (each a sequence of (x, y) [m], at least three
    points) or within ``near_exits`` [m] of an exit edge (0: none)."""
    import shapely

    if not (np.isfinite(near_exits) and near_exits >= 0):
        raise ParameterError(f"near_exits must be a distance >= 0 [m], got {near_exits!r}")
    c = mesh.centroids
    inside = np.zeros(mesh.n_triangles, bool)
    for k, poly in enumerate(polygons):
        pts = np.asarray(poly, float)
        if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 3 or not np.all(np.isfinite(pts)):
            raise ParameterError(f"agent zone {k}: a polygon needs at least three finite "
                                 f"(x, y) points [m], got shape {pts.shape}")
        shape = shapely.Polygon(pts)
        if not shape.is_valid or shape.area <= 0:
            raise ParameterError(f"agent zone {k}: the polygon is not a simple polygon with "
                                 "an area (self-crossing or degenerate)")
        inside |= shapely.intersects_xy(shape, c[:, 0], c[:, 1])
    if near_exits > 0:
        e = mesh.exit_edges()
        if len(e):
            p = mesh.points[mesh.edges[e]]  # (k, 2, 2)
            lines = shapely.multilinestrings(list(p))
            inside |= shapely.dwithin(lines, shapely.points(c), near_exits)
    return inside
