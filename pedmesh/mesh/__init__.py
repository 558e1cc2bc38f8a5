"""Triangle meshes of rooms: :class:`TriMesh`, triangulation and point location."""

from .triangle_mesh import BoundaryKind, TriMesh
from .triangulate import exit_size_field, triangulate

__all__ = ["BoundaryKind", "TriMesh", "exit_size_field", "triangulate"]
