"""Exact geodesic distance to the exits in a polygonal room (unit cost), for verification.

The shortest path from a point to an exit segment inside a polygon with holes is straight,
or bends only at reflex corners of the boundary (convex corners of obstacles, reflex corners
of the outline). So

.. math::  d(x) = \\min\\Big( \\min_{S} |x - \\pi_S(x)| \\;[\\text{if visible}],\\;
           \\min_{v \\text{ visible}} |x - v| + D(v) \\Big),

with ``pi_S(x)`` the closest point of exit segment ``S`` and ``D`` the same distance at the
corners, found by Dijkstra on the visibility graph of the corners. "Visible" means the
straight segment lies in the *closed* walkable area, so a path along a wall or touching a
corner counts (e.g. the point (70, 25) on the face of Example 3's obstacle).
"""

from __future__ import annotations

import heapq

import numpy as np
import shapely

__all__ = ["geodesic_distance", "reflex_corners"]


def reflex_corners(room) -> np.ndarray:
    """(k, 2) boundary corners a shortest path can bend at [m]."""
    out = []
    rings = [(np.asarray(room.outline), True)] + [(np.asarray(o.polygon), False)
                                                  for o in room.obstacles]
    for pts, outer in rings:
        ccw = shapely.LinearRing(pts).is_ccw
        n = len(pts)
        for i in range(n):
            a, b, c = pts[i - 1], pts[i], pts[(i + 1) % n]
            cross = (b[0] - a[0]) * (c[1] - b[1]) - (b[1] - a[1]) * (c[0] - b[0])
            left_turn = (cross > 0) == ccw  # convex corner of this ring
            # reflex for the walkable area: a concave outline corner or a convex obstacle corner
            if (outer and not left_turn) or (not outer and left_turn):
                out.append(b)
    return np.asarray(out, dtype=float).reshape(-1, 2)


def _segments(room, exits) -> list[tuple[np.ndarray, np.ndarray]]:
    idx = range(len(room.exits)) if exits is None else exits
    segs = []
    for k in idx:
        p = np.asarray(room.exit_polyline(k), dtype=float)
        segs += [(p[i], p[i + 1]) for i in range(len(p) - 1)]
    return segs


def _foot(x: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    d = b - a
    t = np.clip(((x - a) @ d) / (d @ d), 0.0, 1.0)
    return a + t[:, None] * d


def geodesic_distance(room, points: np.ndarray, exits=None) -> np.ndarray:
    """Exact shortest-path distance [m] from each point to the nearest (selected) exit.

    Parameters
    ----------
    room
        A :class:`~pedmesh.geometry.Room`.
    points
        (p, 2) coordinates [m] inside the walkable area.
    exits
        Exit indices (default: all).
    """
    region = room.walkable.buffer(1e-9)
    shapely.prepare(region)
    segs = _segments(room, exits)
    corners = reflex_corners(room)

    def direct(x: np.ndarray) -> np.ndarray:
        best = np.full(len(x), np.inf)
        for a, b in segs:
            f = _foot(x, a, b)
            d = np.hypot(*(x - f).T)
            vis = shapely.covers(region, shapely.linestrings(np.stack([x, f], axis=1)))
            # a degenerate (zero-length) segment is a point: visible when inside
            vis |= d == 0
            best = np.where(vis & (d < best), d, best)
        return best

    k = len(corners)
    D = direct(corners) if k else np.zeros(0)
    if k:
        ii, jj = np.triu_indices(k, 1)
        lines = shapely.linestrings(np.stack([corners[ii], corners[jj]], axis=1))
        vis = shapely.covers(region, lines)
        adj: list[list[tuple[int, float]]] = [[] for _ in range(k)]
        for i, j in zip(ii[vis], jj[vis]):
            w = float(np.hypot(*(corners[i] - corners[j])))
            adj[i].append((j, w))
            adj[j].append((i, w))
        heap = [(d, i) for i, d in enumerate(D) if np.isfinite(d)]
        heapq.heapify(heap)
        done = np.zeros(k, bool)
        while heap:
            d, i = heapq.heappop(heap)
            if done[i]:
                continue
            done[i] = True
            for j, w in adj[i]:
                if d + w < D[j]:
                    D[j] = d + w
                    heapq.heappush(heap, (D[j], j))
    x = np.asarray(points, dtype=float).reshape(-1, 2)
    best = direct(x)
    for i in range(k):
        if not np.isfinite(D[i]):
            continue
        d = np.hypot(*(x - corners[i]).T) + D[i]
        cand = d < best
        if cand.any():
            sel = np.flatnonzero(cand)
            lines = shapely.linestrings(
                np.stack([x[sel], np.broadcast_to(corners[i], (len(sel), 2))], axis=1))
            ok = shapely.covers(region, lines)
            best[sel[ok]] = d[sel[ok]]
    return best
