"""pedmesh: pedestrian crowd simulation on triangulated rooms.

The social force model and continuum (finite-volume WENO) models on one triangle mesh, routed
by an unstructured fast-marching eikonal solver. All quantities are SI: metres, seconds,
pedestrians per square metre.
"""

from __future__ import annotations

from ._version import __version__

try:  # stale compiled kernels deleted before any is loaded (pedmesh._kernel_cache)
    from ._kernel_cache import check as _check_kernel_cache

    _check_kernel_cache()
    del _check_kernel_cache
except Exception:  # (never a reason for the import to fail: numba's own caches stand)
    pass

from .errors import (
    GeometryError,
    MeshError,
    ParameterError,
    PedmeshError,
    RoomFileError,
    SimulationError,
    UnsupportedFormatError,
)
from .geometry import Exit, MeasurementArea, MeasurementLine, Obstacle, Room, StartArea
from .io import PVDWriter, load_room, save_room, write_vtu
from .mesh import BoundaryKind, TriMesh, triangulate

# heavy parts (numba kernels) load on first use, so that ``import pedmesh`` stays fast
_LAZY = {
    "solve_eikonal": "pedmesh.eikonal",
    "EikonalSolver": "pedmesh.eikonal",
    "DirectionField": "pedmesh.eikonal",
    "ensemble": "pedmesh.ensembles",
    "simulate": "pedmesh.api",
    "build": "pedmesh.api",
}


def __getattr__(name: str):
    if name in _LAZY:
        import importlib

        value = getattr(importlib.import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'pedmesh' has no attribute {name!r}")


__all__ = [
    "__version__",
    "build",
    "simulate",
    "DirectionField",
    "EikonalSolver",
    "ensemble",
    "solve_eikonal",
    "BoundaryKind",
    "Exit",
    "GeometryError",
    "MeasurementArea",
    "MeasurementLine",
    "MeshError",
    "Obstacle",
    "PVDWriter",
    "ParameterError",
    "PedmeshError",
    "Room",
    "RoomFileError",
    "SimulationError",
    "StartArea",
    "TriMesh",
    "UnsupportedFormatError",
    "load_room",
    "save_room",
    "triangulate",
    "write_vtu",
]
