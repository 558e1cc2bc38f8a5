"""The pedmesh exception hierarchy.

Every error pedmesh raises on bad input is a :class:`PedmeshError`, so a caller (and the
CLI) can catch one class. The message always names the offending element and the problem,
e.g. ``obstacle 'pillar-2' overlaps obstacle 'pillar-3'``.

::

    PedmeshError
    +-- GeometryError        invalid room: outline, obstacles, exits, start areas, ...
    +-- RoomFileError        unreadable or malformed geometry file, unknown key or role
    |   +-- UnsupportedFormatError   no reader/writer for the file suffix
    +-- MeshError            triangulation failed or an inconsistent mesh was given
    +-- ParameterError       bad model/solver parameter (non-positive, unknown name, ...)
    +-- SimulationError      a run could not continue (blow-up, NaN, bad initial state)
"""

from __future__ import annotations

__all__ = [
    "PedmeshError",
    "GeometryError",
    "RoomFileError",
    "UnsupportedFormatError",
    "MeshError",
    "ParameterError",
    "SimulationError",
]


class PedmeshError(Exception):
    """Base class of every error raised by pedmesh on bad input or failed runs."""


class GeometryError(PedmeshError, ValueError):
    """A room, obstacle, exit, start area or measurement element is invalid."""


class RoomFileError(PedmeshError):
    """A geometry file cannot be read: missing, empty, malformed, unknown key or role."""


class UnsupportedFormatError(RoomFileError):
    """No geometry reader or writer is registered for a file suffix."""


class MeshError(PedmeshError):
    """Triangulation failed or mesh arrays are inconsistent."""


class ParameterError(PedmeshError, ValueError):
    """A model or solver parameter is unknown, non-finite or out of range."""


class SimulationError(PedmeshError):
    """A simulation could not continue (blow-up, NaN state, invalid initial state)."""
