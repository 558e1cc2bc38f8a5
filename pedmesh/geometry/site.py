"""A site: what a room file describes, a room (one level, no stairs) or a building (levels
joined by stairs), and the few things that differ between the two, in one place.

Everything downstream (meshing, routes, models, runs, reports, ensembles) takes a site and
asks this module, never the site's type:

* :func:`pedmesh.mesh.site.mesh_site` meshes either, with one set of options and errors
  (a room with :func:`pedmesh.mesh.triangulate`, a building with
  :func:`pedmesh.mesh.triangulate_building`);
* :func:`is_building` says whether the site has levels and stairs (a building's mesh is a
  surface in 3-D; its frames are drawn as an atlas);
* :func:`site_levels` gives its levels as ``(name, z [m], room)``: a room is the one level
  ``(None, 0.0, room)``;
* :func:`check_site` refuses anything else in one line.
"""

from __future__ import annotations

from typing import Any, Union

from ..errors import ParameterError
from .building import Building
from .room import Room

__all__ = ["Site", "is_building", "check_site", "site_levels"]

#: a room or a building
Site = Union[Room, Building]

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
