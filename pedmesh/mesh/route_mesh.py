"""The mesh the social force model's routes are solved on, whatever mesh the run has.

A route bends at door jambs, pillars and the ends of exits, it reads the crowd on the scale
``L`` of its density kernel (the parameter ``route_kernel``), and with ``route_clearance``
it keeps off the walls on the scale of that clearance. Fast marching is first order: its
directions near a reflex corner are only as good as the triangles there, and a cost that
varies on the scale ``L`` needs edges well below ``L``. The run's mesh is chosen for
the output (or for the continuum models) and may be far coarser or finer than that, so a
social force run with ``route_resolution`` set walks on a mesh of its own: edges of
``route_resolution`` [m] at the exits and at the reflex corners of the walkable area, growing
by :data:`ROUTE_GROWTH` metres per metre away from them (and, with a clearance, from a third
of it at the walls by 0.4 m per metre), up to :data:`OPEN_EDGE_PER_KERNEL` times ``L`` in
the open. The answer is then the same on any mesh the user gives
(docs/validation/route_convergence.md measures how it converges with ``route_resolution``).

Around a reflex corner the route turns through the whole angle of the corner within a
fraction of a metre, and in a door a person passes the jambs inside the clearance's bump:
there the first-order route needs far finer edges than anywhere else. So within
:data:`CORNER_ZONE` of a reflex corner the edges are :data:`CORNER_EDGE_FRACTION` of
``route_resolution`` at the corner, growing by :data:`CORNER_GROWTH` only (issue 44: at a
0.8 m door the corner zone moves T90 by +8 %, after which dividing every edge by 2 or 4 moves
it by about 1 %, where before it moved it by 5 %).

A building's route mesh is :func:`~pedmesh.mesh.building.triangulate_building` with the same
grading on every level and stair (whose stair edges count as exits).
"""

from __future__ import annotations

import dataclasses
import math
from collections import OrderedDict

import numpy as np
import shapely

from ..errors import MeshError
from .triangulate import (MAX_CELLS, MIN_ANGLE, WALL_GROWTH, _boundary_segments,
                          _edge_to_area, _NearestDistances, _point_segments,
                          _polyline_segments, estimate_cells, ring_turns, triangulate)
from .triangle_mesh import room_fingerprint

__all__ = ["route_mesh", "route_size_field", "reflex_corners", "OPEN_EDGE_PER_KERNEL",
           "ROUTE_GROWTH", "CORNER_EDGE_FRACTION", "CORNER_GROWTH", "CORNER_ZONE"]

#: the route mesh's edge length in the open, in units of the route kernel's width: a third
#: of L puts about four edges across the kernel's half-width
OPEN_EDGE_PER_KERNEL = 1.0 / 3.0
#: [m per m] growth of the route mesh's edges away from exits and reflex corners
ROUTE_GROWTH = 0.2
#: the route mesh's edge at a reflex corner, as a fraction of ``route_resolution``
CORNER_EDGE_FRACTION = 1.0 / 8.0
#: [m per m] growth of the route mesh's edges within :data:`CORNER_ZONE` of a reflex corner
CORNER_GROWTH = 0.1
#: [m] the distance from a reflex corner within which its edges grow by CORNER_GROWTH only
#: (beyond it by ROUTE_GROWTH): the whole of a door's jambs and about half a metre before
#: and behind them, where issue 44's probes found the route's error to lie
CORNER_ZONE = 0.5
#: [degrees] a boundary vertex where the walkable area turns inwards by more than this is a
#: reflex corner (a door jamb, a pillar's corner, the mouth of a corridor)
REFLEX_TURN = 15.0
#: route meshes kept for reuse (an ensemble or a fit builds the same one many times)
_CACHE_SIZE = 8
_cache: "OrderedDict[tuple, object]" = OrderedDict()


def reflex_corners(room, min_turn: float = REFLEX_TURN) -> np.ndarray:
    """(c, 2) [m] the vertices of the walkable area's boundary (outline and obstacles) where
    the boundary turns into the walkable area by more than ``min_turn`` degrees: the
    corners around which routes bend."""
    poly = shapely.geometry.polygon.orient(room.walkable, 1.0)  # outline ccw, holes cw
    out = []
    for ring in [poly.exterior, *poly.interiors]:
        c, turn = ring_turns(ring)
        # the walkable area lies to the left of every ring: a right turn is a reflex corner
        out.append(c[turn < -min_turn])
    return np.concatenate(out) if out else np.zeros((0, 2))


def route_size_field(room, resolution: float, open_edge: float,
                     growth: float = ROUTE_GROWTH, *, wall_edge: float | None = None,
                     refine: float = 1.0):
    """The route mesh's size field: (p, 2) points [m] -> largest triangle area [m^2], of an
    equilateral triangle with edge ``resolution + growth d`` [m] (``d`` the distance to the
    nearest exit), at most ``open_edge`` [m]; near a reflex corner at most
    ``CORNER_EDGE_FRACTION resolution + CORNER_GROWTH d_c`` (``d_c`` the distance to the
    corner, within :data:`CORNER_ZONE`; beyond the zone growing on by ``growth``); with
    ``wall_edge`` [m] also at most ``wall_edge + WALL_GROWTH d_w`` (``d_w`` the distance to
    the nearest wall or obstacle: a route that keeps a clearance from walls varies there);
    every edge divided by ``refine``."""
    corners = reflex_corners(room)
    # (the corners' term lies below resolution + growth d_c, as CORNER_EDGE_FRACTION < 1
    # and growth >= CORNER_GROWTH: the first term need only measure the exits' distance)
    h_corner = CORNER_EDGE_FRACTION * resolution
    # (remembered by the points' coordinates: each refinement pass asks again for most
    # centroids of the pass before; the same numbers, so the same mesh)
    sets = [_polyline_segments([room.exit_polyline(k) for k in range(len(room.exits))]),
            _point_segments(corners)]
    if wall_edge is not None:
        sets.append(_boundary_segments(room, 2.0 * wall_edge / refine))
    distances = _NearestDistances(sets)

    def size(xy: np.ndarray) -> np.ndarray:
        xy = np.asarray(xy, float).reshape(-1, 2)
        d = distances(xy)
        h = np.minimum(resolution + growth * d[0], open_edge)
        if len(corners):
            h = np.minimum(h, h_corner + CORNER_GROWTH * np.minimum(d[1], CORNER_ZONE)
                           + growth * np.maximum(d[1] - CORNER_ZONE, 0.0))
        if wall_edge is not None:
            h = np.minimum(h, wall_edge + WALL_GROWTH * d[2])
        return _edge_to_area(h / refine)

    return size


def open_edge_of(kernel: float) -> float:
    """The route mesh's edge [m] in the open for a route kernel of width ``kernel`` [m]."""
    return OPEN_EDGE_PER_KERNEL * float(kernel)


def route_mesh(site, *, resolution: float, kernel: float, clearance: float = 0.0,
               refine: float = 1.0, max_cells: float | None = None):
    """The mesh a social force run on ``site`` (a :class:`~pedmesh.geometry.Room` or a
    :class:`~pedmesh.geometry.Building`) walks on: edges of ``resolution`` [m] at the exits
    and reflex corners, ``kernel`` / 3 [m] in the open, and with a ``clearance`` [m] (the
    route keeps off walls) ``clearance`` / 3 along the walls (see the module docstring).
    ``refine`` (the parameter ``route_refine``) divides every one of these edges: a
    convergence check of the route's discretisation as a whole. The last few meshes are
    kept and reused. A one-line :class:`~pedmesh.errors.MeshError` names the parameters
    when the mesh would be too large."""
    for name, v, unit in (("route_resolution", resolution, " of metres"),
                          ("route_kernel", kernel, " of metres"), ("route_refine", refine, "")):
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise MeshError(f"{name} must be a positive number{unit}, got {v!r}")
    h_open = max(open_edge_of(kernel), float(resolution))
    h_wall = max(OPEN_EDGE_PER_KERNEL * float(clearance), float(resolution)) \
        if clearance and clearance > 0 else None
    refine = float(refine)
    from ..geometry.site import is_building

    building = is_building(site)
    if building:
        from .building import building_fingerprint, triangulate_building

        fingerprint = building_fingerprint(site)
    else:
        fingerprint = room_fingerprint(site)
    key = (building, fingerprint, float(resolution), float(h_open), h_wall, refine, max_cells)
    mesh = _cache.get(key)
    if mesh is None and building:
        mesh = triangulate_building(
            site, max_area=float(_edge_to_area(h_open / refine)), feature_area=None,
            max_cells=max_cells,
            size_of=lambda room: route_size_field(room, float(resolution), h_open,
                                                  wall_edge=h_wall, refine=refine))
    elif mesh is None:
        size = route_size_field(site, float(resolution), h_open, wall_edge=h_wall,
                                refine=refine)
        max_area = float(_edge_to_area(h_open / refine))
        limit = MAX_CELLS if max_cells is None else float(max_cells)
        n = estimate_cells(site, max_area, [size])
        if n > limit:  # (named by the route's parameters, not the run's mesh options)
            raise MeshError(
                f"room '{site.name}': the social force model's route mesh would have about "
                f"{n:,.0f} triangles (route_resolution {resolution:g} m, "
                f"route_kernel {kernel:g} m, route_refine {refine:g}), more than the limit "
                f"of {limit:,.0f}; use a larger route_resolution or route_kernel or a smaller "
                "route_refine (--param NAME=VALUE)")
        mesh = triangulate(site, max_area=max_area, min_angle=MIN_ANGLE, feature_area=None,
                           size=size, max_cells=math.inf)
    else:
        _cache.move_to_end(key)
    if key not in _cache:
        _cache[key] = mesh
        if len(_cache) > _CACHE_SIZE:
            _cache.popitem(last=False)
    if building:  # the same levels and stairs: this building's crowd
        return mesh if mesh.building is site else dataclasses.replace(mesh, building=site)
    if mesh.room is not site:  # the same walls and exits: this room's crowd
        mesh = dataclasses.replace(mesh, room=site)
    return mesh
