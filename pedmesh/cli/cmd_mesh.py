"""``pedmesh mesh``: triangulate a room, print a summary, write the mesh as VTU."""

from __future__ import annotations

import argparse
from pathlib import Path

HELP = "triangulate a room and write the mesh (VTU) with boundary tags"
DESCRIPTION = """\
Triangulate the walkable area of a room (outline minus obstacles) and print a summary:
vertices, triangles, smallest angle, area and exits. With -o, write the mesh to a .vtu
file that ParaView opens; boundary edges are written as line cells with the cell fields
boundary_kind (1 wall, 2 obstacle, 3 exit) and boundary_owner (obstacle or exit number).

example:
  pedmesh mesh geometries/example3.json -o example3_mesh.vtu
  pedmesh mesh geometries/example3.json --max-area 0.25 --feature-area none -o uniform.vtu
"""


def _area_or_none(text: str):
    if text.strip().lower() in ("none", "uniform"):
        return None
    return float(text)


def add_mesh_args(p: argparse.ArgumentParser) -> None:
    """Mesh options shared by every command that meshes a room."""
    from ..mesh.triangulate import FEATURE_AREA, MAX_AREA, MAX_CELLS, MIN_ANGLE

    p.add_argument("--max-area", type=float, default=MAX_AREA, metavar="A",
                   help=f"largest triangle area in m^2, in the open (default: {MAX_AREA:g}, "
                        f"edges of about {(4 * MAX_AREA / 3 ** 0.5) ** 0.5:.1f} m)")
    p.add_argument("--feature-area", type=_area_or_none, default=FEATURE_AREA, metavar="F",
                   help="triangle area in m^2 at exits, corners and walls, growing to "
                        f"--max-area away from them (default: {FEATURE_AREA:g}, edges of "
                        f"about {(4 * FEATURE_AREA / 3 ** 0.5) ** 0.5:.2f} m); "
                        "'none': a uniform mesh of --max-area, as is any F >= A")
    p.add_argument("--min-angle", type=float, default=MIN_ANGLE, metavar="Q",
                   help=f"smallest triangle angle in degrees (default: {MIN_ANGLE:g}, at most "
                        "34)")
    p.add_argument("--exit-size", type=float, default=None, metavar="H",
                   help="grade the mesh to edges of about H m at the exits (default: uniform)")
    p.add_argument("--max-cells", type=float, default=None, metavar="N",
                   help="stop with an error, before meshing, if the mesh would have more than "
                        "N triangles (estimated as 1.6 x walkable area / max-area, or from "
                        f"the exit grading; default: {MAX_CELLS:.0f}; 'inf' for no limit)")


def add_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("geometry", metavar="GEOMETRY", help="room file (.json, .geojson or .dxf)")
    add_mesh_args(p)
    p.add_argument("-o", "--output", metavar="FILE",
                   help="write the mesh to this .vtu file")


def mesh_from_args(args: argparse.Namespace, *, buildings: bool = False, check=None):
    """Load the room named on the command line and triangulate it; a building (levels and
    stairs) only where the command handles one (``buildings``), else a one-line error.
    ``check``: called with the room before it is meshed (e.g. the crowd's size)."""
    from ..errors import PedmeshError
    from ..geometry.site import is_building
    from ..mesh.site import mesh_site
    from ..io import load_room

    room = load_room(args.geometry)
    if check is not None:
        check(room)
    if is_building(room) and not buildings:
        raise PedmeshError(f"{args.geometry}: '{room.name}' is a building (levels and "
                           f"stairs); `pedmesh {args.command}` takes a single-level room "
                           "for now (`pedmesh mesh` meshes a building)")
    return room, mesh_site(room, **mesh_options(args), max_cells=args.max_cells)


def mesh_options(args: argparse.Namespace) -> dict:
    """The mesh options given on the command line (as recorded in a run's settings)."""
    return {"max_area": args.max_area, "min_angle": args.min_angle,
            "feature_area": args.feature_area, "exit_size": args.exit_size}


def _building_summary(args: argparse.Namespace, building, mesh) -> int:
    """What `pedmesh mesh` prints and writes for a building's surface mesh."""
    print(f"building '{building.name}' ({args.geometry})")
    print(f"  walkable area   {building.area:.3f} m^2 on the surface (mesh: {mesh.area:.3f} m^2)")
    print(f"  vertices        {mesh.n_points}")
    print(f"  triangles       {mesh.n_triangles}")
    for p in mesh.pieces:
        if p.kind == "level":
            lv = building.level(p.name)
            print(f"  level {p.name:<10} z = {lv.z:g} m, {p.mesh.n_triangles} triangles, "
                  f"{len(lv.room.initial_positions())} pedestrians")
    for s in building.stairs:
        print(f"  stair {s.name:<10} {s.bottom.level} -> {s.top.level}, rise "
              f"{building.rise(s):g} m, slope {building.slope(s):.1f} deg")
    print(f"  exits           {', '.join(mesh.exit_names) or 'none'}")
    if args.output:
        _write(args.output, mesh, " (the building in 3-D: levels at their heights, stairs "
               "sloped)", cell_data=mesh.cell_data())
    return 0


def run(args: argparse.Namespace) -> int:
    from ..geometry.site import is_building

    room, mesh = mesh_from_args(args, buildings=True)
    if is_building(room):
        return _building_summary(args, room, mesh)
    s = mesh.summary()
    exits = ", ".join(f"{n} {L:.3f} m" for n, L in s["exits"].items()) or "none"
    n_ped = len(room.initial_positions())
    print(f"room '{room.name}' ({args.geometry})")
    print(f"  walkable area   {room.area:.3f} m^2 (mesh: {s['area_m2']:.3f} m^2)")
    print(f"  vertices        {s['vertices']}")
    print(f"  triangles       {s['triangles']}")
    print(f"  angles          smallest {s['min_angle_deg']:.2f} deg, "
          f"largest {s['max_angle_deg']:.2f} deg")
    print(f"  cell size       {s['h_m']:.3f} m (square root of the mean triangle area)")
    print(f"  exits           {exits}")
    print(f"  obstacles       {len(room.obstacles)}")
    print(f"  pedestrians     {n_ped} in {len(room.start_areas)} start area(s)")
    if args.output:
        _write(args.output, mesh, "", cell_data={"area": mesh.areas}, boundary=True)
    return 0


def _write(output: str, mesh, note: str, **kw) -> None:
    """Write ``mesh`` to the .vtu file ``output`` (``kw``: fields, see
    :func:`pedmesh.io.write_vtu`) and say so."""
    from ..errors import PedmeshError
    from ..io import write_vtu

    out = Path(output)
    if out.suffix.lower() != ".vtu":
        raise PedmeshError(f"{out}: the mesh is written as VTU; use a .vtu suffix")
    if out.parent and not out.parent.exists():
        out.parent.mkdir(parents=True)
    write_vtu(out, mesh, **kw)
    print(f"wrote {out}{note}")
