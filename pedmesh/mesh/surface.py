"""A building's walkable surface: one triangle mesh in 3-D whose pieces (levels and stairs)
are planar, stitched along the stair edges (:func:`pedmesh.mesh.building.triangulate_building`).

A :class:`SurfaceMesh` keeps, besides the 3-D mesh, each piece's own flat mesh in its chart
(:attr:`SurfaceMesh.pieces`): a level's chart is its plan (x, y); a stair's is its inclined
plane unrolled about its bottom edge, so that lengths and areas in the chart are the true
ones on the slope. The solvers work piece by piece in these charts; across a stair edge a
chart meets the next by a rigid motion of the plane.

Conventions follow :class:`~pedmesh.mesh.TriMesh`: ``points`` (n, 3) [m], ``triangles``
(m, 3) counter-clockwise seen from above (every piece is at most 45 degrees steep), tagged
boundary ``segments`` (walls, obstacles, exits; the stair edges are interior).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np

from ..errors import MeshError
from .triangle_mesh import BoundaryKind, TriMesh, vertex_triangle_csr

__all__ = ["Piece", "SurfaceMesh"]


@dataclass(frozen=True, eq=False)
class Piece:
    """One planar piece of a building's surface.

    ``kind`` is ``"level"`` or ``"stair"``; ``mesh`` its flat mesh in its chart [m];
    ``vertices`` (n_piece,) the surface vertex of each chart vertex; ``triangles`` the
    surface triangles of its chart triangles, in order; ``origin`` (3,) [m] and ``axes``
    (2, 3) the chart: a chart point (u, v) is at ``origin + u axes[0] + v axes[1]`` in 3-D.
    """

    name: str
    kind: str
    mesh: TriMesh
    vertices: np.ndarray
    triangles: np.ndarray
    origin: np.ndarray
    axes: np.ndarray

    def to_3d(self, uv: np.ndarray) -> np.ndarray:
        """3-D points [m] of chart points ``uv`` (k, 2) [m]."""
        uv = np.asarray(uv, float).reshape(-1, 2)
        return self.origin + uv @ self.axes

    def to_chart(self, xyz: np.ndarray) -> np.ndarray:
        """Chart points (k, 2) [m] of 3-D points ``xyz`` (k, 3) on the piece's plane."""
        return (np.asarray(xyz, float).reshape(-1, 3) - self.origin) @ self.axes.T


@dataclass(frozen=True, eq=False)
class SurfaceMesh:
    """A building's walkable surface (see the module docstring)."""

    points: np.ndarray
    triangles: np.ndarray
    piece: np.ndarray
    pieces: tuple[Piece, ...]
    segments: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), np.int64))
    segment_kind: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int8))
    segment_owner: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    exit_names: tuple[str, ...] = ()
    obstacle_names: tuple[str, ...] = ()
    building: Any = field(default=None, repr=False)
    _cache: dict = field(default_factory=dict, init=False, repr=False)

    def __post_init__(self) -> None:
        pts = np.ascontiguousarray(self.points, dtype=np.float64)
        tri = np.ascontiguousarray(self.triangles, dtype=np.int64)
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise MeshError(f"surface points must have shape (n, 3), got {pts.shape}")
        if tri.ndim != 2 or tri.shape[1] != 3 or len(tri) == 0:
            raise MeshError(f"triangles must have shape (m, 3) with m > 0, got {tri.shape}")
        if tri.min() < 0 or tri.max() >= len(pts):
            raise MeshError("triangles refer to vertices that do not exist")
        for name, arr in (("points", pts), ("triangles", tri)):
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        piece = np.ascontiguousarray(self.piece, dtype=np.int64)
        if piece.shape != (len(tri),):
            raise MeshError("piece must give one piece index per triangle")
        object.__setattr__(self, "piece", piece)
        for name, dtype in (("segments", np.int64), ("segment_kind", np.int8),
                            ("segment_owner", np.int64)):
            object.__setattr__(self, name, np.ascontiguousarray(getattr(self, name), dtype))
        object.__setattr__(self, "segments", self.segments.reshape(-1, 2))
        if np.any(self.normals[:, 2] <= 0):
            raise MeshError("a surface triangle faces down or stands vertical")

    # ------------------------------------------------------------------ sizes
    @property
    def n_points(self) -> int:
        return len(self.points)

    @property
    def n_triangles(self) -> int:
        return len(self.triangles)

    def __repr__(self) -> str:
        kinds = [p.kind for p in self.pieces]
        return (f"SurfaceMesh({self.n_points} points, {self.n_triangles} triangles, "
                f"{kinds.count('level')} levels, {kinds.count('stair')} stairs, "
                f"exits={list(self.exit_names)})")

    # ------------------------------------------------------------------ geometry
    @cached_property
    def _cross(self) -> np.ndarray:
        p = self.points[self.triangles]
        return np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])

    @cached_property
    def areas(self) -> np.ndarray:
        """True (3-D) triangle areas [m^2]."""
        return 0.5 * np.linalg.norm(self._cross, axis=1)

    @cached_property
    def normals(self) -> np.ndarray:
        """Unit normals (m, 3) of the triangles (pointing up)."""
        return self._cross / np.linalg.norm(self._cross, axis=1)[:, None]

    @cached_property
    def centroids(self) -> np.ndarray:
        """Triangle centroids (m, 3) [m]."""
        return self.points[self.triangles].mean(axis=1)

    @cached_property
    def _edge_data(self) -> tuple[np.ndarray, np.ndarray]:
        loc = np.sort(self.triangles[:, [[1, 2], [2, 0], [0, 1]]].reshape(-1, 2), axis=1)
        return np.unique(loc, axis=0, return_counts=True)

    @property
    def edges(self) -> np.ndarray:
        """Unique edges (k, 2) as vertex pairs, smaller index first."""
        return self._edge_data[0]

    @property
    def edge_triangle_counts(self) -> np.ndarray:
        """How many triangles share each edge of :attr:`edges` (1 on the boundary)."""
        return self._edge_data[1]

    @cached_property
    def edge_lengths(self) -> np.ndarray:
        """True (3-D) edge lengths [m]."""
        p = self.points
        return np.linalg.norm(p[self.edges[:, 1]] - p[self.edges[:, 0]], axis=1)

    @cached_property
    def vertex_triangles(self) -> tuple[np.ndarray, np.ndarray]:
        """Vertex-to-triangle adjacency in CSR form ``(indptr, indices)`` (as
        :attr:`pedmesh.mesh.TriMesh.vertex_triangles`)."""
        return vertex_triangle_csr(self.triangles, self.n_points)

    @cached_property
    def exit_vertices(self) -> np.ndarray:
        """(n,) exit number of each vertex lying on an exit, -1 elsewhere (as
        :attr:`pedmesh.mesh.TriMesh.exit_vertices`)."""
        out = np.full(self.n_points, -1, np.int64)
        sel = self.segment_kind == BoundaryKind.EXIT
        out[self.segments[sel, 0]] = self.segment_owner[sel]
        out[self.segments[sel, 1]] = self.segment_owner[sel]
        out.setflags(write=False)
        return out

    @property
    def area(self) -> float:
        """The walkable surface's area [m^2]."""
        return float(self.areas.sum())

    @cached_property
    def piece_is_stair(self) -> np.ndarray:
        """(p,) True for the stairs among the pieces."""
        return np.array([p.kind == "stair" for p in self.pieces], bool)

    @cached_property
    def piece_group(self) -> np.ndarray:
        """(p,) the flat group of each piece: pieces joined by stairs without rise (a flat
        connector) form one group, which lies in one horizontal plane and whose plan is its
        chart, as one room's; the stair edges within a group are no fold at all. Groups are
        numbered by their first piece."""
        n = len(self.pieces)
        root = list(range(n))

        def find(k: int) -> int:
            while root[k] != k:
                k = root[k]
            return k

        b = self.building
        for st in (b.stairs if b is not None else ()):
            if b.rise(st) != 0:
                continue
            ks = sorted(find(self.piece_index(x))
                        for x in (st.name, st.bottom.level, st.top.level))
            for k in ks[1:]:
                root[k] = ks[0]
        roots = np.array([find(k) for k in range(n)], np.int64)
        return np.unique(roots, return_inverse=True)[1].astype(np.int64)

    def piece_index(self, name: str) -> int:
        """The index of the piece (level or stair) called ``name``."""
        for k, p in enumerate(self.pieces):
            if p.name == name:
                return k
        raise MeshError(f"no level or stair '{name}' (pieces: "
                        f"{', '.join(p.name for p in self.pieces)})")

    # ------------------------------------------------------------------ output
    def cell_data(self) -> dict[str, np.ndarray]:
        """Fields that describe the mesh, for VTK: the piece index, whether it is a stair,
        and the true triangle area [m^2]."""
        stair = np.array([p.kind == "stair" for p in self.pieces], np.int8)
        return {"piece": self.piece.astype(np.int32), "stair": stair[self.piece],
                "area": self.areas}
