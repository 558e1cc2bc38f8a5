"""Loading and saving rooms: the one user-facing entry point for geometry files."""

from __future__ import annotations

from pathlib import Path

from ..errors import GeometryError
from ..geometry import formats as _formats
from ..geometry.room import Room

__all__ = ["load_room", "save_room"]


def load_room(path: str | Path) -> Room:
    """Read a room from a geometry file, choosing the reader by suffix.

    ``.json`` is the native format, ``.geojson`` GeoJSON and ``.dxf`` a DXF drawing with
    role layers; see docs/rooms.md for each.

    Raises
    ------
    RoomFileError
        The file is missing, empty, malformed or has unknown keys/roles (including
        :class:`~pedmesh.errors.UnsupportedFormatError` for an unknown suffix).
    GeometryError
        The file is well formed but describes an invalid room.
    """
    fmt = _formats.format_for(path)
    try:
        return fmt.reader(path)
    except GeometryError as exc:
        msg = str(exc)
        if msg.startswith(str(path)):
            raise
        raise type(exc)(f"{path}: {msg}") from None


def save_room(room: Room, path: str | Path) -> Path:
    """Write ``room`` to ``path`` in the format given by the suffix; returns the path."""
    fmt = _formats.format_for(path)
    if fmt.writer is None:
        raise _formats.UnsupportedFormatError(f"{path}: format '{fmt.name}' cannot be written")
    fmt.writer(room, path)
    return Path(path)
