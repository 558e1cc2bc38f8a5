"""Fast marching on a building's surface (:class:`~pedmesh.mesh.surface.SurfaceMesh`).

The same compiled march as on a room (:mod:`pedmesh.eikonal.fmm_kernels`), on the surface's
3-D vertices: every triangle is planar, so its update in 3-D is the update in its own
chart, and a distance along a stair is measured on the slope. What needs the plane is done
piece by piece in each piece's chart: the obtuse-angle splits (their walk stops at a stair
edge, where the plain update takes over) and the straight rays from exit end points and
reflex corners (visible within the piece).

``cost`` [s/m] is per vertex or per triangle as on a room; :func:`stair_costs` gives the
cost of walking at the level speed and at the stairs' speeds up or down.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from ..errors import ParameterError
from ..mesh.surface import SurfaceMesh
from ..mesh.triangle_mesh import TriMesh, csr_ranges
from . import fmm_kernels as _fmm
from .direction import DirectionField
from .fmm import (DEFAULT_CORNER_RADIUS, MAX_SPLIT_STEPS, EikonalSolver, _corner_rays, _csr,
                  _ray_samples)

__all__ = ["SurfaceEikonalSolver", "BuildingRoutes", "atlas_direction_field", "stair_costs",
           "stair_factors", "surface_gradient"]


class SurfaceEikonalSolver(EikonalSolver):
    """:class:`~pedmesh.eikonal.EikonalSolver` on a building's surface mesh (see the
    module docstring); ``solve`` is the room solver's, with ties accepted in the order of
    the vertices (:attr:`ordered`: :class:`BuildingRoutes` marches again only where the
    crowd's costs can change the potential, which needs the march to be a function of its
    costs)."""

    ordered = True

    def __init__(self, surface: SurfaceMesh, exits: Sequence[str | int] | None = None,
                 corner_radius: float = DEFAULT_CORNER_RADIUS) -> None:
        if not isinstance(surface, SurfaceMesh):
            raise ParameterError("SurfaceEikonalSolver takes a building's SurfaceMesh")
        super().__init__(surface, exits, corner_radius)

    def _groups(self) -> list[tuple[TriMesh, np.ndarray, np.ndarray]]:
        """The flat groups of the surface: ``(mesh, vertices, triangles)`` for each set of
        pieces joined by stairs without rise (all in one horizontal plane, so their plan is
        their chart and the stair edges between them are no fold at all), one piece where no
        such stair joins it. ``mesh`` is the group's flat mesh; ``vertices`` and
        ``triangles`` give the surface vertex and triangle of each of its vertices and
        triangles. Within a group the obtuse-angle splits and the corner rays see across
        the stair edges as on one room, so a flat connector answers as the floor it
        replaces."""
        if "groups" in self.__dict__:
            return self.__dict__["groups"]
        s = self.mesh
        b = s.building
        members: dict[int, list[int]] = {}
        for k, grp in enumerate(s.piece_group):
            members.setdefault(int(grp), []).append(k)
        out = []
        for ks in members.values():
            if len(ks) == 1:
                p = s.pieces[ks[0]]
                out.append((p.mesh, p.vertices, p.triangles))
                continue
            tris = np.flatnonzero(np.isin(s.piece, ks))
            verts = np.unique(s.triangles[tris])
            local = np.full(s.n_points, -1, np.int64)
            local[verts] = np.arange(len(verts))
            m0 = TriMesh(points=s.points[verts, :2], triangles=local[s.triangles[tris]])
            # the surface's walls, obstacles and exits that are edges of the group
            seg = local[s.segments]
            ok = np.all(seg >= 0, axis=1)
            ok[ok] = m0.find_edges(seg[ok]) >= 0
            rooms = [s.pieces[k] for k in ks]
            region = _group_region(b, [p.name for p in rooms])
            out.append((TriMesh(points=m0.points, triangles=m0.triangles, segments=seg[ok],
                                segment_kind=s.segment_kind[ok],
                                segment_owner=s.segment_owner[ok], exit_names=s.exit_names,
                                obstacle_names=s.obstacle_names, room=region),
                        verts, tris))
        self.__dict__["groups"] = out
        return out

    def _split_vertices(self) -> np.ndarray:
        """The obtuse-angle splits, group by group (:meth:`_groups`) in each group's chart
        (a walk stops at a stair edge with a rise, the boundary of its group), in surface
        numbering."""
        s = self.mesh
        split = np.full((s.n_triangles, 3), -1, np.int64)
        for m, verts, tris in self._groups():
            loc = _fmm.find_split_vertices(m.points, m.triangles, m.triangle_neighbors,
                                           MAX_SPLIT_STEPS)
            split[tris] = np.where(loc >= 0, verts[np.maximum(loc, 0)], loc)
        return split

    def _march_points(self) -> np.ndarray:
        return np.ascontiguousarray(self.mesh.points)

    def _rays(self) -> None:
        """The corner rays of every group (:meth:`_groups`), in surface numbering (CSR by
        source vertex)."""
        s = self.mesh
        src, dst, length, samp_n, samp_tri = [], [], [], [], []
        for m, verts, tris in self._groups():
            ptr, idx, ln = _corner_rays(m, self.corner_radius)
            if len(idx) == 0:
                continue
            sptr, stri = _ray_samples(m, ptr, idx, ln)
            src.append(verts[np.repeat(np.arange(m.n_points), np.diff(ptr))])
            dst.append(verts[idx])
            length.append(ln)
            samp_n.append(np.diff(sptr))
            samp_tri.append(np.split(tris[stri], sptr[1:-1]))
        n = s.n_points
        if not src:
            self.ray_ptr = np.zeros(n + 1, np.int64)
            self.ray_idx = np.zeros(0, np.int32)
            self.ray_len = np.zeros(0)
            self.ray_samp_ptr, self.ray_samp_tri = np.zeros(1, np.int64), np.zeros(0, np.int64)
            return
        src = np.concatenate(src)
        self.ray_ptr, order = _csr(src, n)
        self.ray_idx = np.ascontiguousarray(np.concatenate(dst)[order], dtype=np.int32)
        self.ray_len = np.ascontiguousarray(np.concatenate(length)[order])
        samples = [x for part in samp_tri for x in part]
        samples = [samples[k] for k in order]
        counts = np.array([len(x) for x in samples], np.int64)
        self.ray_samp_ptr = np.zeros(len(samples) + 1, np.int64)
        np.cumsum(counts, out=self.ray_samp_ptr[1:])
        self.ray_samp_tri = np.concatenate(samples).astype(np.int64)


def _group_region(building, names: list[str]):
    """The walkable plan (a shapely polygon) of the pieces ``names`` of one flat group: its
    levels' walkable areas and its stairs' polygons, as one room
    (:class:`~pedmesh.geometry.Room`) without its exits, for the corner rays' visibility."""
    import shapely

    parts = []
    for lv in building.levels:
        if lv.name in names:
            parts.append(lv.room.walkable)
    for st in building.stairs:
        if st.name in names:
            parts.append(st.shape)
    union = shapely.union_all(parts)
    return _RegionRoom(union)


class _RegionRoom:
    """A stand-in for a room that only has a walkable area (what the corner rays read)."""

    def __init__(self, walkable) -> None:
        self.walkable = walkable


def stair_factors(surface: SurfaceMesh, phi: np.ndarray | None = None,
                  triangles: np.ndarray | None = None) -> np.ndarray:
    """The desired speed per triangle as a fraction of the level's (m,): 1 on the levels,
    and on a stair its ``speed_up`` where it is walked up, ``speed_down`` where down. Which
    way a stair is walked is read from the gradient of ``phi`` (a potential, e.g. the
    distance to the exits, decreasing towards them) along the stair's slope; without
    ``phi`` everyone goes down (the exits below). A stair without rise is a flat connector,
    walked at the level's speed. With ``triangles``: the factors of those only (the same
    numbers: each triangle's is its own)."""
    walked, up, down = _stair_speeds(surface)
    if triangles is not None:
        tris = np.asarray(triangles, np.int64)
        out = np.ones(len(tris))
        on = np.flatnonzero(walked[tris])
        t = tris[on]
        d = np.ones(len(t), bool) if phi is None else _walked_down(surface, phi, t)
        out[on] = np.where(d, down[t], up[t])
        return out
    out = np.ones(surface.n_triangles)
    for p in surface.pieces:
        tris = p.triangles
        if not (len(tris) and walked[tris[0]]):
            continue
        d = np.ones(len(tris), bool) if phi is None else _walked_down(surface, phi, tris)
        out[tris] = np.where(d, down[tris], up[tris])
    return out


def _walked_down(surface: SurfaceMesh, phi: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Whether each stair triangle ``tris`` is walked down: ``phi`` grows with the height
    in it (it falls towards the exits)."""
    pts = surface.points[surface.triangles[tris]]  # (k, 3, 3)
    dz = pts[:, :, 2] - pts[:, :, 2].mean(axis=1)[:, None]
    f = np.asarray(phi, float)[surface.triangles[tris]]
    dphi = f - f.mean(axis=1)[:, None]
    return np.sum(dz * dphi, axis=1) >= 0.0


def _stair_speeds(surface: SurfaceMesh) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(m,) per triangle: on a stair with a rise (walked at a stair speed), its speed up and
    its speed down as fractions of the level's (1 elsewhere)."""
    cache = surface._cache
    if "stair_speeds" not in cache:
        b = surface.building
        walked = np.zeros(surface.n_triangles, bool)
        up, down = np.ones(surface.n_triangles), np.ones(surface.n_triangles)
        for p in surface.pieces:
            if p.kind != "stair":
                continue
            st = next(x for x in b.stairs if x.name == p.name)
            if b.rise(st) == 0:
                continue
            walked[p.triangles] = True
            up[p.triangles] = st.speed_up
            down[p.triangles] = st.speed_down
        cache["stair_speeds"] = (walked, up, down)
    return cache["stair_speeds"]


def stair_costs(surface: SurfaceMesh, phi: np.ndarray | None = None, *,
                level_cost: float | np.ndarray = 1.0) -> np.ndarray:
    """The cost [s/m] per triangle of walking on the surface: ``level_cost`` on the levels
    (a scalar or one value per triangle) and on a stair ``level_cost / speed_up`` going up,
    ``/ speed_down`` going down (:func:`stair_factors`)."""
    base = np.broadcast_to(np.asarray(level_cost, float), (surface.n_triangles,)).copy()
    stair = surface.piece_is_stair[surface.piece]
    base[stair] = base[stair] / stair_factors(surface, phi)[stair]
    return base


def atlas_direction_field(atlas, phi: np.ndarray) -> DirectionField:
    """The desired-direction field of the surface potential ``phi`` (one value per surface
    vertex) on the building's atlas (:class:`~pedmesh.mesh.atlas.Atlas`), in each piece's
    chart. It is built on :attr:`~pedmesh.mesh.atlas.Atlas.steer`, where a stair edge is
    neither a wall nor an exit; the directions at the vertices along a stair edge (not its
    end points, which are on walls and keep their own side's, kept in the walkable wedge)
    are the descent of the gradients of the triangles on both sides."""
    pa = np.asarray(phi, float)[atlas.to_surface]
    df = DirectionField(atlas.steer, pa)
    merged = atlas.flat_steer
    if merged is not None:  # flat connectors: their groups steer as one room
        mesh, key = merged
        pm = np.empty(mesh.n_points)
        pm[key] = pa
        df.vertex_directions = DirectionField(mesh, pm).vertex_directions[key]
    hv = _hinge_inner_vertices(atlas)
    if len(hv):
        df.vertex_directions[hv] = hinge_inner_directions(atlas, df.triangle_gradients,
                                                          np.isfinite(pa[hv]))
        df._packed = None
    P = df.packed
    jr = _jamb_rows(atlas)
    t, col, val = hinge_jambs(atlas, pa[jr[:, 2]], pa[jr[:, 3]])
    P[t, col], P[t, col + 1] = val[:, 0], val[:, 1]
    t, col, val = inflow_hinges(atlas, df.triangle_directions)
    P[t, col], P[t, col + 1] = val[:, 0], val[:, 1]
    return df


def _hinge_edge_rows(atlas) -> tuple[np.ndarray, ...]:
    """The stair edges of :attr:`~pedmesh.mesh.atlas.Atlas.open`: each edge ``he``, its
    triangle ``t``, the edge's place ``loc`` in it and the triangle across it."""
    m = atlas.open
    cache = atlas.steer._cache
    if "hinge_edges" not in cache:
        he = atlas.hinge_edges
        t = m.edge_triangles[he, 0]
        loc = np.argmax(m.triangle_edges[t] == he[:, None], axis=1)
        g = atlas.glued
        both = g.edge_triangles[g.find_edges(m.edges[he])]
        across = np.where(both[:, 0] == t, both[:, 1], both[:, 0])
        cache["hinge_edges"] = (he, t, loc, across)
    return cache["hinge_edges"]


def inflow_hinges(atlas, triangle_directions: np.ndarray, rows: np.ndarray | None = None):
    """``(t, col, values)``: on the side of a stair edge where the route comes in over it
    (the direction of the triangle across it, ``triangle_directions`` (m, 2), points over
    it, to this side), the edge steers like a wall: its outward normal ``values`` (k, 2)
    goes into columns ``col``, ``col + 1`` of row ``t`` of the packed steering table
    (:func:`pedmesh.eikonal.direction._pack`), so that the component of the direction
    into it is removed near it (as at a wall,
    :func:`pedmesh.eikonal.direction._interpolate`) and nobody is steered onto a stair
    against the way over it, e.g. while turning round the end of the wall beside its foot.
    ``rows``: of those stair edges only (indices into :func:`_hinge_edge_rows`)."""
    he, t, loc, across = _hinge_edge_rows(atlas)
    if rows is not None:
        he, t, loc, across = he[rows], t[rows], loc[rows], across[rows]
    n = atlas.open.edge_normals[he]  # out of the triangle's side, over the edge
    d = triangle_directions[across]
    inflow = np.sum(d * n, axis=1) < 0.0
    return t[inflow], 12 + 2 * loc[inflow], n[inflow]


def _jamb_rows(atlas) -> np.ndarray:
    """(k, 4) rows (triangle, local corner, jamb vertex, the wall's other vertex) of
    :func:`hinge_jambs`."""
    cache = atlas.steer._cache
    if "hinge_jambs" not in cache:
        m = atlas.open
        rows = []  # (triangle, local corner, jamb vertex, the wall's other vertex)
        ptr, idx = m.vertex_triangles
        touches = np.zeros(m.n_triangles, bool)
        touches[m.edge_triangles[atlas.hinge_edges, 0]] = True
        ends = _wall_ends(atlas)
        for a, c in m.edges[m.wall_edges()]:
            for v, u in ((a, c), (c, a)):
                if not ends[v]:
                    continue
                for t in idx[ptr[v]:ptr[v + 1]]:
                    if not touches[t]:
                        rows.append((t, int(np.flatnonzero(m.triangles[t] == v)[0]), v, u))
        cache["hinge_jambs"] = np.array(rows, np.int64).reshape(-1, 4)
    return cache["hinge_jambs"]


def hinge_jambs(atlas, phi_v: np.ndarray, phi_u: np.ndarray, rows: np.ndarray | None = None):
    """``(t, col, values)``: where a stair edge ends on a wall that ends there too
    (:func:`_wall_ends`), in the triangles of the end point's fan that do not touch the
    stair edge, the end point's direction (columns ``col``, ``col + 1`` of row ``t`` of
    the packed steering table) is the wall's, the way the potential falls along it
    (towards the stair edge for those going onto it, away for those coming off it): a
    pedestrian who turns round the corner (the wall's end) is steered along the wall, not
    into it (as at a door jamb, :mod:`pedmesh.eikonal.direction`). ``phi_v``, ``phi_u``:
    the potential at the rows' jamb vertices and at the walls' other ends (of the rows
    ``rows`` of :func:`_jamb_rows` only, if given)."""
    jr = _jamb_rows(atlas)
    if rows is not None:
        jr = jr[rows]
    pts = atlas.open.points
    t, loc, v, u = jr.T
    d = pts[v] - pts[u]
    d /= np.hypot(d[:, 0], d[:, 1])[:, None]
    d = np.where((phi_v <= phi_u)[:, None], d, -d)  # (the way phi falls along the wall)
    ok = np.isfinite(phi_v) & np.isfinite(phi_u)
    return t[ok], 6 + 2 * loc[ok], d[ok]


def hinge_inner_directions(atlas, triangle_gradients: np.ndarray, finite: np.ndarray,
                           which: np.ndarray | None = None) -> np.ndarray:
    """(k, 2) the directions at the vertices along the stair edges
    (:func:`_hinge_inner_vertices`, or those of them at the indices ``which``): the
    descent of the area-weighted gradients ``triangle_gradients`` of the triangles around
    each on both sides of its edge, 0 where the potential is not ``finite`` (k,). Each
    vertex's is computed alone: a subset's are all's, bit for bit."""
    ring, ptr = _hinge_rings(atlas)
    if which is None:
        counts = np.diff(ptr)
        rows = ring
    else:
        counts = ptr[which + 1] - ptr[which]
        rows = ring[csr_ranges(ptr[which], counts)]
    g = atlas.glued
    w = g.areas[rows][:, None] * triangle_gradients[rows]
    sums = np.add.reduceat(w, np.concatenate([[0], np.cumsum(counts)[:-1]]), axis=0)
    norm = np.hypot(sums[:, 0], sums[:, 1])
    e = np.where(norm[:, None] > 0, -sums / np.where(norm > 0, norm, 1.0)[:, None], 0.0)
    e[~finite] = 0.0
    return e


def _hinge_rings(atlas) -> tuple[np.ndarray, np.ndarray]:
    """The triangles around each vertex of :func:`_hinge_inner_vertices` on both sides of
    its stair edge, CSR ``(triangles, ptr)``."""
    cache = atlas.steer._cache
    if "hinge_rings" not in cache:
        hv = _hinge_inner_vertices(atlas)
        ptr, idx = atlas.glued.vertex_triangles
        counts = np.diff(ptr)[hv]
        ring = idx[csr_ranges(ptr[hv], counts)]
        rptr = np.zeros(len(hv) + 1, np.int64)
        np.cumsum(counts, out=rptr[1:])
        cache["hinge_rings"] = (ring, rptr)
    return cache["hinge_rings"]


def _hinge_inner_vertices(atlas) -> np.ndarray:
    """The atlas vertices on a stair edge that are not on a wall, an obstacle or an exit."""
    cache = atlas.steer._cache
    if "hinge_inner" not in cache:
        b = atlas.open.boundary_edges
        other = np.setdiff1d(b, atlas.hinge_edges)  # walls, obstacles, the building's exits
        cache["hinge_inner"] = np.flatnonzero(atlas.boundary_vertices(atlas.hinge_edges)
                                              & ~atlas.boundary_vertices(other))
    return cache["hinge_inner"]


def _wall_ends(atlas) -> np.ndarray:
    """(n,) bool over the atlas vertices: the points where a stair edge ends on a wall and
    the wall ends too: the surface's angle about the point (both sides together) is
    reflex, e.g. the end of the thin wall between a stair and the level beside its foot
    (360 degrees). Where the walls of the two sides continue each other (180 degrees) or
    meet in a corner, nothing is done."""
    cache = atlas.steer._cache
    if "wall_ends" not in cache:
        m = atlas.open
        ends = np.flatnonzero(atlas.boundary_vertices(atlas.hinge_edges)
                              & atlas.boundary_vertices(m.wall_edges()))
        g = atlas.glued
        total = np.zeros(m.n_points)
        np.add.at(total, g.canon[g.triangles].ravel(), g.angles.ravel())
        out = np.zeros(m.n_points, bool)
        out[ends[total[g.canon[ends]] > np.pi + 0.1]] = True
        cache["wall_ends"] = out
    return cache["wall_ends"]


#: [m] the radius of the discs about the ends of the walls beside a stair's ends, and the
#: factor of the walking cost in them (:func:`_corner_costs`)
CORNER_RADIUS = 0.5
CORNER_COST = 3.0


def _corner_costs(atlas) -> np.ndarray:
    """(m,) 1, and :data:`CORNER_COST` in the triangles within :data:`CORNER_RADIUS` of a
    point where a stair edge ends on a wall that ends there too (:func:`_wall_ends`), e.g.
    the wall between a stair and the level beside its foot: the way from one to the other
    turns round that end, and a route that grazes it steers a pedestrian (who has a body)
    straight into it. With the corners dearer the routes keep their distance, as people
    do."""
    s = atlas.surface
    ends = np.unique(atlas.to_surface[np.flatnonzero(_wall_ends(atlas))])
    out = np.ones(s.n_triangles)
    if len(ends) == 0:
        return out
    from scipy.spatial import cKDTree

    near = cKDTree(s.points[ends]).query_ball_point(s.centroids, CORNER_RADIUS)
    out[np.array([len(n) > 0 for n in near])] = CORNER_COST
    return out


class BuildingRoutes:
    """Routes of a building for the models that run on its atlas: the potential on the
    surface (:class:`SurfaceEikonalSolver`, the stairs at their speeds up or down), its
    direction field on the atlas (:func:`atlas_direction_field`) and the stair speed factor
    of every triangle (:func:`stair_factors`)."""

    def __init__(self, atlas, exits: Sequence[str | int] | None = None) -> None:
        self.atlas = atlas
        self.surface = atlas.surface
        self.solver = SurfaceEikonalSolver(self.surface, exits)
        self._phi: np.ndarray | None = None
        self.corner_cost = _corner_costs(atlas)


    def solve(self, level_cost: float | np.ndarray = 1.0):
        """``(phi, field, factors)``: the potential (surface vertices) for the level cost
        [s/m] (a scalar, or one value per surface vertex or triangle), its direction field
        on the atlas and the stair factors per triangle. Which way each stair is walked
        comes from the previous solve (the first: from the distance)."""
        s = self.surface
        c = np.asarray(level_cost, float)
        if c.shape == (s.n_points,):
            c = c[s.triangles].mean(axis=1)
        if self._phi is None:
            self._phi = self.solver.solve(1.0)
        factors = stair_factors(s, self._phi)
        cost = np.broadcast_to(c, (s.n_triangles,)) / factors * self.corner_cost
        phi = self.solver.solve(np.ascontiguousarray(cost))
        self._phi = phi
        return phi, atlas_direction_field(self.atlas, phi), stair_factors(s, phi)


def surface_gradient(surface: SurfaceMesh, phi: np.ndarray) -> np.ndarray:
    """The gradient (m, 3) of the piecewise-linear ``phi`` in each triangle's plane (tangent
    to the surface): ``-gradient / |gradient|`` is the walking direction."""
    p = surface.points[surface.triangles]  # (m, 3, 3)
    f = np.asarray(phi, float)[surface.triangles]
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    d1, d2 = f[:, 1] - f[:, 0], f[:, 2] - f[:, 0]
    # g = a e1 + b e2 with g.e1 = d1, g.e2 = d2 (the Gram system of the triangle)
    g11 = np.sum(e1 * e1, axis=1)
    g12 = np.sum(e1 * e2, axis=1)
    g22 = np.sum(e2 * e2, axis=1)
    det = g11 * g22 - g12 * g12
    a = (d1 * g22 - d2 * g12) / det
    b = (d2 * g11 - d1 * g12) / det
    return a[:, None] * e1 + b[:, None] * e2
