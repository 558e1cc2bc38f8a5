"""The triangle mesh every pedmesh model runs on.

A :class:`TriMesh` is an immutable dataclass over flat arrays (one row per entity); all
connectivity and geometry is derived lazily with numpy and cached. Conventions:

* ``points`` (n, 2) float64 vertex coordinates [m];
* ``triangles`` (m, 3) int64 vertex indices, counter-clockwise;
* local edge ``i`` of a triangle is the edge *opposite* its vertex ``i``, i.e. from vertex
  ``(i+1) % 3`` to vertex ``(i+2) % 3`` (counter-clockwise);
* ``edges`` (k, 2) unique vertex pairs with ``edges[:, 0] < edges[:, 1]``;
* ``edge_triangles`` (k, 2): the triangle(s) on either side; column 0 is always a triangle,
  column 1 is ``-1`` on the boundary; ``edge_normals`` are unit normals pointing out of
  ``edge_triangles[:, 0]`` (so out of the domain on boundary edges);
* boundary edges carry a :class:`BoundaryKind` (wall, obstacle, exit) and an owner index
  (the obstacle or exit number, -1 for outer walls).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np

from ..errors import MeshError

__all__ = ["BoundaryKind", "TriMesh", "vertex_triangle_csr", "room_fingerprint"]


class BoundaryKind(enum.IntEnum):
    """Kind of a mesh edge."""

    INTERIOR = 0
    WALL = 1  #: the room outline
    OBSTACLE = 2  #: an obstacle's boundary
    EXIT = 3  #: an exit (open boundary)


def room_fingerprint(room) -> str:
    """SHA-256 (hex) of what a mesh of ``room`` depends on: its boundary rings (walls and
    obstacles, with the exits' vertices inserted), the exits as they lie on them, and the
    exit and obstacle names. Start areas and measurement elements do not count: one mesh
    serves a room with another crowd. Kept in the mesh (:attr:`TriMesh.room_fingerprint`)
    and checked when a room is run on a mesh."""
    import hashlib

    cache = getattr(room, "_cache", None)
    if isinstance(cache, dict) and "mesh_fingerprint" in cache:
        return cache["mesh_fingerprint"]
    h = hashlib.sha256()

    def add(label: str, arr) -> None:
        a = np.ascontiguousarray(np.asarray(arr, np.float64))
        h.update(f"{label}{a.shape}".encode())
        h.update(a.tobytes())

    for ring in room.boundary_rings:
        add(f"ring {ring.owner} {tuple(ring.exits)}", ring.points)
    for k in range(len(room.exits)):
        add(f"exit {k}", room.exit_polyline(k))
    h.update(repr((tuple(room.exit_names), tuple(room.obstacle_names))).encode())
    fp = h.hexdigest()
    if isinstance(cache, dict):
        cache["mesh_fingerprint"] = fp
    return fp


def vertex_triangle_csr(triangles: np.ndarray, n_points: int) -> tuple[np.ndarray, np.ndarray]:
    """Vertex-to-triangle adjacency of ``triangles`` (m, 3) over ``n_points`` vertices in CSR
    form ``(indptr, indices)``, the triangles of each vertex in increasing order; a vertex of
    no triangle is a :class:`~pedmesh.errors.MeshError`."""
    flat = np.asarray(triangles).ravel()
    order = np.argsort(flat, kind="stable")
    indices = (order // 3).astype(np.int64)
    counts = np.bincount(flat, minlength=n_points)
    indptr = np.zeros(n_points + 1, np.int64)
    np.cumsum(counts, out=indptr[1:])
    if np.any(counts == 0):
        v = int(np.flatnonzero(counts == 0)[0])
        raise MeshError(f"vertex {v} belongs to no triangle")
    return indptr, indices


def csr_ranges(starts: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """The indices ``starts[k], ..., starts[k] + counts[k] - 1`` of every k, one run after
    the other (the entries of some rows of a CSR list: ``idx[csr_ranges(ptr[rows],
    ptr[rows + 1] - ptr[rows])]``)."""
    counts = np.asarray(counts, np.int64)
    total = int(counts.sum())
    if total == 0:
        return np.zeros(0, np.int64)
    before = np.concatenate([[0], np.cumsum(counts)[:-1]])
    return np.repeat(np.asarray(starts, np.int64) - before, counts) + np.arange(total)


@dataclass(frozen=True, eq=False)
class TriMesh:
    """A 2-D triangle mesh of a room with tagged boundary edges.

    Parameters
    ----------
    points
        (n, 2) vertex coordinates [m].
    triangles
        (m, 3) vertex indices; clockwise triangles are reoriented.
    segments
        (s, 2) vertex pairs of tagged boundary edges. Boundary edges not listed are walls.
    segment_kind
        (s,) :class:`BoundaryKind` of each segment.
    segment_owner
        (s,) obstacle or exit index of each segment (-1 for walls).
    exit_names, obstacle_names
        Names of the exits / obstacles, indexed by the owner numbers.
    room
        The :class:`~pedmesh.geometry.Room` the mesh was made from, if any.
    room_fingerprint
        :func:`room_fingerprint` of that room (computed from ``room`` if not given):
        running a room on a mesh checks that they match.
    """

    points: np.ndarray
    triangles: np.ndarray
    segments: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), np.int64))
    segment_kind: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int8))
    segment_owner: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    exit_names: tuple[str, ...] = ()
    obstacle_names: tuple[str, ...] = ()
    room: Any = field(default=None, repr=False)
    room_fingerprint: str | None = field(default=None, repr=False)
    _cache: dict = field(default_factory=dict, init=False, repr=False)

    def __post_init__(self) -> None:
        pts = np.ascontiguousarray(self.points, dtype=np.float64)
        tri = np.ascontiguousarray(self.triangles, dtype=np.int64)
        if pts.ndim != 2 or pts.shape[1] != 2:
            raise MeshError(f"points must have shape (n, 2), got {pts.shape}")
        if tri.ndim != 2 or tri.shape[1] != 3 or len(tri) == 0:
            raise MeshError(f"triangles must have shape (m, 3) with m > 0, got {tri.shape}")
        if not np.all(np.isfinite(pts)):
            raise MeshError("points contain non-finite coordinates")
        if tri.min() < 0 or tri.max() >= len(pts):
            raise MeshError("triangles refer to vertices that do not exist")
        a2 = _twice_area(pts, tri)
        cw = a2 < 0
        if np.any(cw):
            tri = tri.copy()
            tri[cw] = tri[cw][:, [0, 2, 1]]
            a2 = np.abs(a2)
        if np.any(a2 <= 0):
            bad = int(np.flatnonzero(a2 <= 0)[0])
            raise MeshError(f"triangle {bad} is degenerate (zero area)")
        seg = np.ascontiguousarray(self.segments, dtype=np.int64).reshape(-1, 2)
        kind = np.ascontiguousarray(self.segment_kind, dtype=np.int8).ravel()
        owner = np.ascontiguousarray(self.segment_owner, dtype=np.int64).ravel()
        if not (len(seg) == len(kind) == len(owner)):
            raise MeshError("segments, segment_kind and segment_owner differ in length")
        for name, arr in [("points", pts), ("triangles", tri), ("segments", seg)]:
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        kind.setflags(write=False)
        owner.setflags(write=False)
        object.__setattr__(self, "segment_kind", kind)
        object.__setattr__(self, "segment_owner", owner)
        object.__setattr__(self, "exit_names", tuple(self.exit_names))
        object.__setattr__(self, "obstacle_names", tuple(self.obstacle_names))
        if self.room_fingerprint is None and self.room is not None \
                and hasattr(self.room, "boundary_rings"):
            object.__setattr__(self, "room_fingerprint", room_fingerprint(self.room))

    # ------------------------------------------------------------------ sizes
    @property
    def n_points(self) -> int:
        return len(self.points)

    @property
    def n_triangles(self) -> int:
        return len(self.triangles)

    @property
    def n_edges(self) -> int:
        return len(self.edges)

    def __repr__(self) -> str:
        return (
            f"TriMesh({self.n_points} points, {self.n_triangles} triangles, "
            f"exits={list(self.exit_names)}, obstacles={len(self.obstacle_names)})"
        )

    # ------------------------------------------------------------------ topology
    def _vertex_keys(self, v: np.ndarray) -> np.ndarray:
        """The vertex each vertex index stands for in the topology: itself (a
        :class:`~pedmesh.mesh.atlas.GluedMesh` maps the two copies of a stair edge's
        vertices to one)."""
        return v

    @cached_property
    def _edge_data(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        tri = self.triangles
        m = len(tri)
        # local edge i is opposite vertex i: (v[i+1], v[i+2])
        loc = tri[:, [[1, 2], [2, 0], [0, 1]]].reshape(-1, 2)  # (3 m, 2)
        srt = np.sort(self._vertex_keys(loc), axis=1)
        keys, inv, counts = np.unique(srt, axis=0, return_inverse=True, return_counts=True)
        inv = inv.ravel()
        if counts.max() > 2:
            e = int(np.argmax(counts))
            raise MeshError(f"edge {tuple(keys[e])} is shared by {counts.max()} triangles")
        t2e = inv.reshape(m, 3)
        owner = np.repeat(np.arange(m), 3)
        order = np.argsort(inv, kind="stable")
        e_sorted = inv[order]
        first = np.ones(len(order), bool)
        first[1:] = e_sorted[1:] != e_sorted[:-1]
        e2t = np.full((len(keys), 2), -1, np.int64)
        e2t[e_sorted[first], 0] = owner[order[first]]
        e2t[e_sorted[~first], 1] = owner[order[~first]]
        # an edge's vertices are those of its first triangle (the keys themselves, but in a
        # glued mesh, where the geometry is that triangle's), in the order of their keys
        edges = np.empty_like(keys)
        lf = loc[order[first]]
        kf = self._vertex_keys(lf)
        edges[e_sorted[first]] = np.where((kf[:, 0] > kf[:, 1])[:, None], lf[:, ::-1], lf)
        self._cache["edge_keys"] = keys.astype(np.int64)
        for a in (edges, t2e, e2t):
            a.setflags(write=False)
        return edges.astype(np.int64), t2e.astype(np.int64), e2t

    @property
    def edges(self) -> np.ndarray:
        """(k, 2) unique edges as sorted vertex pairs."""
        return self._edge_data[0]

    @property
    def triangle_edges(self) -> np.ndarray:
        """(m, 3) edge index of each triangle's local edge i (opposite vertex i)."""
        return self._edge_data[1]

    @property
    def edge_triangles(self) -> np.ndarray:
        """(k, 2) triangles on either side of each edge; column 1 is -1 on the boundary."""
        return self._edge_data[2]

    @cached_property
    def triangle_neighbors(self) -> np.ndarray:
        """(m, 3) neighbour across local edge i (opposite vertex i), -1 on the boundary."""
        e2t = self.edge_triangles
        t2e = self.triangle_edges
        me = np.arange(self.n_triangles)[:, None]
        a = e2t[t2e, 0]
        b = e2t[t2e, 1]
        nbr = np.where(a == me, b, a)
        nbr.setflags(write=False)
        return nbr

    @cached_property
    def boundary_edges(self) -> np.ndarray:
        """Indices of the boundary edges."""
        out = np.flatnonzero(self.edge_triangles[:, 1] < 0)
        out.setflags(write=False)
        return out

    @cached_property
    def _edge_tags(self) -> tuple[np.ndarray, np.ndarray]:
        ne = self.n_edges
        kind = np.full(ne, BoundaryKind.INTERIOR, np.int8)
        owner = np.full(ne, -1, np.int64)
        b = self.boundary_edges
        kind[b] = BoundaryKind.WALL
        if len(self.segments):
            idx = self.find_edges(self.segments)
            if np.any(idx < 0):
                s = self.segments[int(np.flatnonzero(idx < 0)[0])]
                raise MeshError(f"boundary segment {tuple(s)} is not an edge of the mesh")
            if np.any(self.edge_triangles[idx, 1] >= 0):
                raise MeshError("a tagged boundary segment is an interior edge of the mesh")
            kind[idx] = self.segment_kind
            owner[idx] = self.segment_owner
        kind.setflags(write=False)
        owner.setflags(write=False)
        return kind, owner

    @property
    def edge_kind(self) -> np.ndarray:
        """(k,) :class:`BoundaryKind` of each edge (0 = interior)."""
        return self._edge_tags[0]

    @property
    def edge_owner(self) -> np.ndarray:
        """(k,) obstacle or exit index of each boundary edge (-1 for walls and interior)."""
        return self._edge_tags[1]

    def find_edges(self, pairs: np.ndarray) -> np.ndarray:
        """Edge index of each vertex pair (any order), -1 where no such edge exists."""
        pairs = np.sort(self._vertex_keys(np.asarray(pairs, dtype=np.int64).reshape(-1, 2)),
                        axis=1)
        n = np.int64(self.n_points)
        self._edge_data  # (its keys, sorted)
        ek = self._cache["edge_keys"]
        keys = ek[:, 0] * n + ek[:, 1]
        q = pairs[:, 0] * n + pairs[:, 1]
        pos = np.searchsorted(keys, q)
        pos = np.minimum(pos, len(keys) - 1)
        return np.where(keys[pos] == q, pos, -1)

    def exit_edges(self, k: int | None = None) -> np.ndarray:
        """Indices of the edges of exit ``k`` (all exits if ``None``; read-only, kept)."""
        key = ("exit_edges", None if k is None else int(k))
        out = self._cache.get(key)
        if out is None:
            sel = self.edge_kind == BoundaryKind.EXIT
            if k is not None:
                sel &= self.edge_owner == k
            out = np.flatnonzero(sel)
            out.setflags(write=False)
            self._cache[key] = out
        return out

    def wall_edges(self) -> np.ndarray:
        """Indices of the solid boundary edges (outer walls and obstacles)."""
        return np.flatnonzero(
            (self.edge_kind == BoundaryKind.WALL) | (self.edge_kind == BoundaryKind.OBSTACLE)
        )

    @cached_property
    def exit_vertices(self) -> np.ndarray:
        """(n,) exit number of each vertex lying on an exit, -1 elsewhere."""
        out = np.full(self.n_points, -1, np.int64)
        e = self.exit_edges()
        out[self.edges[e, 0]] = self.edge_owner[e]
        out[self.edges[e, 1]] = self.edge_owner[e]
        out.setflags(write=False)
        return out

    @cached_property
    def boundary_vertices(self) -> np.ndarray:
        """(n,) True on vertices of boundary edges."""
        out = np.zeros(self.n_points, bool)
        out[self.edges[self.boundary_edges].ravel()] = True
        out.setflags(write=False)
        return out

    @cached_property
    def vertex_triangles(self) -> tuple[np.ndarray, np.ndarray]:
        """Vertex-to-triangle adjacency in CSR form ``(indptr, indices)``.

        The triangles around vertex ``v`` are ``indices[indptr[v]:indptr[v+1]]``.
        """
        return vertex_triangle_csr(self.triangles, self.n_points)

    # ------------------------------------------------------------------ geometry
    @cached_property
    def areas(self) -> np.ndarray:
        """(m,) triangle areas [m^2]."""
        a = 0.5 * _twice_area(self.points, self.triangles)
        a.setflags(write=False)
        return a

    @property
    def total_area(self) -> float:
        """Sum of the triangle areas [m^2]."""
        return float(np.sum(self.areas))

    @cached_property
    def centroids(self) -> np.ndarray:
        """(m, 2) triangle centroids [m]."""
        c = self.points[self.triangles].mean(axis=1)
        c.setflags(write=False)
        return c

    @cached_property
    def edge_lengths(self) -> np.ndarray:
        """(k,) edge lengths [m]."""
        d = self.points[self.edges[:, 1]] - self.points[self.edges[:, 0]]
        out = np.hypot(d[:, 0], d[:, 1])
        out.setflags(write=False)
        return out

    @cached_property
    def edge_midpoints(self) -> np.ndarray:
        """(k, 2) edge midpoints [m]."""
        out = 0.5 * (self.points[self.edges[:, 0]] + self.points[self.edges[:, 1]])
        out.setflags(write=False)
        return out

    @cached_property
    def edge_normals(self) -> np.ndarray:
        """(k, 2) unit normals pointing out of ``edge_triangles[:, 0]``."""
        p0 = self.points[self.edges[:, 0]]
        d = self.points[self.edges[:, 1]] - p0
        n = np.column_stack([d[:, 1], -d[:, 0]]) / self.edge_lengths[:, None]
        c = self.centroids[self.edge_triangles[:, 0]]
        flip = np.einsum("ij,ij->i", n, p0 - c) < 0
        n[flip] *= -1.0
        n.setflags(write=False)
        return n

    @cached_property
    def angles(self) -> np.ndarray:
        """(m, 3) interior angle [rad] at each triangle vertex."""
        p = self.points[self.triangles]
        a = p[:, [1, 2, 0]] - p  # to next
        b = p[:, [2, 0, 1]] - p  # to previous
        cross = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
        dot = np.einsum("ijk,ijk->ij", a, b)
        out = np.arctan2(np.abs(cross), dot)
        out.setflags(write=False)
        return out

    @property
    def min_angle(self) -> float:
        """Smallest triangle angle [degrees]."""
        return float(np.degrees(self.angles.min()))

    @property
    def max_angle(self) -> float:
        """Largest triangle angle [degrees]."""
        return float(np.degrees(self.angles.max()))

    @cached_property
    def exit_lengths(self) -> np.ndarray:
        """(n_exits,) total length [m] of each exit's edges."""
        e = self.exit_edges()
        out = np.bincount(
            self.edge_owner[e], weights=self.edge_lengths[e], minlength=len(self.exit_names)
        )
        out.setflags(write=False)
        return out

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(xmin, ymin, xmax, ymax) [m]."""
        lo = self.points.min(axis=0)
        hi = self.points.max(axis=0)
        return float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])

    @property
    def h(self) -> float:
        """Typical cell size [m]: the square root of the mean triangle area."""
        return float(np.sqrt(self.areas.mean()))

    # ------------------------------------------------------------------ point location
    @cached_property
    def _locator(self):
        from ._locate import TriangleLocator

        return TriangleLocator(self.points, self.triangles)

    def locate(self, points: np.ndarray) -> np.ndarray:
        """Triangle containing each point, -1 for points outside the mesh.

        Points on an edge or a vertex get one of the triangles sharing it. A point counts as
        inside when its barycentric coordinates are all >= -1e-12.

        Parameters
        ----------
        points
            (p, 2) query coordinates [m].

        Returns
        -------
        ndarray
            (p,) int64 triangle indices.
        """
        return self._locator.locate(points)

    def barycentric(self, points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
        """(p, 3) barycentric coordinates of ``points`` in the given triangles."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        t = np.asarray(triangles, dtype=np.int64)
        p = self.points[self.triangles[t]]  # (p, 3, 2)
        a2 = _twice_area(self.points, self.triangles[t])
        lam = np.empty((len(pts), 3))
        for i in range(3):
            b, c = p[:, (i + 1) % 3], p[:, (i + 2) % 3]
            lam[:, i] = (
                (c[:, 0] - b[:, 0]) * (pts[:, 1] - b[:, 1])
                - (c[:, 1] - b[:, 1]) * (pts[:, 0] - b[:, 0])
            ) / a2
        return lam

    # ------------------------------------------------------------------ summary
    def summary(self) -> dict[str, Any]:
        """Short description: sizes, quality, area and exits."""
        return {
            "vertices": self.n_points,
            "triangles": self.n_triangles,
            "edges": self.n_edges,
            "min_angle_deg": self.min_angle,
            "max_angle_deg": self.max_angle,
            "area_m2": self.total_area,
            "h_m": self.h,
            "exits": {n: float(L) for n, L in zip(self.exit_names, self.exit_lengths)},
        }


def _twice_area(pts: np.ndarray, tri: np.ndarray) -> np.ndarray:
    p0, p1, p2 = pts[tri[:, 0]], pts[tri[:, 1]], pts[tri[:, 2]]
    return (p1[:, 0] - p0[:, 0]) * (p2[:, 1] - p0[:, 1]) - (p2[:, 0] - p0[:, 0]) * (
        p1[:, 1] - p0[:, 1]
    )
