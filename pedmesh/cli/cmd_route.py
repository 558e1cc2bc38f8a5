"""``pedmesh route``: solve the route potential of a room and write it with its directions."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from .cmd_mesh import add_mesh_args, mesh_from_args

HELP = "solve the route potential (eikonal, unit cost) and write phi and the walking direction"
DESCRIPTION = """\
Solve |grad phi| = 1 with phi = 0 on the exits (phi is the walking distance to the nearest
exit, in m) by fast marching on the room's mesh (a building's surface: stairs measured on
their slope), and write phi and the desired walking
direction e = -grad(phi)/|grad(phi)| to a .vtu file. In ParaView, colour by phi and apply
the Glyph filter to the point vector 'direction' to see the routes.

example:
  pedmesh route geometries/example3.json -o example3_route.vtu
"""


def add_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("geometry", metavar="GEOMETRY", help="room file (.json, .geojson or .dxf)")
    add_mesh_args(p)
    p.add_argument("--exits", metavar="NAMES", default=None,
                   help="comma-separated target exits (default: all)")
    p.add_argument("-o", "--output", metavar="FILE", default="route.vtu",
                   help="output .vtu file (default: route.vtu)")


def _building_route(building, mesh, exits, out: Path) -> int:
    """The route of a building: distance on the surface (stairs on their slope) and the
    walking direction per triangle, in 3-D."""
    import numpy as np

    from ..eikonal.surface import SurfaceEikonalSolver, surface_gradient
    from ..io import write_vtu

    t0 = time.perf_counter()
    phi = SurfaceEikonalSolver(mesh, exits=exits).solve(1.0)
    t1 = time.perf_counter()
    g = surface_gradient(mesh, np.where(np.isfinite(phi), phi, 0.0))
    norm = np.linalg.norm(g, axis=1)
    e = -g / np.where(norm > 0, norm, 1.0)[:, None]
    reach = np.isfinite(phi)
    print(f"building '{building.name}': {mesh.n_points} vertices, {mesh.n_triangles} "
          f"triangles, {len(building.levels)} levels, {len(building.stairs)} stairs")
    print(f"  set-up and solve {1e3 * (t1 - t0):.1f} ms")
    print(f"  distance to exit on the surface: max {phi[reach].max():.2f} m, mean "
          f"{phi[reach].mean():.2f} m"
          + ("" if reach.all() else f"; {np.sum(~reach)} vertices cannot reach an exit"))
    if out.parent and not out.parent.exists():
        out.parent.mkdir(parents=True)
    write_vtu(out, mesh, point_data={"phi": phi},
              cell_data={"direction_cell": e, **mesh.cell_data()})
    print(f"wrote {out}")
    return 0


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from ..eikonal import DirectionField, EikonalSolver
    from ..errors import PedmeshError
    from ..io import write_vtu

    out = Path(args.output)
    if out.suffix.lower() != ".vtu":
        raise PedmeshError(f"{out}: the route field is written as VTU; use a .vtu suffix")
    room, mesh = mesh_from_args(args, buildings=True)
    exits = None if args.exits is None else [e.strip() for e in args.exits.split(",") if e.strip()]
    from ..mesh import SurfaceMesh

    if isinstance(mesh, SurfaceMesh):
        return _building_route(room, mesh, exits, out)
    t0 = time.perf_counter()
    solver = EikonalSolver(mesh, exits=exits)
    t1 = time.perf_counter()
    phi = solver.solve(1.0)
    t2 = time.perf_counter()
    field = DirectionField(mesh, phi)
    reach = np.isfinite(phi)
    print(f"room '{room.name}': {mesh.n_points} vertices, {mesh.n_triangles} triangles")
    print(f"  set-up {1e3 * (t1 - t0):.1f} ms, solve {1e3 * (t2 - t1):.1f} ms")
    print(f"  distance to exit: max {phi[reach].max():.2f} m, mean {phi[reach].mean():.2f} m"
          + ("" if reach.all() else f"; {np.sum(~reach)} vertices cannot reach an exit"))
    if out.parent and not out.parent.exists():
        out.parent.mkdir(parents=True)
    write_vtu(out, mesh, point_data={"phi": phi, "direction": field.vertex_directions},
              cell_data={"direction_cell": field.triangle_directions})
    print(f"wrote {out}")
    return 0
