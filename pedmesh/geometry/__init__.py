"""Rooms (walls, obstacles, exits, start areas) and their file formats."""

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
    "EXIT_TOLERANCE",
    "Exit",
    "MeasurementArea",
    "MeasurementLine",
    "Obstacle",
    "Room",
    "StartArea",
]
