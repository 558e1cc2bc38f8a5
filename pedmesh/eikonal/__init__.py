"""Route choice: unstructured fast marching for the eikonal equation and the desired
direction field."""

from .direction import DirectionField, p1_gradients
from .exact import geodesic_distance
from .fmm import EikonalSolver, solve_eikonal

__all__ = ["DirectionField", "EikonalSolver", "geodesic_distance", "p1_gradients",
           "solve_eikonal"]
