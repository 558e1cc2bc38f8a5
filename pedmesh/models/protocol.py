"""What the run driver needs of a model: the :class:`RunModel` protocol, and the optional
capability :class:`DenseFrames`.

Every model registered with :func:`pedmesh.models.register_model` builds an object that
implements :class:`RunModel` (the social force model's
:class:`~pedmesh.models.sfm.adapter.SFMRun`, the continuum models'
:class:`~pedmesh.models.continuum.adapter.MacroRun`); the driver checks it with
``isinstance`` when the model is built and calls nothing outside it. A model that also
implements :class:`DenseFrames` with a true ``dense_frames`` is stepped freely and asked for
each frame at its time (the continuum models interpolate between the step's two states);
the others have their steps land on the frame times.
"""

from __future__ import annotations

import math
from typing import Any, Protocol, runtime_checkable

import numpy as np

__all__ = ["RunModel", "DenseFrames"]


@runtime_checkable
class RunModel(Protocol):
    """A model behind ``pedmesh run``: state, stepping and output."""

    #: canonical model name
    name: str
    #: interval [s] between rows of evacuation.csv and outflow.csv
    sample_interval: float
    #: interval [s] between density (and pedestrian) frames
    output_interval: float
    #: things the user should know about this run, printed and kept in the summary
    warnings: list[str]

    @property
    def t(self) -> float:
        """Simulated time [s]."""

    @property
    def n_initial(self) -> float:
        """Pedestrians [ped] at t = 0."""

    @property
    def evacuated(self) -> float:
        """Pedestrians [ped] who have left so far."""

    @property
    def remaining(self) -> float:
        """Pedestrians [ped] still inside."""

    @property
    def done(self) -> bool:
        """Whether the room counts as empty."""

    def step(self, t_limit: float = math.inf) -> None:
        """Advance one time step, never past ``t_limit`` [s] (a model with a fixed step
        may ignore it when its steps land on the driver's output times)."""

    def exit_counts(self) -> np.ndarray:
        """Cumulative number of pedestrians [ped] out through each exit (mesh order)."""

    def record(self, writer: Any, final: bool = False) -> None:
        """After every step: the model's own records (e.g. trajectories, exits.csv);
        ``final``: the last call, at the end of the run."""

    def write_frame(self, writer: Any, frame: int) -> None:
        """Write density (and pedestrian) frame number ``frame`` at the current time."""

    def parameters(self) -> dict[str, Any]:
        """Every parameter the run uses, for the summary."""

    def summary(self) -> dict[str, Any]:
        """Counts and evacuation times for the final summary."""


@runtime_checkable
class DenseFrames(Protocol):
    """A model that can write its state at any time within its last step."""

    #: whether the driver should step freely and ask for each frame at its time
    dense_frames: bool

    def write_frame_at(self, writer: Any, frame: int, t: float) -> None:
        """Write frame ``frame`` at time ``t`` [s] within the last step."""
