"""The atlas of a building's surface: every piece's chart laid side by side in one plane,
where the room models run.

Each level and stair of a :class:`~pedmesh.mesh.surface.SurfaceMesh` has a flat chart
(:class:`~pedmesh.mesh.surface.Piece`): lengths, angles and areas in it are the true ones
on the surface. The atlas translates every chart by its own offset [m] so that no two
pieces overlap (stacked floors lie side by side), and numbers the triangles as the surface
does (atlas triangle t is surface triangle t). A stair edge then appears twice, once on
each of its pieces. Across it, one chart meets the other by a pure translation: a stair's
chart is its plane unrolled about its bottom edge (:mod:`pedmesh.mesh.building`), so its
bottom edge lies where the level's plan has it and its top edge is shifted along the run by
the slope's length less the run's. No vector turns when it crosses a stair edge: a
velocity or a momentum has the same components on both sides.

Three meshes share the atlas's points and triangles:

* :attr:`Atlas.open`, a :class:`GluedMesh` on which every stair edge is an exit of its own
  (named :data:`~pedmesh.mesh.building.HINGE_PREFIX` ...), except a flat connector's (a
  stair without rise), which are interior edges: its group lies in one plan. The social
  force model walks on it and moves a pedestrian who crosses such an exit to the other side
  (:attr:`Atlas.hinges`).
* :attr:`Atlas.glued`, a :class:`GluedMesh`, on which the two copies of a stair edge are one
  interior edge: its cells are face neighbours across the hinge and the finite volumes
  send their fluxes across it (mass is conserved to round-off), while every cell keeps the
  geometry of its own chart. :meth:`GluedMesh.cell_shift` says how far to move a cell's
  points into a neighbour's frame.
* :attr:`Atlas.steer`, on which the stair edges are boundary edges of no kind (neither walls
  nor exits), for the direction fields (:func:`pedmesh.eikonal.surface.atlas_direction_field`;
  :attr:`Atlas.flat_steer` with a flat connector's edges interior).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from ..errors import MeshError
from .building import HINGE_PREFIX, piece_segments
from .surface import SurfaceMesh
from .triangle_mesh import BoundaryKind, TriMesh

__all__ = ["Atlas", "GluedMesh", "build_atlas", "ATLAS_GAP"]

#: [m] the gap between two pieces laid side by side in the atlas
ATLAS_GAP = 10.0


@dataclass(frozen=True, eq=False)
class GluedMesh(TriMesh):
    """A :class:`~pedmesh.mesh.TriMesh` whose vertices ``canon[v] == canon[w]`` are one
    vertex of the surface, so that the edges of two pieces along a stair edge are one
    interior edge. Its geometry is that of each triangle's own points: an edge's length,
    normal and midpoint are those of its first triangle (``edge_triangles[:, 0]``), and a
    point of cell j is in cell i's frame after adding ``cell_shift(i, j)``.

    ``piece`` (m,) the piece of each triangle; ``piece_shift`` (p, p, 2) [m]: added to the
    coordinates of a point of piece b it gives them in the frame of piece a (zero between
    a piece and itself)."""

    canon: np.ndarray = field(default=None, repr=False)
    piece: np.ndarray = field(default=None, repr=False)
    piece_shift: np.ndarray = field(default=None, repr=False)

    def _vertex_keys(self, v: np.ndarray) -> np.ndarray:
        return self.canon[v]

    @cached_property
    def vertex_triangles(self) -> tuple[np.ndarray, np.ndarray]:
        """The triangles around each vertex, on both sides of a stair edge (CSR)."""
        flat = self.canon[self.triangles].ravel()
        idx_c = np.argsort(flat, kind="stable") // 3
        ptr_c = np.zeros(self.n_points + 1, np.int64)
        np.cumsum(np.bincount(flat, minlength=self.n_points), out=ptr_c[1:])
        counts = np.diff(ptr_c)[self.canon]
        ptr = np.zeros(self.n_points + 1, np.int64)
        np.cumsum(counts, out=ptr[1:])
        start = np.repeat(ptr_c[self.canon], counts)
        idx = idx_c[start + np.arange(ptr[-1]) - np.repeat(ptr[:-1], counts)]
        for a in (ptr, idx):
            a.setflags(write=False)
        return ptr, idx

    def cell_shift(self, i: np.ndarray, j: np.ndarray) -> np.ndarray:
        """(..., 2) [m]: added to a point of cell ``j`` it gives the point in the frame of
        cell ``i`` (zero within a piece)."""
        return self.piece_shift[self.piece[np.asarray(i)], self.piece[np.asarray(j)]]


@dataclass(frozen=True, eq=False)
class Atlas:
    """A building's surface laid out flat (see the module docstring).

    ``offset`` (p, 2) [m]: a chart point ``uv`` of piece k is at ``uv + offset[k]`` in the
    atlas; ``to_surface`` (n,): the surface vertex of each atlas vertex; ``hinges``: one row
    per atlas exit that is a stair edge, (exit index in :attr:`open`, its piece, the piece
    across, shift x, shift y [m]) with the shift that carries a point over to the other
    side."""

    surface: SurfaceMesh
    open: TriMesh
    glued: GluedMesh
    steer: TriMesh
    offset: np.ndarray
    to_surface: np.ndarray
    hinges: np.ndarray
    flat_canon: np.ndarray

    @property
    def n_exits(self) -> int:
        """The building's own exits (the first exits of :attr:`open`)."""
        return len(self.surface.exit_names)

    @cached_property
    def hinge_edges(self) -> np.ndarray:
        """The edges of :attr:`open` that are stair edges (its exits after the building's;
        a flat connector's are interior edges)."""
        m = self.open
        b = m.boundary_edges
        return b[(m.edge_kind[b] == BoundaryKind.EXIT) & (m.edge_owner[b] >= self.n_exits)]

    @cached_property
    def flat_steer(self) -> tuple[TriMesh, np.ndarray] | None:
        """``(mesh, key)``: :attr:`steer` with the two copies of every flat connector's
        stair edge made one (an interior edge), and ``key`` (n,) the vertex of ``mesh`` of
        each atlas vertex; None without flat connectors. The pieces of a flat group share
        their plan in the atlas, so ``mesh`` is each group's room as one mesh, and a
        direction field on it is the flat room's."""
        if np.all(self.flat_canon == np.arange(len(self.flat_canon))):
            return None
        keep = np.unique(self.flat_canon)
        compact = np.full(len(self.flat_canon), -1, np.int64)
        compact[keep] = np.arange(len(keep))
        key = compact[self.flat_canon]
        st = self.steer
        inner = self.open.find_edges(st.segments)
        solid = self.open.edge_triangles[inner, 1] < 0  # (a flat connector's: interior)
        mesh = TriMesh(points=st.points[keep], triangles=key[st.triangles],
                       segments=key[st.segments[solid]],
                       segment_kind=st.segment_kind[solid],
                       segment_owner=st.segment_owner[solid], exit_names=st.exit_names,
                       obstacle_names=st.obstacle_names)
        return mesh, key

    def boundary_vertices(self, edges: np.ndarray) -> np.ndarray:
        """(n,) True on the vertices of ``edges`` (edges of :attr:`open`)."""
        out = np.zeros(self.open.n_points, bool)
        out[self.open.edges[edges].ravel()] = True
        return out

    def to_3d(self, xy: np.ndarray, piece: np.ndarray) -> np.ndarray:
        """3-D points (k, 3) [m] of atlas points ``xy`` (k, 2) on pieces ``piece`` (k,)."""
        xy = np.asarray(xy, float).reshape(-1, 2)
        piece = np.asarray(piece, np.int64).reshape(-1)
        out = np.empty((len(xy), 3))
        for k, p in enumerate(self.surface.pieces):
            sel = piece == k
            if sel.any():
                out[sel] = p.to_3d(xy[sel] - self.offset[k])
        return out

    def vectors_3d(self, uv: np.ndarray, piece: np.ndarray) -> np.ndarray:
        """3-D vectors (k, 3) of chart vectors ``uv`` (k, 2) on pieces ``piece`` (k,)
        (velocities: the same components in the atlas and in the chart)."""
        axes = np.stack([p.axes for p in self.surface.pieces])  # (p, 2, 3)
        a = axes[np.asarray(piece, np.int64)]
        uv = np.asarray(uv, float).reshape(-1, 2)
        return uv[:, 0, None] * a[:, 0] + uv[:, 1, None] * a[:, 1]

    def cell_vectors_3d(self, uv: np.ndarray) -> np.ndarray:
        """:meth:`vectors_3d` of one vector per triangle (m, 2)."""
        return self.vectors_3d(uv, self.surface.piece)

    def level_shift(self, level: str) -> np.ndarray:
        """(2,) [m]: a plan point of ``level`` is at plan + this in the atlas."""
        return self.offset[self.surface.piece_index(level)]


def build_atlas(surface: SurfaceMesh) -> Atlas:
    """The :class:`Atlas` of a building's surface (cached on the surface)."""
    if "atlas" in surface._cache:
        return surface._cache["atlas"]
    pieces = surface.pieces
    offset = _offsets(pieces, surface.piece_group)
    starts = np.cumsum([0] + [p.mesh.n_points for p in pieces])
    pts = np.concatenate([p.mesh.points + offset[k] for k, p in enumerate(pieces)])
    tri = np.concatenate([p.mesh.triangles + starts[k] for k, p in enumerate(pieces)])
    to_surface = np.concatenate([p.vertices for p in pieces]).astype(np.int64)
    if not np.array_equal(to_surface[tri], surface.triangles):
        raise MeshError("the atlas's triangles are not the surface's (a mesh of another "
                        "building?)")
    first = np.full(surface.n_points, -1, np.int64)
    first[to_surface[::-1]] = np.arange(len(pts))[::-1]
    canon = first[to_surface]
    # the copies of a vertex within one flat group (a flat connector's stair edges) are one
    # vertex of the open mesh: one per (surface vertex, group), the first atlas copy
    vgroup = np.repeat(surface.piece_group, [p.mesh.n_points for p in pieces])
    pair = to_surface * (int(vgroup.max()) + 1) + vgroup
    _, first_copy, inv = np.unique(pair, return_index=True, return_inverse=True)
    flat_canon = first_copy[inv.ravel()].astype(np.int64)
    flat_names = {st.name for st in (surface.building.stairs if surface.building else ())
                  if surface.building.rise(st) == 0}
    # the tagged boundary: each piece's walls, obstacles and exits; stair edges are exits of
    # the open atlas only
    exit_names = list(surface.exit_names)
    hinge_names: list[str] = []
    hinge_piece: list[int] = []
    seg, kind, owner, obstacles = [], [], [], []
    hseg, howner, fseg = [], [], []
    for k, p in enumerate(pieces):
        rows, stair_edges = piece_segments(p.name, p.mesh, exit_names, obstacles)
        for j, sk, so in rows:
            seg.append(p.mesh.segments[j] + starts[k])
            kind.append(sk)
            owner.append(so)
        for j, name in stair_edges:
            if name[len(HINGE_PREFIX):].rsplit(":", 1)[0] in flat_names:
                # a flat connector's: an interior edge of the open mesh
                fseg.append(p.mesh.segments[j] + starts[k])
                continue
            label = f"{name}@{p.name}"
            if label not in hinge_names:
                hinge_names.append(label)
                hinge_piece.append(k)
            hseg.append(p.mesh.segments[j] + starts[k])
            howner.append(len(exit_names) + hinge_names.index(label))
    seg_a = np.array(seg, np.int64).reshape(-1, 2)
    shift = _piece_shifts(pts, to_surface, canon, starts, len(pieces))
    glued = GluedMesh(points=pts, triangles=tri, segments=seg_a,
                      segment_kind=np.array(kind, np.int8), segment_owner=np.array(owner),
                      exit_names=tuple(exit_names), obstacle_names=tuple(obstacles),
                      canon=canon, piece=surface.piece, piece_shift=shift)
    hseg_a = np.array(hseg, np.int64).reshape(-1, 2)
    open_mesh = GluedMesh(points=pts, triangles=tri,
                        segments=np.concatenate([seg_a, hseg_a]),
                        segment_kind=np.concatenate([np.array(kind, np.int8),
                                                     np.full(len(hseg_a), BoundaryKind.EXIT,
                                                             np.int8)]),
                        segment_owner=np.concatenate([np.array(owner, np.int64),
                                                      np.array(howner, np.int64)]),
                        exit_names=tuple(exit_names + hinge_names),
                        obstacle_names=tuple(obstacles), canon=flat_canon,
                        piece=surface.piece, piece_shift=shift)
    # the mesh for steering: the stair edges are boundary edges of no kind (neither a wall
    # nor an exit: no wall correction, no exit direction, no door jamb there)
    fseg_a = np.array(fseg, np.int64).reshape(-1, 2)
    steer = TriMesh(points=pts, triangles=tri,
                    segments=np.concatenate([open_mesh.segments, fseg_a]),
                    segment_kind=np.concatenate([np.array(kind, np.int8),
                                                 np.full(len(hseg_a) + len(fseg_a),
                                                         BoundaryKind.INTERIOR, np.int8)]),
                    segment_owner=np.concatenate([open_mesh.segment_owner,
                                                  np.full(len(fseg_a), -1, np.int64)]),
                    exit_names=tuple(exit_names), obstacle_names=tuple(obstacles))
    if len(glued.boundary_edges) != len(open_mesh.boundary_edges) - len(hseg_a):
        raise MeshError("the two sides of a stair edge of the atlas did not glue")
    rows = []
    for h, label in enumerate(hinge_names):
        k = hinge_piece[h]
        e = open_mesh.exit_edges(len(exit_names) + h)
        v = open_mesh.edges[e].ravel()
        across = glued.edge_triangles[glued.find_edges(open_mesh.edges[e]), :]
        other = np.unique(surface.piece[across.ravel()])
        other = other[other != k]
        if len(other) != 1:
            raise MeshError(f"stair edge {label!r} joins {len(other)} pieces, not one")
        b = int(other[0])
        rows.append((len(exit_names) + h, k, b, *shift[b, k]))
        if not len(v):
            raise MeshError(f"stair edge {label!r} has no edges")
    hinges = np.array(rows, float).reshape(-1, 5)
    atlas = Atlas(surface=surface, open=open_mesh, glued=glued, steer=steer, offset=offset,
                  to_surface=to_surface, hinges=hinges, flat_canon=flat_canon)
    surface._cache["atlas"] = atlas
    glued._cache["atlas"] = atlas
    return atlas


def _offsets(pieces, group: np.ndarray) -> np.ndarray:
    """(p, 2) [m] each piece's place in the atlas: its own chart where that overlaps no
    piece placed before it (a building without stacked parts keeps its plan); the others
    on shelves to the right of those, :data:`ATLAS_GAP` apart, in rows about as wide as
    all of them are high (a compact picture: :func:`pedmesh.plotting.plot_density`). The
    pieces of one flat group (:attr:`~pedmesh.mesh.surface.SurfaceMesh.piece_group`) move
    together: their charts stay one plan."""
    import shapely

    offset = np.zeros((len(pieces), 2))
    n_groups = int(group.max()) + 1
    members = [np.flatnonzero(group == g) for g in range(n_groups)]
    # (a piece's area from its boundary edges: its triangles' union, built at once)
    regions = [shapely.union_all([shapely.build_area(shapely.multilinestrings(
        pieces[k].mesh.points[pieces[k].mesh.edges[pieces[k].mesh.boundary_edges]]))
        for k in ks]) for ks in members]
    placed = None
    moved = []
    for g, region in enumerate(regions):
        if placed is not None and placed.intersection(region).area > 1e-9 * region.area:
            moved.append(g)
            continue
        placed = region if placed is None else shapely.union(placed, region)
    if not moved:
        return offset
    x0, _, x1, y1 = placed.bounds
    lo = np.array([np.array(regions[g].bounds[:2]) for g in moved])
    size = np.array([np.array(regions[g].bounds[2:]) for g in moved]) - lo + ATLAS_GAP
    width = max(float(size[:, 0].max()), math.sqrt(float(np.sum(size[:, 0] * size[:, 1]))),
                x1 - x0)
    x, y, row = x1 + ATLAS_GAP, y1, 0.0
    for g, l, sz in zip(moved, lo, size):
        if x + sz[0] > x1 + ATLAS_GAP + width and row > 0:  # a new shelf below
            x, y, row = x1 + ATLAS_GAP, y - row, 0.0
        offset[members[g]] = (x - l[0], y - sz[1] + ATLAS_GAP - l[1])
        x += sz[0]
        row = max(row, sz[1])
    return offset


def _piece_shifts(pts, to_surface, canon, starts, n_pieces) -> np.ndarray:
    """(p, p, 2) [m]: the translation from piece b's frame to piece a's, from the vertices
    the two share (adjacent pieces) and composed along the fewest stair edges (others)."""
    piece_of = np.repeat(np.arange(n_pieces), np.diff(starts))
    direct: dict[tuple[int, int], np.ndarray] = {}
    dup = np.flatnonzero(canon != np.arange(len(canon)))
    for v in dup:
        a, b = int(piece_of[canon[v]]), int(piece_of[v])
        d = pts[canon[v]] - pts[v]  # b's point + d = a's point
        key = (a, b)
        if key in direct:
            if not np.allclose(direct[key], d, atol=1e-6):
                raise MeshError("two pieces meet along two stair edges that are not one "
                                "translation apart (a stair from a level back to itself?)")
            continue
        direct[key] = d
        direct[(b, a)] = -d
    shift = np.zeros((n_pieces, n_pieces, 2))
    nbrs: dict[int, list[int]] = {k: [] for k in range(n_pieces)}
    for a, b in direct:
        nbrs[a].append(b)
    for a in range(n_pieces):  # breadth first from each piece
        seen = {a}
        queue = deque([a])
        while queue:
            c = queue.popleft()
            for b in nbrs[c]:
                if b not in seen:
                    seen.add(b)
                    # b's point + direct[(c, b)] is in c's frame; + shift[a, c] in a's
                    shift[a, b] = shift[a, c] + direct[(c, b)]
                    queue.append(b)
    return shift
