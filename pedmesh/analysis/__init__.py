"""Analysis of runs: kernel fields, outflow, evacuation curves, density-flow diagrams,
distances between runs, crowd-safety measures (:mod:`pedmesh.analysis.safety`). Pure,
keyword-only functions on arrays."""

from .evacuation import (
    curve_distance,
    density_l1,
    evacuation_curve,
    evacuation_times,
    evacuation_times_from_curve,
)
from .fields import kernel_density, kernel_velocity, vertex_to_cell
from .levels import level_trajectories
from .fundamental import PAPER_BINS, DensityFlowDiagram, density_flow_diagram, reference_flow
from .outflow import continuum_outflow, crossing_rate, exit_gauss_points, particle_outflow
from .safety import (
    FRUIN_QUEUING,
    FRUIN_WALKWAY,
    area_time_above,
    clear_time,
    crowd_pressure,
    exit_usage_from_crossings,
    exit_usage_from_flow,
    level_of_service,
    local_density,
    peak_crowd_pressure,
    peak_density,
    time_above,
    worst_level_of_service,
)

__all__ = [
    "FRUIN_QUEUING",
    "FRUIN_WALKWAY",
    "PAPER_BINS",
    "DensityFlowDiagram",
    "area_time_above",
    "clear_time",
    "continuum_outflow",
    "crossing_rate",
    "crowd_pressure",
    "curve_distance",
    "density_flow_diagram",
    "density_l1",
    "evacuation_curve",
    "evacuation_times",
    "evacuation_times_from_curve",
    "exit_gauss_points",
    "exit_usage_from_crossings",
    "exit_usage_from_flow",
    "kernel_density",
    "kernel_velocity",
    "level_trajectories",
    "level_of_service",
    "local_density",
    "particle_outflow",
    "peak_crowd_pressure",
    "peak_density",
    "reference_flow",
    "time_above",
    "vertex_to_cell",
    "worst_level_of_service",
]
