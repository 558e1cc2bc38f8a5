"""Meshing a site (:mod:`pedmesh.geometry.site`: a room or a building) with one function,
one set of options and one set of errors, whatever it is."""

from __future__ import annotations

from typing import Any, Mapping

from ..errors import MeshError, ParameterError
from ..geometry.site import Site, is_building, site_levels

__all__ = ["mesh_site", "MESH_OPTIONS", "check_mesh_options", "check_mesh_size"]

#: the options :func:`mesh_site` takes (those of :func:`pedmesh.mesh.triangulate`); a
#: building takes them but ``exit_size`` and ``size``
MESH_OPTIONS = ("max_area", "min_angle", "feature_area", "exit_size", "size_growth", "size",
                "max_refinements", "max_cells")
_ROOM_ONLY = ("exit_size", "size", "size_growth", "max_refinements")


def mesh_site(site: Site, **options: Any):
    """The mesh of ``site``: a room's :class:`~pedmesh.mesh.TriMesh`
    (:func:`~pedmesh.mesh.triangulate`), a building's
    :class:`~pedmesh.mesh.surface.SurfaceMesh` (:func:`~pedmesh.mesh.triangulate_building`),
    with the ``options`` of :data:`MESH_OPTIONS` (None values are the defaults'). An
    unknown option, or a room-only one given for a building, is a one-line error."""
    from .building import triangulate_building
    from .triangulate import triangulate

    check_mesh_options(options, site)
    opts = {k: v for k, v in options.items() if v is not None or k in ("feature_area",
                                                                      "max_cells")}
    if is_building(site):
        return triangulate_building(site, **{k: v for k, v in opts.items()
                                             if k not in _ROOM_ONLY})
    return triangulate(site, **opts)


def check_mesh_options(options: Any, site: Site | None = None) -> None:
    """A one-line error for ``options`` that :func:`mesh_site` cannot take: not a mapping,
    an unknown name, a value of the wrong kind (its range is the mesher's to check), or,
    for a building ``site``, a room-only option given."""
    import numbers

    if not isinstance(options, Mapping):
        raise ParameterError("mesh_options must be a mapping of option names to values, "
                             f"e.g. {{'max_area': 0.5}}; got {type(options).__name__}")
    bad = [k for k in options if k not in MESH_OPTIONS]
    if bad:
        raise ParameterError(f"mesh_options: unknown option {bad[0]!r} (options: "
                             f"{', '.join(MESH_OPTIONS)})")
    for key, value in options.items():
        if value is None:
            continue
        if key == "size":
            if not callable(value):
                raise ParameterError(f"mesh option 'size' must be a function of the points "
                                     f"(an (n, 2) array [m]) giving edge lengths [m], got "
                                     f"{type(value).__name__}")
        elif isinstance(value, bool) or not isinstance(value, numbers.Real):
            raise ParameterError(f"mesh option '{key}' must be a number, got "
                                 f"{type(value).__name__} {value!r:.40}")
    if site is not None and is_building(site):
        room_only = [k for k in _ROOM_ONLY if options.get(k) is not None]
        if room_only:
            flag = room_only[0].replace("_", "-")
            raise MeshError(f"{room_only[0]} (--{flag}) is not available for buildings")


def check_mesh_size(site: Site, mesh_options: dict, max_cells: float | None) -> None:
    """The mesher's size check of ``site`` on its estimate (each level of a building as a
    room: its stairs are small), before any mesh is made: a one-line
    :class:`~pedmesh.errors.MeshError` if it would have more than ``max_cells``
    triangles."""
    import math

    from .triangulate import MAX_CELLS, check_max_cells, estimate_cells, size_fields

    check_max_cells(max_cells)
    check_mesh_options(mesh_options, site)
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
