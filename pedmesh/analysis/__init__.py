"""Analysis of runs: kernel fields, outflow, evacuation curves, density-flow diagrams,
distances between runs. Pure, keyword-only functions on arrays."""

from .evacuation import (
    curve_distance,
    density_l1,
    evacuation_curve,
    evacuation_times,
    evacuation_times_from_curve,
)
from .fields import kernel_density, kernel_velocity, vertex_to_cell
from .fundamental import PAPER_BINS, DensityFlowDiagram, density_flow_diagram, reference_flow
from .outflow import continuum_outflow, crossing_rate, exit_gauss_points, particle_outflow

__all__ = [
    "PAPER_BINS",
    "DensityFlowDiagram",
    "continuum_outflow",
    "crossing_rate",
    "curve_distance",
    "density_flow_diagram",
    "density_l1",
    "evacuation_curve",
    "evacuation_times",
    "evacuation_times_from_curve",
    "exit_gauss_points",
    "kernel_density",
    "kernel_velocity",
    "particle_outflow",
    "reference_flow",
    "vertex_to_cell",
]
