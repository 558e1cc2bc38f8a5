"""Geometric tolerances shared by the room model and the mesher (a module of their own, so
that the mesher needs nothing else from the room model)."""

from __future__ import annotations

__all__ = ["EXIT_TOLERANCE"]

#: Largest distance [m] between an exit (or a start/measurement element) and the boundary
#: (or walkable area) it must lie on. Exit vertices closer than this to the boundary are
#: projected onto it when the room is meshed.
EXIT_TOLERANCE = 1e-6
