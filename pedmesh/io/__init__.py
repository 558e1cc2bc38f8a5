"""Input and output: geometry files and VTK (ParaView) output."""

from .rooms import load_room, save_room
from .vtk import PVDWriter, mesh_to_meshio, read_pvd_index, write_vtp, write_vtu

__all__ = [
    "PVDWriter",
    "load_room",
    "mesh_to_meshio",
    "read_pvd_index",
    "save_room",
    "write_vtp",
    "write_vtu",
]
