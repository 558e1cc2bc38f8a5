"""Triangle meshes of rooms (:class:`TriMesh`, triangulation, point location) and of
buildings (:class:`~pedmesh.mesh.surface.SurfaceMesh`, :func:`triangulate_building`)."""

from .building import triangulate_building
from .surface import SurfaceMesh
from .triangle_mesh import BoundaryKind, TriMesh
from .triangulate import exit_size_field, triangulate

__all__ = ["BoundaryKind", "SurfaceMesh", "TriMesh", "exit_size_field", "triangulate",
           "triangulate_building"]
