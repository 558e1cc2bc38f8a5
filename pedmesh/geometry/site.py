"""A site: what a room file describes, a room (one level, no stairs) or a building (levels
joined by stairs), and the few things that differ between the two, in one place.

Everything downstream (meshing, routes, models, runs, reports, ensembles) takes a site and
asks this module, never the site's type:

* :func:`mesh_site` meshes either, with one set of options and errors (a room with
  :func:`pedmesh.mesh.triangulate`, a building with
  :func:`pedmesh.mesh.triangulate_building`);
* :func:`is_building` says whether the site has levels and stairs (a building's mesh is a
  surface in 3-D; its frames are drawn as an atlas);
* :func:`site_levels` gives its levels as ``(name, z [m], room)``: a room is the one level
  ``(None, 0.0, room)``;
* :func:`check_site` refuses anything else in one line.
"""

from __future__ import annotations

from typing import Any, Union

from ..errors import MeshError, ParameterError
from .building import Building
from .room import Room

__all__ = ["Site", "is_building", "check_site", "site_levels", "mesh_site", "MESH_OPTIONS",
           "check_mesh_size"]

#: a room or a building
Site = Union[Room, Building]

#: the options :func:`mesh_site` takes (those of :func:`pedmesh.mesh.triangulate`); a
#: building takes them but ``exit_size`` and ``size``
MESH_OPTIONS = ("max_area", "min_angle", "feature_area", "exit_size", "size_growth", "size",
                "max_refinements", "max_cells")
_ROOM_ONLY = ("exit_size", "size", "size_growth", "max_refinements")


def is_building(site: Any) -> bool:
    """Whether ``site`` is a building (levels joined by stairs) rather than a room."""
    return isinstance(site, Building)


def check_site(site: Any, what: str = "room") -> Site:
    """``site`` if it is a room or a building, else a one-line
    :class:`~pedmesh.errors.ParameterError` naming ``what`` it should have been."""
    if not isinstance(site, (Room, Building)):
        raise ParameterError(f"{what} must be a Room, a Building or the path of a room file, "
                             f"got {type(site).__name__}")
    return site


def site_levels(site: Site) -> list[tuple[str | None, float, Room]]:
    """The levels of ``site`` as ``(name, z [m], room)``; a room is one level,
    ``(None, 0.0, room)``."""
    if is_building(site):
        return [(lv.name, lv.z, lv.room) for lv in site.levels]
    return [(None, 0.0, site)]


def mesh_site(site: Site, **options: Any):
    """The mesh of ``site``: a room's :class:`~pedmesh.mesh.TriMesh`
    (:func:`~pedmesh.mesh.triangulate`), a building's
    :class:`~pedmesh.mesh.surface.SurfaceMesh` (:func:`~pedmesh.mesh.triangulate_building`),
    with the ``options`` of :data:`MESH_OPTIONS` (None values are the defaults'). An
    unknown option, or a room-only one given for a building, is a one-line error."""
    from ..mesh import triangulate, triangulate_building

    bad = [k for k in options if k not in MESH_OPTIONS]
    if bad:
        raise ParameterError(f"unknown mesh option '{bad[0]}' (options: "
                             f"{', '.join(MESH_OPTIONS)})")
    for k, v in options.items():
        _check_option(k, v)
    opts = {k: v for k, v in options.items() if v is not None or k in ("feature_area",
                                                                      "max_cells")}
    if is_building(site):
        room_only = [k for k in _ROOM_ONLY if opts.get(k) is not None]
        if room_only:
            flag = room_only[0].replace("_", "-")
            raise MeshError(f"{room_only[0]} (--{flag}) is not available for buildings")
        return triangulate_building(site, **{k: v for k, v in opts.items()
                                             if k not in _ROOM_ONLY})
    return triangulate(site, **opts)


def _check_option(key: str, value: Any) -> None:
    """A one-line error for a mesh option's value of the wrong kind (its range is the
    mesher's to check)."""
    import numbers

    if value is None:
        return
    if key == "size":
        if not callable(value):
            raise ParameterError(f"mesh option 'size' must be a function of the points "
                                 f"(an (n, 2) array [m]) giving edge lengths [m], got "
                                 f"{type(value).__name__}")
        return
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ParameterError(f"mesh option '{key}' must be a number, got "
                             f"{type(value).__name__} {value!r:.40}")


def check_mesh_size(site: Site, mesh_options: dict, max_cells: float | None) -> None:
    """The mesher's size check of ``site`` on its estimate (each level of a building as a
    room: its stairs are small), before any mesh is made: a one-line
    :class:`~pedmesh.errors.MeshError` if it would have more than ``max_cells``
    triangles."""
    import math

    from ..mesh.triangulate import MAX_CELLS, check_max_cells, estimate_cells, size_fields

    check_max_cells(max_cells)
    if is_building(site) and mesh_options.get("exit_size") is not None:
        raise MeshError("exit_size (--exit-size) is not available for buildings")
    limit = MAX_CELLS if max_cells is None else max_cells
    if not math.isfinite(limit) or not (mesh_options["max_area"] > 0):
        return  # no limit, or a bad max_area that the mesher reports itself
    for _, _, room in site_levels(site):
        exit_size = mesh_options.get("exit_size") if room.exits else None
        fields = size_fields(room, feature_area=mesh_options.get("feature_area"),
                             exit_size=exit_size, max_area=mesh_options["max_area"])
        n = estimate_cells(room, mesh_options["max_area"], fields)
        if n > limit:
            raise MeshError(f"the members' mesh would have about {n:,.0f} triangles, more "
                            f"than the limit of {limit:,.0f}; use a larger max_area, or "
                            "raise the limit (--max-cells N)")
