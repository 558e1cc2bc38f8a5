"""``pedmesh export``: a 3-D model of a room (and a crowd) for Blender and web viewers."""

from __future__ import annotations

import argparse

HELP = "write a 3-D model of a room (walls, obstacles, exits, crowd) as glTF/OBJ/PLY/STL"
DESCRIPTION = """\
Write the room as a 3-D scene in metres, z up: the floor (the walkable area), the walls
(extruded, with openings at the exits), the obstacles (extruded), green strips at the exits
and, with --run, the crowd of a social force run as cylinders at the frame nearest --time.
The suffix of -o picks the format: .glb (binary glTF, colours kept: Blender's File >
Import > glTF 2.0, three.js, online glTF viewers), .gltf, .obj, .ply or .stl.

examples:
  pedmesh export geometries/pillar_hall.json -o hall.glb
  pedmesh export geometries/example2.json -o ex2.glb --run runs/ex2-sfm --time 40
"""


def add_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("geometry", metavar="GEOMETRY", help="room file (.json, .geojson, .dxf, .svg)")
    p.add_argument("-o", "--output", required=True, metavar="FILE",
                   help="output file (.glb, .gltf, .obj, .ply or .stl)")
    p.add_argument("--wall-height", type=float, default=2.5, metavar="H",
                   help="height of walls and obstacles in m, at most 1000 (default: 2.5)")
    p.add_argument("--run", metavar="RUN_DIR", default=None,
                   help="add the pedestrians of this social force run folder")
    p.add_argument("--time", type=float, default=None, metavar="T",
                   help="with --run: the frame nearest T s (default: the middle of the run)")


def run(args: argparse.Namespace) -> int:
    import math
    from pathlib import Path

    from ..errors import PedmeshError
    from ..io import load_room
    from ..io.export3d import FORMATS, MAX_SIZE_M, export_room_3d, read_positions

    if Path(args.output).suffix.lower() not in FORMATS:
        raise PedmeshError(f"{args.output}: unsupported 3-D format (use "
                           f"{', '.join(FORMATS)})")
    if args.time is not None and not args.run:
        raise PedmeshError("--time needs --run RUN_DIR (the run whose crowd to show)")
    if args.time is not None and not (math.isfinite(args.time) and args.time >= 0):
        raise PedmeshError(f"--time must be a finite number of seconds >= 0, got {args.time:g}")
    if not (math.isfinite(args.wall_height) and 0 < args.wall_height <= MAX_SIZE_M):
        raise PedmeshError(f"--wall-height must be a positive number of metres up to "
                           f"{MAX_SIZE_M:g}, got {args.wall_height:g}")
    room = load_room(args.geometry)
    positions, note = None, ""
    if args.run:
        from ..run.output import file_sha256
        from ..run.results import RunResult

        made_from = RunResult.load(args.run).settings.get("room_sha256")
        if made_from is not None and made_from != file_sha256(args.geometry):
            raise PedmeshError(f"{args.run}: that run was made from another room file than "
                               f"{args.geometry}")
        t, positions = read_positions(Path(args.run), args.time)
        note = f", {len(positions)} pedestrians at t = {t:g} s"
    out = export_room_3d(room, args.output, positions=positions, wall_height=args.wall_height)
    print(f"room '{room.name}'{note} written to {out}")
    return 0
