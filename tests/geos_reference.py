"""The reference the compiled nearest-segment distances (pedmesh.mesh.distance) are held
to in the tests: GEOS's nearest search on an STR tree (shapely)."""

from __future__ import annotations

import numpy as np
import shapely


def geos_distance(segments: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(p,) the distance [m] from each of ``points`` (p, 2) to the nearest of ``segments``
    ((s, 2, 2) or (s, 4); a segment whose ends coincide is a point), inf for none."""
    seg = np.asarray(segments, float).reshape(-1, 2, 2)
    if len(seg) == 0:
        return np.full(len(points), np.inf)
    geoms = [shapely.Point(g[0]) if np.array_equal(g[0], g[1]) else shapely.LineString(g)
             for g in seg]
    (_, _), d = shapely.STRtree(geoms).query_nearest(
        shapely.points(points), return_distance=True, all_matches=False)
    return d
