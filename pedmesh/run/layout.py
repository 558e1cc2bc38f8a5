"""A building run laid out flat for pictures (``pedmesh animate``, ``pedmesh report``).

A building's frames are in 3-D: drawn in plan, its floors would lie on top of each other.
:func:`building_layout` rebuilds the run's surface mesh from the room file and the mesh
settings the run recorded, checks it is the frames' mesh, and lays it out as people read
building plans (:class:`BuildingLayout`): one panel per level in its own plan coordinates,
each stair where it is, labelled with its name and the level it leads to, on both levels
it joins, the start areas with their counts; the cells in the frames' order. Pedestrians
go there by the level or stair their frame names (the ``piece`` array of
pedestrians.pvd).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import PedmeshError

__all__ = ["BuildingLayout", "building_layout", "find_room_file"]


def find_room_file(geometry: str | None, base: Path,
                   sha: str | None) -> tuple[Path | None, str]:
    """The room file a run names (as given, or relative to the run folder and the folders
    above it) and a note: '' when found with the recorded hash."""
    if not geometry:
        return None, "the run names no room file"
    g = Path(geometry)
    cands = [g] if g.is_absolute() else [g] + [d / g for d in [base, *base.resolve().parents]]
    found = [c for c in cands if c.is_file()]
    if not found:
        return None, f"the room file {geometry} was not found"
    if sha:
        from .output import file_sha256

        for c in found:
            if file_sha256(c) == sha:
                return c, ""
        return found[0], (f"the room file {found[0]} has changed since the run (its SHA-256 "
                          "differs from the one recorded); the plan shows the file as it is now")
    return found[0], ""


@dataclass(frozen=True, eq=False)
class BuildingLayout:
    """A building drawn as people read building plans: one panel per level, in the
    level's own plan coordinates shifted to its panel, the levels in order left to right
    and top to bottom; each stair drawn in plan where it is, its cells on its bottom level's
    panel and its outline on both levels' panels, labelled with its name and direction.

    ``points`` (n, 2) [m] and ``triangles`` (m, 3): the atlas mesh with every vertex at its
    plan position in its panel (cell t is the frames' cell t); ``walls`` (k, 2, 2),
    ``exits`` (e, 2, 2) and ``stair_edges`` (j, 2, 2) [m] in the panels; ``labels`` the name
    of each level with a point [m] (its panel's top left); ``stairs`` each stair's outline
    (s, 2) [m] on a panel with its label and a point for it; ``start_areas`` each start
    area's outline with its name and count; ``panel_shift`` per level name, the shift [m]
    from its plan to its panel; ``panels`` each level's panel box (x0, y0, x1, y1) [m]."""

    atlas: object
    points: np.ndarray
    triangles: np.ndarray
    walls: np.ndarray
    exits: np.ndarray
    stair_edges: np.ndarray
    labels: tuple[tuple[str, tuple[float, float]], ...]
    stairs: tuple = ()
    start_areas: tuple = ()
    panel_shift: dict | None = None
    panels: tuple = ()
    piece_shift: np.ndarray | None = None

    def crowd(self, xyz: np.ndarray, piece: np.ndarray) -> np.ndarray:
        """Panel points (k, 2) [m] of 3-D positions ``xyz`` (k, 3) on pieces ``piece``:
        their plan position shifted to the panel of their level (a stair's: its bottom
        level's)."""
        xyz = np.asarray(xyz, float).reshape(-1, 3)
        piece = np.asarray(piece, np.int64).reshape(-1)
        return xyz[:, :2] + self.piece_shift[piece]

    def draw(self, ax, *, lw: float = 1.0, labels: bool = True) -> None:
        """The panels' frames, the walls (black), the exits (green), the stairs (grey,
        labelled, with their edges dashed), the start areas with their counts and the
        names of the levels on a matplotlib axes."""
        from matplotlib.collections import LineCollection
        from matplotlib.patches import Polygon as MplPolygon, Rectangle

        for x0, y0, x1, y1 in self.panels:
            ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, ec="0.8",
                                   lw=0.6 * lw, zorder=0))
        ax.add_collection(LineCollection(self.walls, colors="k", linewidths=lw))
        ax.add_collection(LineCollection(self.exits, colors="#00a651", linewidths=4 * lw,
                                         zorder=4))
        ax.add_collection(LineCollection(self.stair_edges, colors="0.45", linewidths=0.6 * lw,
                                         linestyles="dashed"))
        for poly, text, at in self.stairs:
            ax.add_patch(MplPolygon(poly, closed=True, fill=False, ec="0.35", lw=0.8 * lw,
                                    ls="--", zorder=3))
            if labels:
                ax.annotate(text, at, ha="center", va="center", fontsize=6, color="0.15",
                            zorder=7)
        for poly, text, at in self.start_areas:
            ax.add_patch(MplPolygon(poly, closed=True, fc="#1f77b4", alpha=0.12,
                                    ec="#1f77b4", lw=0.6 * lw, zorder=2))
            if labels:
                ax.annotate(text, at, ha="center", va="center", fontsize=6, color="#1f4e79",
                            zorder=7)
        if labels:
            for name, (x, y) in self.labels:
                ax.annotate(name, (x, y), ha="left", va="bottom", fontsize=8,
                            fontweight="bold", color="0.1", zorder=6)


def building_layout(summary: dict, run_dir: Path,
                    n_cells: int | None = None) -> tuple[BuildingLayout | None, str]:
    """The layout of a building run (``summary`` its summary.json) and a note; ``(None,
    note)`` where the room file is missing, is not a building, or no longer gives the
    frames' mesh (``n_cells`` cells)."""
    from ..geometry.site import is_building
    from ..io import load_room

    settings = summary.get("settings") or {}
    path, note = find_room_file(summary.get("geometry"), Path(run_dir),
                                settings.get("room_sha256"))
    if path is None:
        return None, note
    try:
        room = load_room(path)
    except PedmeshError as exc:
        return None, f"the room file {path} could not be read: {exc}"
    if not is_building(room):
        return None, ""
    from ..mesh.site import mesh_site
    from ..mesh.atlas import build_atlas
    from ..mesh.triangle_mesh import BoundaryKind

    opts = {k: v for k, v in (settings.get("mesh") or {}).items()
            if k in ("max_area", "min_angle", "feature_area") and v is not None}
    try:
        surface = mesh_site(room, **opts)
    except PedmeshError as exc:
        return None, f"the building {path} could not be meshed again: {exc}"
    if n_cells is not None and surface.n_triangles != n_cells:
        return None, (f"the building {path} meshes into {surface.n_triangles} cells, the "
                      f"run's frames have {n_cells}: its floors are drawn on top of each other")
    atlas = build_atlas(surface)
    return _plan_layout(room, surface, atlas), ""


def _plan_layout(building, surface, atlas) -> BuildingLayout:
    """The panels of :class:`BuildingLayout` for ``building`` (its surface and atlas)."""
    import math

    from ..mesh.triangle_mesh import BoundaryKind

    pieces = surface.pieces
    levels = [lv.name for lv in building.levels]
    bottom = {st.name: st.bottom.level for st in building.stairs}
    top = {st.name: st.top.level for st in building.stairs}
    # the panels: every level's plan box (stairs included), the same size, in a grid
    xy = np.asarray(surface.points)[:, :2]
    x0, y0 = xy.min(axis=0)
    x1, y1 = xy.max(axis=0)
    w, h = x1 - x0, y1 - y0
    gap = 0.12 * max(w, h) + 2.0
    cols = max(1, min(len(levels), math.ceil(math.sqrt(len(levels) * h / max(w, 1e-9)))))
    shift = {}
    panels = []
    for k, name in enumerate(levels):
        r, c = divmod(k, cols)
        dx, dy = c * (w + gap) - x0, -r * (h + gap) - y0
        shift[name] = np.array([dx, dy])
        panels.append((x0 + dx - 0.5, y0 + dy - 0.5, x1 + dx + 0.5, y1 + dy + 1.8))
    piece_shift = np.array([shift[p.name] if p.kind == "level" else shift[bottom[p.name]]
                            for p in pieces])
    m = atlas.open
    tri = np.asarray(m.triangles)
    vpiece = np.zeros(m.n_points, np.int64)
    vpiece[tri.ravel()] = np.repeat(np.asarray(atlas.glued.piece), 3)
    pts = xy[np.asarray(atlas.to_surface)] + piece_shift[vpiece]
    b = m.boundary_edges
    hinge = np.isin(b, atlas.hinge_edges)
    door = (m.edge_kind[b] == BoundaryKind.EXIT) & ~hinge
    labels = tuple((name, (float(panels[k][0] + 0.3), float(panels[k][3] - 1.5)))
                   for k, name in enumerate(levels))
    stairs = []
    texts: dict[tuple, list[str]] = {}  # (stairs stacked in plan: one label of lines)
    for st in building.stairs:
        poly = np.asarray(st.polygon, float)
        c = poly.mean(axis=0)
        for lv, text in ((bottom[st.name], f"{st.name} ↑ {top[st.name]}"),
                         (top[st.name], f"{st.name} ↓ {bottom[st.name]}")):
            at = tuple(np.round(c + shift[lv], 1))
            if at not in texts:
                texts[at] = []
                stairs.append((poly + shift[lv], texts[at], at))
            texts[at].append(text)
    stairs = [(poly, "\n".join(lines), at) for poly, lines, at in stairs]
    areas = []
    for lv in building.levels:
        for a in lv.room.start_areas:
            poly = np.asarray(a.polygon, float) + shift[lv.name]
            n = len(a.positions(lv.room.walkable))
            at = np.asarray(a.shape.representative_point().coords[0]) + shift[lv.name]
            areas.append((poly, f"{a.name}: {n}", tuple(at)))
    return BuildingLayout(atlas=atlas, points=pts, triangles=tri,
                          walls=pts[m.edges[b[~hinge & ~door]]],
                          exits=pts[m.edges[b[door]]],
                          stair_edges=pts[m.edges[b[hinge]]],
                          labels=labels, stairs=tuple(stairs), start_areas=tuple(areas),
                          panel_shift=shift, panels=tuple(panels), piece_shift=piece_shift)
