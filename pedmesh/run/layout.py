"""A building run laid out flat for pictures (``pedmesh animate``, ``pedmesh report``).

A building's frames are in 3-D: drawn in plan, its floors would lie on top of each other.
:func:`building_layout` rebuilds the run's surface mesh from the room file and the mesh
settings the run recorded, checks it is the frames' mesh, and returns its atlas
(:class:`~pedmesh.mesh.atlas.Atlas`): every level and stair in its own chart, side by side
in one plane, stacked floors apart, the cells in the frames' order. Pedestrians go there
by the level or stair their frame names (the ``piece`` array of pedestrians.pvd).
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
    """A building's atlas for drawing: ``points`` (n, 2) [m] and ``triangles`` (m, 3) (cell
    t is the frames' cell t), ``walls`` (k, 2, 2) [m] the walls and obstacle sides,
    ``exits`` (e, 2, 2) [m] the building's exits, ``stair_edges`` (j, 2, 2) [m] the stair
    edges (each on both of its pieces) and ``labels`` the name of each level with a point
    [m] inside it."""

    atlas: object
    points: np.ndarray
    triangles: np.ndarray
    walls: np.ndarray
    exits: np.ndarray
    stair_edges: np.ndarray
    labels: tuple[tuple[str, tuple[float, float]], ...]

    def crowd(self, xyz: np.ndarray, piece: np.ndarray) -> np.ndarray:
        """Atlas points (k, 2) [m] of 3-D positions ``xyz`` (k, 3) on pieces ``piece``."""
        xyz = np.asarray(xyz, float).reshape(-1, 3)
        piece = np.asarray(piece, np.int64).reshape(-1)
        out = np.empty((len(xyz), 2))
        for k, p in enumerate(self.atlas.surface.pieces):
            sel = piece == k
            if sel.any():
                out[sel] = p.to_chart(xyz[sel]) + self.atlas.offset[k]
        return out

    def draw(self, ax, *, lw: float = 1.0, labels: bool = True) -> None:
        """The walls (black), the exits (green), the stair edges (grey, dashed) and the
        names of the levels on a matplotlib axes."""
        from matplotlib.collections import LineCollection

        ax.add_collection(LineCollection(self.walls, colors="k", linewidths=lw))
        ax.add_collection(LineCollection(self.exits, colors="#00a651", linewidths=4 * lw,
                                         zorder=4))
        ax.add_collection(LineCollection(self.stair_edges, colors="0.45", linewidths=0.6 * lw,
                                         linestyles="dashed"))
        if labels:
            for name, (x, y) in self.labels:
                ax.annotate(name, (x, y), ha="center", va="center", fontsize=7,
                            color="0.2", alpha=0.8, zorder=6)


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
    from ..geometry.site import mesh_site
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
    m = atlas.open
    b = m.boundary_edges
    hinge = np.isin(b, atlas.hinge_edges)
    door = (m.edge_kind[b] == BoundaryKind.EXIT) & ~hinge
    labels = []
    for k, p in enumerate(surface.pieces):
        if p.kind != "level":  # (the stairs are small: their names would cover them)
            continue
        tris = p.mesh.triangles
        c = p.mesh.points[tris].mean(axis=1)
        w = p.mesh.areas
        centre = (w[:, None] * c).sum(axis=0) / w.sum()
        # the centroid of the cell nearest the area's centre (inside an L-shaped level)
        at = c[np.argmin(np.hypot(*(c - centre).T))] + atlas.offset[k]
        labels.append((p.name, (float(at[0]), float(at[1]))))
    return BuildingLayout(atlas=atlas, points=np.asarray(m.points),
                          triangles=np.asarray(m.triangles),
                          walls=np.asarray(m.points)[m.edges[b[~hinge & ~door]]],
                          exits=np.asarray(m.points)[m.edges[b[door]]],
                          stair_edges=np.asarray(m.points)[m.edges[b[hinge]]],
                          labels=tuple(labels)), ""
