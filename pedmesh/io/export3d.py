"""A 3-D model of a room and its crowd (trimesh), for Blender, web viewers and slides.

:func:`export_room_3d` builds a scene in metres with z up:

* ``floor``: the walkable area (the room's triangle mesh), light grey;
* ``walls``: the outline as a solid band ``wall_thickness`` thick outside the walkable area,
  ``wall_height`` high, with a gap at every exit on the outline, grey;
* ``obstacles``: each obstacle extruded to ``wall_height``, dark grey;
* ``exits``: a green strip on the floor along every exit;
* ``crowd`` (if positions are given): one upright cylinder per pedestrian (radius
  ``body_radius``, height ``body_height``), blue.

The suffix picks the format: ``.glb`` (binary glTF 2.0, one file, colours kept; Blender's
File > Import > glTF, three.js, https://gltf-viewer.donmccurdy.com), ``.gltf`` (glTF with
embedded buffers), ``.obj``, ``.ply``, ``.stl`` (one merged mesh; STL has no colours).

Axes: glTF's up axis is +y and Blender's OBJ importer and three.js take OBJ files as y-up
too, so ``.glb``, ``.gltf`` and ``.obj`` files hold the scene turned z-up to y-up, as the
point (x, y, z) -> (x, z, -y) (glTF: a rotation on every node; the meshes stay in the room's
frame); the importers turn it back, so the floor lies flat. ``.ply`` and ``.stl`` stay
z-up, as Blender reads them.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import PedmeshError
from ..mesh.triangulate import triangulate

__all__ = ["room_scene", "export_room_3d", "read_positions", "FORMATS", "Z_UP_TO_Y_UP"]

FORMATS = (".glb", ".gltf", ".obj", ".ply", ".stl")
#: z-up (pedmesh) to y-up (glTF, OBJ): (x, y, z) -> (x, z, -y)
Z_UP_TO_Y_UP = np.array([[1.0, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 0], [0, 0, 0, 1]])
Y_UP_SUFFIXES = (".glb", ".gltf", ".obj")
_COLOURS = {"stairs": (205, 160, 90, 255),
            "floor": (225, 225, 220, 255), "walls": (150, 150, 150, 255),
            "obstacles": (95, 95, 100, 255), "exits": (40, 170, 60, 255),
            "crowd": (40, 90, 200, 255)}


def _coloured(mesh, name: str):
    mesh.visual.face_colors = np.tile(np.array(_COLOURS[name], np.uint8), (len(mesh.faces), 1))
    mesh.metadata["name"] = name
    return mesh


def _extrude(shape, height: float):
    import shapely
    import trimesh

    parts = [shape] if shape.geom_type == "Polygon" else list(getattr(shape, "geoms", []))
    solids = [trimesh.creation.extrude_polygon(shapely.orient_polygons(p), height,
                                               engine="triangle")
              for p in parts if p.geom_type == "Polygon" and p.area > 1e-12]
    return trimesh.util.concatenate(solids) if solids else None


#: [m] the largest wall height, wall thickness, body radius or height taken (a taller wall
#: is no room's; 1e300 made infinite vertices)
MAX_SIZE_M = 1000.0


def room_scene(room, *, mesh=None, positions: np.ndarray | None = None,
               wall_height: float = 2.5, wall_thickness: float = 0.2,
               body_radius: float = 0.2, body_height: float = 1.75, openings=()):
    """The room (and crowd at ``positions`` (n, 2) [m]) as a ``trimesh.Scene`` (see the
    module docstring); ``mesh``: the room's TriMesh for the floor (default: a new one);
    ``openings``: more wall segments ((x, y), (x, y)) left open besides the exits (a
    building's stair edges)."""
    import shapely
    import trimesh

    for label, v in (("wall_height", wall_height), ("wall_thickness", wall_thickness),
                     ("body_radius", body_radius), ("body_height", body_height)):
        if not (np.isfinite(v) and 0 < v <= MAX_SIZE_M):
            raise PedmeshError(f"{label} must be a positive number of metres up to "
                               f"{MAX_SIZE_M:g}, got {v!r}")
    tri = mesh if mesh is not None else triangulate(room, max_area=max(room.area / 2000.0, 0.5))
    scene = trimesh.Scene()
    floor = trimesh.Trimesh(np.column_stack([tri.points, np.zeros(tri.n_points)]),
                            tri.triangles, process=False)
    scene.add_geometry(_coloured(floor, "floor"), geom_name="floor")
    outline = shapely.Polygon(room.outline)
    band = outline.buffer(wall_thickness, join_style="mitre").difference(outline)
    exit_lines = [shapely.LineString(room.exit_polyline(k)) for k in range(len(room.exits))]
    doors = [ln.buffer(1.5 * wall_thickness, cap_style="flat")
             for ln in exit_lines + [shapely.LineString(o) for o in openings]]
    if doors:
        band = band.difference(shapely.union_all(doors))
    walls = _extrude(band, wall_height)
    if walls is not None:
        scene.add_geometry(_coloured(walls, "walls"), geom_name="walls")
    obstacles = [_extrude(o.shape, wall_height) for o in room.obstacles]
    obstacles = [o for o in obstacles if o is not None]
    if obstacles:
        scene.add_geometry(_coloured(trimesh.util.concatenate(obstacles), "obstacles"),
                           geom_name="obstacles")
    if exit_lines:
        strip = shapely.union_all([ln.buffer(0.15, cap_style="flat") for ln in exit_lines])
        strip = strip.intersection(room.walkable.buffer(1e-6))
        solid = _extrude(strip, 0.02)
        if solid is not None:
            scene.add_geometry(_coloured(solid, "exits"), geom_name="exits")
    if positions is not None and len(positions):
        pos = np.asarray(positions, float).reshape(-1, 2)
        body = trimesh.creation.cylinder(radius=body_radius, height=body_height, sections=12)
        body.apply_translation((0.0, 0.0, body_height / 2))
        n_v = len(body.vertices)
        verts = (body.vertices[None, :, :] + np.column_stack(
            [pos, np.zeros(len(pos))])[:, None, :]).reshape(-1, 3)
        faces = (body.faces[None, :, :] + (np.arange(len(pos)) * n_v)[:, None, None])
        crowd = trimesh.Trimesh(verts, faces.reshape(-1, 3), process=False)
        crowd.metadata["bodies"] = int(len(pos))
        scene.add_geometry(_coloured(crowd, "crowd"), geom_name="crowd")
    return scene


def building_scene(building, *, surface=None, wall_height: float = 2.5, **kw: Any):
    """A building as a ``trimesh.Scene``: every level as :func:`room_scene` draws a room,
    lifted to its height, with its walls open at the stair edges, and every stair as its
    sloped surface (``surface``: the building's
    :class:`~pedmesh.mesh.surface.SurfaceMesh`, default: a new one)."""
    import trimesh

    from ..mesh.building import triangulate_building

    if surface is None:
        surface = triangulate_building(building, max_area=max(building.area / 4000.0, 0.5))
    scene = trimesh.Scene()
    for lv in building.levels:
        openings = [getattr(s, end).edge for s in building.stairs for end in ("bottom", "top")
                    if getattr(s, end).level == lv.name]
        piece = surface.pieces[surface.piece_index(lv.name)]
        sub = room_scene(lv.room, mesh=piece.mesh, wall_height=wall_height,
                         openings=openings, **kw)
        lift = trimesh.transformations.translation_matrix((0.0, 0.0, lv.z))
        for name, geom in sub.geometry.items():
            scene.add_geometry(geom, geom_name=f"{lv.name}/{name}", transform=lift)
    for s in building.stairs:
        piece = surface.pieces[surface.piece_index(s.name)]
        stair = trimesh.Trimesh(surface.points[piece.vertices], piece.mesh.triangles,
                                process=False)
        scene.add_geometry(_coloured(stair, "stairs"), geom_name=f"{s.name}/stairs")
    return scene


def export_room_3d(room, path: str | Path, **kw: Any) -> Path:
    """Write :func:`room_scene` (or :func:`building_scene` for a building; keyword
    arguments passed on) to ``path``; the suffix picks the format (:data:`FORMATS`).
    Returns the path."""
    import trimesh

    p = Path(path)
    suffix = p.suffix.lower()
    if suffix not in FORMATS:
        raise PedmeshError(f"{path}: unsupported 3-D format '{suffix or '(none)'}' "
                           f"(use {', '.join(FORMATS)})")
    from ..geometry.site import is_building

    if is_building(room):
        if kw.get("positions") is not None:
            raise PedmeshError("a building's crowd cannot be drawn yet (--run takes a room)")
        kw.pop("positions", None)
        scene = building_scene(room, **kw)
    else:
        scene = room_scene(room, **kw)
    if suffix in Y_UP_SUFFIXES:
        scene.apply_transform(Z_UP_TO_Y_UP)
    p.parent.mkdir(parents=True, exist_ok=True)
    if suffix == ".glb":
        data = scene.export(file_type="glb")
    elif suffix == ".gltf":
        data = trimesh.exchange.gltf.export_gltf(scene, embed_buffers=True)["model.gltf"]
    else:
        merged = trimesh.util.concatenate(list(scene.dump()))
        data = merged.export(file_type=suffix[1:])
    from .files import write_whole

    try:  # (through a temporary file of its own: never a file of the user's)
        return write_whole(p, data if isinstance(data, bytes) else data.encode("utf-8"))
    except OSError as exc:
        raise PedmeshError(f"cannot write {p}: {exc.strerror or exc}") from None


def read_positions(run_dir: Path, t: float | None) -> tuple[float, np.ndarray]:
    """(frame time [s], positions (n, 2) [m]) of the pedestrians frame nearest ``t`` (the
    middle of the run if None) of a run folder."""
    import pyvista as pv

    from .run_folder import PEDESTRIANS_PVD
    from .vtk import read_pvd_index

    if t is not None and not (isinstance(t, (int, float)) and math.isfinite(t) and t >= 0):
        raise PedmeshError(f"the time must be a finite number of seconds >= 0, got {t!r}")
    pvd = Path(run_dir) / PEDESTRIANS_PVD
    if not pvd.exists():
        raise PedmeshError(f"{run_dir}: no {PEDESTRIANS_PVD} (a social force run folder?)")
    frames = read_pvd_index(pvd)
    if not frames:
        raise PedmeshError(f"{pvd}: no frames")
    when = frames[-1][0] / 2 if t is None else t
    ft, f = min(frames, key=lambda fr: abs(fr[0] - when))
    pts = np.asarray(pv.read(f).points, float).reshape(-1, 3)[:, :2]
    return ft, pts
