"""Triangulate a building into one surface: every level and stair meshed in its own chart
(:mod:`pedmesh.mesh.triangulate`), lifted to 3-D and stitched along the stair edges.

A stair edge is meshed on both sides with the same vertices: each hinge is first split
into pieces of about the feature size, handed to both pieces as a polyline (an exit of the
mesher, so the grading treats it as an opening), and where Triangle splits a hinge segment
further on one side, the points are added to both and the two pieces meshed again.
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np

from ..errors import MeshError, PedmeshError
from .surface import Piece, SurfaceMesh
from .triangle_mesh import BoundaryKind, TriMesh
from .triangulate import FEATURE_AREA, MAX_AREA, MIN_ANGLE, triangulate

__all__ = ["triangulate_building", "piece_segments", "building_fingerprint", "HINGE_PREFIX"]

#: the name prefix of the mesher's exits that are stair edges (never a real exit's name)
HINGE_PREFIX = "\u2195hinge:"
#: rounds of re-meshing until both sides of every stair edge share their vertices
MAX_STITCH_ROUNDS = 8


def _edge_len(area: float) -> float:
    """The edge length [m] of an equilateral triangle of ``area`` [m^2]."""
    return math.sqrt(4.0 * area / math.sqrt(3.0))


class _StairChart:
    """The chart of a stair: its plane unrolled about its bottom edge (plan -> chart
    stretches distances along the run direction by L/run, the slope's length over the
    plan's)."""

    def __init__(self, building, stair) -> None:
        self.d, self.run = stair.run_direction()
        self.o = np.asarray(stair.bottom.edge[0], float)
        self.rise = building.rise(stair)
        self.k = math.hypot(self.run, self.rise) / self.run
        self.z0 = building.level(stair.bottom.level).z

    def to_chart(self, xy: np.ndarray) -> np.ndarray:
        xy = np.asarray(xy, float).reshape(-1, 2)
        along = (xy - self.o) @ self.d
        return xy + ((self.k - 1.0) * along)[:, None] * self.d

    def to_3d(self, uv: np.ndarray) -> np.ndarray:
        uv = np.asarray(uv, float).reshape(-1, 2)
        along = (uv - self.o) @ self.d / self.k  # plan distance from the bottom edge
        xy = uv - ((self.k - 1.0) * along)[:, None] * self.d
        return np.column_stack([xy, self.z0 + self.rise * along / self.run])

    def frame(self) -> tuple[np.ndarray, np.ndarray]:
        """origin (3,) and axes (2, 3) of the chart in 3-D."""
        p = self.to_3d(np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]))
        return p[0], np.array([p[1] - p[0], p[2] - p[0]])


def _hinges(building) -> list[dict]:
    """Every stair edge: the stair, which end, the level, and its plan segment."""
    out = []
    for s in building.stairs:
        for end in ("bottom", "top"):
            e = getattr(s, end)
            out.append({"stair": s, "end": end, "level": e.level,
                        "a": np.asarray(e.edge[0], float), "b": np.asarray(e.edge[1], float),
                        "name": f"{HINGE_PREFIX}{s.name}:{end}"})
    return out


def _on_exit(mesh: TriMesh, name: str) -> np.ndarray:
    """The vertices of ``mesh`` on its exit ``name`` (a hinge: the mesher's exit), sorted."""
    k = mesh.exit_names.index(name)
    sel = (mesh.segment_kind == BoundaryKind.EXIT) & (mesh.segment_owner == k)
    return np.unique(mesh.segments[sel])


def _params_on(mesh: TriMesh, name: str, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The parameters s in [0, 1] along a -> b of the vertices on hinge exit ``name``."""
    v = _on_exit(mesh, name)
    ab = b - a
    return np.sort((mesh.points[v] - a) @ ab / (ab @ ab))


def building_fingerprint(building) -> str:
    """SHA-256 (hex) of what a mesh of ``building`` depends on: each level's name, height
    and room (:func:`~pedmesh.mesh.triangle_mesh.room_fingerprint`) and each stair's name,
    plan polygon and ends. Crowds, stair speeds and descriptions do not count."""
    import hashlib

    from .triangle_mesh import room_fingerprint

    cache = getattr(building, "_cache", None)
    if isinstance(cache, dict) and "mesh_fingerprint" in cache:
        return cache["mesh_fingerprint"]
    h = hashlib.sha256()
    for lv in building.levels:
        h.update(repr(("level", lv.name, float(lv.z), room_fingerprint(lv.room))).encode())
    for st in building.stairs:
        h.update(repr(("stair", st.name, st.bottom.level, st.top.level)).encode())
        for arr in (st.polygon, st.bottom.edge, st.top.edge):
            a = np.ascontiguousarray(np.asarray(arr, np.float64))
            h.update(f"{a.shape}".encode())
            h.update(a.tobytes())
    h.update(repr(tuple(building.exit_names)).encode())
    fp = h.hexdigest()
    if isinstance(cache, dict):
        cache["mesh_fingerprint"] = fp
    return fp


def triangulate_building(building, max_area: float = MAX_AREA, min_angle: float = MIN_ANGLE,
                         *, feature_area: float | None = FEATURE_AREA,
                         max_cells: float | None = None,
                         size_of: Callable | None = None) -> SurfaceMesh:
    """One surface mesh of ``building`` (a :class:`~pedmesh.geometry.Building`): every
    level and stair triangulated as :func:`~pedmesh.mesh.triangulate` does a room, with
    the same options, then lifted to 3-D and stitched along the stair edges. ``size_of``:
    a function of a piece's room (a level's, or a stair's in its own chart, its stair
    edges as exits) giving that piece's custom size field (``size`` of
    :func:`~pedmesh.mesh.triangulate`)."""
    hinges = _hinges(building)
    h = _edge_len(min(max_area, feature_area or max_area))
    for hg in hinges:  # the first split: pieces of about the feature size
        n = max(1, math.ceil(np.linalg.norm(hg["b"] - hg["a"]) / h))
        hg["s"] = np.linspace(0.0, 1.0, n + 1)
    charts = {s.name: _StairChart(building, s) for s in building.stairs}
    opts = dict(max_area=max_area, min_angle=min_angle, feature_area=feature_area,
                max_cells=max_cells, size_of=size_of)
    # a piece's mesh depends only on its own outline and the splits of its own hinges: a
    # round meshes again only the pieces one of whose hinges changed (the same input, so
    # the same mesh as meshing every piece again)
    levels: list = [None] * len(building.levels)
    stairs: list = [None] * len(building.stairs)
    used: dict = {}  # piece -> the splits of its hinges it was meshed with

    def splits(mine) -> tuple:
        return tuple(hg["s"].tobytes() for hg in mine)

    for _ in range(MAX_STITCH_ROUNDS):
        for k, lv in enumerate(building.levels):
            key = splits([hg for hg in hinges if hg["level"] == lv.name])
            if used.get(("level", k)) != key:
                levels[k], used[("level", k)] = _mesh_level(lv, hinges, opts), key
        for k, st in enumerate(building.stairs):
            key = splits([hg for hg in hinges if hg["stair"] is st])
            if used.get(("stair", k)) != key:
                stairs[k] = _mesh_stair(st, charts[st.name], hinges, opts)
                used[("stair", k)] = key
        if not _refine_hinges(building, hinges, levels, stairs, charts):
            break
    else:
        raise MeshError(f"building '{building.name}': the two sides of a stair edge could "
                        f"not be meshed alike in {MAX_STITCH_ROUNDS} rounds")
    return _stitch(building, hinges, levels, stairs, charts)


def _mesh_level(lv, hinges, opts) -> TriMesh:
    from ..geometry import Exit

    mine = [hg for hg in hinges if hg["level"] == lv.name]
    extra = [Exit(hg["name"], [tuple(hg["a"] + s * (hg["b"] - hg["a"])) for s in hg["s"]])
             for hg in mine]
    try:
        room = lv.room.with_changes(exits=tuple(lv.room.exits) + tuple(extra))
        return _triangulate_piece(room, opts)
    except PedmeshError as exc:  # (in the file's words: no internal stair-edge names)
        raise type(exc)(f"level '{lv.name}': {plain_words(str(exc))}") from None


def plain_words(message: str) -> str:
    """``message`` with the mesher's internal names of stair edges (``'↕hinge:NAME:END'``)
    written as the file says them (``the END edge of stair 'NAME'``)."""
    import re

    return re.sub(re.escape(HINGE_PREFIX) + r"(.+?):(top|bottom)'?",
                  lambda m: f"the {m.group(2)} edge of stair '{m.group(1)}'",
                  message.replace("exit '" + HINGE_PREFIX, HINGE_PREFIX))


def _triangulate_piece(room, opts) -> TriMesh:
    """:func:`~pedmesh.mesh.triangulate` of one piece's room with the building's options
    (``size_of``, if given, makes the piece's own size field)."""
    opts = dict(opts)
    size_of = opts.pop("size_of", None)
    if size_of is not None:
        opts["size"] = size_of(room)
    return triangulate(room, **opts)


def _mesh_stair(s, chart: _StairChart, hinges, opts) -> TriMesh:
    from ..geometry import Exit, Room

    ends = [hg for hg in hinges if hg["stair"] is s]
    exits = []
    for hg in ends:
        line = np.array([hg["a"] + t * (hg["b"] - hg["a"]) for t in hg["s"]])
        exits.append(Exit(hg["name"], [tuple(p) for p in chart.to_chart(line)]))
    try:
        room = Room(outline=[tuple(p) for p in chart.to_chart(np.asarray(s.polygon))],
                    exits=exits, name=s.name)
        return _triangulate_piece(room, opts)
    except PedmeshError as exc:  # (in the file's words: no internal stair-edge names)
        raise type(exc)(f"stair '{s.name}': {plain_words(str(exc))}") from None


def _refine_hinges(building, hinges, levels, stairs, charts) -> bool:
    """Add to each hinge's split the points Triangle put on either side; True if any hinge
    changed (the pieces are meshed again)."""
    changed = False
    lv_index = {lv.name: k for k, lv in enumerate(building.levels)}
    st_index = {s.name: k for k, s in enumerate(building.stairs)}
    for hg in hinges:
        ch = charts[hg["stair"].name]
        a_c, b_c = ch.to_chart(np.array([hg["a"], hg["b"]]))
        s1 = _params_on(levels[lv_index[hg["level"]]], hg["name"], hg["a"], hg["b"])
        s2 = _params_on(stairs[st_index[hg["stair"].name]], hg["name"], a_c, b_c)
        union = np.unique(np.round(np.concatenate([hg["s"], s1, s2]), 12))
        if len(union) != len(hg["s"]) or len(s1) != len(union) or len(s2) != len(union):
            changed = changed or len(union) != len(hg["s"]) or len(s1) != len(s2)
            hg["s"] = union
    return changed


def _stitch(building, hinges, levels, stairs, charts) -> SurfaceMesh:
    """Lift every piece to 3-D, merge the vertices of each stair edge, gather the tags."""
    points, tris, piece_of, pieces = [], [], [], []
    seg, kind, owner = [], [], []
    exit_names = list(building.exit_names)
    obstacle_names: list[str] = []
    offset = 0
    parts = [(lv.name, "level", m, None) for lv, m in zip(building.levels, levels)]
    parts += [(s.name, "stair", m, charts[s.name]) for s, m in zip(building.stairs, stairs)]
    z_of = {lv.name: lv.z for lv in building.levels}
    for k, (name, kind_, m, chart) in enumerate(parts):
        if chart is None:
            p3 = np.column_stack([m.points, np.full(m.n_points, z_of[name])])
            origin = np.array([0.0, 0.0, z_of[name]])
            axes = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
        else:
            p3 = chart.to_3d(m.points)
            origin, axes = chart.frame()
        points.append(p3)
        tris.append(m.triangles + offset)
        piece_of.append(np.full(m.n_triangles, k))
        rows, _ = piece_segments(name, m, exit_names, obstacle_names)  # (stair edges: interior)
        for j, sk, so in rows:
            seg.append(m.segments[j] + offset)
            kind.append(sk)
            owner.append(so)
        pieces.append((name, kind_, m, offset, origin, axes))
        offset += m.n_points
    pts = np.concatenate(points)
    # merge each stair edge's vertices: the stair's copies become the level's
    remap = np.arange(len(pts))
    index_of = {p[0]: k for k, p in enumerate(pieces)}
    for hg in hinges:
        lv_k, st_k = index_of[hg["level"]], index_of[hg["stair"].name]
        along = np.append(hg["b"] - hg["a"], 0.0)  # the hinge is horizontal: a -> b in 3-D
        va = _hinge_vertices(pieces[lv_k], hg["name"], pts, along)
        vb = _hinge_vertices(pieces[st_k], hg["name"], pts, along)
        if len(va) != len(vb) or not np.allclose(pts[va], pts[vb], atol=1e-6):
            raise MeshError(f"stair '{hg['stair'].name}': its {hg['end']} edge was meshed "
                            "differently on its two sides")
        remap[vb] = va
    keep = np.unique(remap)
    new_index = np.full(len(pts), -1, np.int64)
    new_index[keep] = np.arange(len(keep))
    final = new_index[remap]
    tri = final[np.concatenate(tris)]
    piece_of = np.concatenate(piece_of)
    out_pieces = []
    for k, (name, kind_, m, off, origin, axes) in enumerate(pieces):
        verts = final[off + np.arange(m.n_points)]
        out_pieces.append(Piece(name, kind_, m, verts, np.flatnonzero(piece_of == k), origin,
                                axes))
    return SurfaceMesh(points=pts[keep], triangles=tri, piece=piece_of,
                       pieces=tuple(out_pieces), segments=final[np.array(seg).reshape(-1, 2)],
                       segment_kind=np.array(kind, np.int8), segment_owner=np.array(owner),
                       exit_names=tuple(exit_names), obstacle_names=tuple(obstacle_names),
                       building=building)


def piece_segments(name: str, m: TriMesh, exit_names: list[str],
                   obstacle_names: list[str]) -> tuple[list, list]:
    """The tagged boundary of piece ``name``'s chart mesh ``m``: ``(j, kind, owner)`` of
    each wall, obstacle and exit segment ``m.segments[j]``, with the exits numbered as in
    ``exit_names`` and the obstacles as in ``obstacle_names`` (one number per obstacle,
    named ``PIECE/OBSTACLE``; the list grows), and ``(j, name)`` of each stair-edge segment."""
    rows, hinges = [], []
    for j in range(len(m.segments)):
        sk, so = int(m.segment_kind[j]), int(m.segment_owner[j])
        if sk == BoundaryKind.EXIT:
            ename = m.exit_names[so]
            if ename.startswith(HINGE_PREFIX):
                hinges.append((j, ename))
                continue
            so = exit_names.index(ename)
        elif sk == BoundaryKind.OBSTACLE:
            oname = f"{name}/{m.obstacle_names[so]}"
            if oname not in obstacle_names:
                obstacle_names.append(oname)
            so = obstacle_names.index(oname)
        rows.append((j, sk, so))
    return rows, hinges


def _hinge_vertices(piece, name: str, pts: np.ndarray, along: np.ndarray) -> np.ndarray:
    """The (global, pre-merge) vertices of a piece on hinge ``name``, in order along the
    hinge's direction ``along`` (3,)."""
    _, _, m, off, _, _ = piece
    v = _on_exit(m, name) + off
    return v[np.argsort(pts[v] @ along, kind="stable")]
