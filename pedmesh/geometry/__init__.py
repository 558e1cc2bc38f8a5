"""Rooms (walls, obstacles, exits, start areas), buildings (levels joined by stairs) and
their file formats."""

from .building import Building, Level, Stair, StairEnd
from .room import (
    EXIT_TOLERANCE,
    Exit,
    MeasurementArea,
    MeasurementLine,
    Obstacle,
    Room,
    StartArea,
)

__all__ = [
    "Building",
    "Level",
    "Stair",
    "StairEnd",
    "EXIT_TOLERANCE",
    "Exit",
    "MeasurementArea",
    "MeasurementLine",
    "Obstacle",
    "Room",
    "StartArea",
]
