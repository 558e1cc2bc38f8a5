"""A run's output kept in memory (the Python API without an output directory): the writer
protocol of :mod:`pedmesh.io.run_folder` (the methods of :class:`~pedmesh.run.output.RunWriter`),
collecting arrays instead of files; its result is a :class:`~pedmesh.run.results.RunResult`
as a run folder's is."""

from __future__ import annotations

import copy
import csv
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np

from .._version import __version__
from ..errors import PedmeshError
from ..io.run_folder import json_safe
from .results import (BUILDING_TRAJECTORY_DTYPE, TRAJECTORY_DTYPE, MemoryOutput,
                      RunResult)

__all__ = ["MemoryWriter"]


class MemoryWriter:
    """Collects what :class:`~pedmesh.run.output.RunWriter` would write (see its methods)."""

    def __init__(self, header: Mapping[str, Any], *, exit_names: Sequence[str] = ()) -> None:
        self.header = {**dict(header), "pedmesh_version": __version__}
        self.exit_names = list(exit_names)
        self.evacuation: list[tuple[float, float]] = []
        self.outflow_rows: list[tuple[float, list[float]]] = []
        #: name -> (header, rows as lists of fields) of the tables a model appends to
        self.tables: dict[str, tuple[Any, list[list]]] = {}
        #: (t [s], point data, cell data) of each density frame
        self.density: list[tuple[float, dict, dict]] = []
        #: (t [s], positions (n, 2) [m], data) of each pedestrian frame
        self.pedestrians: list[tuple[float, np.ndarray, dict]] = []
        self.trajectory: list[np.ndarray] = []
        self.frame_rate: float | None = None
        self.triangles: np.ndarray | None = None
        self.summary: dict[str, Any] = {**self.header, "status": "running"}

    def start(self, header: Mapping[str, Any] | None = None) -> None:
        if header:
            self.header.update(header)
            self.summary.update(header)

    def call(self, fn, *args: Any, **kwargs: Any) -> None:
        """``fn(self, *args, **kwargs)`` (:meth:`pedmesh.run.output.RunWriter.call`)."""
        fn(self, *args, **kwargs)

    def sample(self, t: float, evacuated: float) -> None:
        self.evacuation.append((float(t), float(evacuated)))

    def outflow(self, t: float, flows: Sequence[float]) -> None:
        self.outflow_rows.append((float(t), [float(f) for f in flows]))

    def append_rows(self, name: str, header: Sequence[str] | str,
                    rows: Sequence[Sequence[Any] | str]) -> None:
        """Keep rows of a table (fields, or a CSV line as a string)."""
        self.tables.setdefault(name, (header, []))[1].extend(
            next(csv.reader([r])) if isinstance(r, str) else list(r)
            for r in rows)

    def density_frame(self, t: float, mesh, point_data=None, cell_data=None) -> None:
        if self.triangles is None:
            self.triangles = np.array(mesh.triangles, np.int64)
        self.density.append((float(t), copy.deepcopy(dict(point_data or {})),
                             copy.deepcopy(dict(cell_data or {}))))

    def pedestrian_frame(self, t: float, points: np.ndarray,
                         data: Mapping[str, np.ndarray]) -> None:
        self.pedestrians.append((float(t), np.array(points, float),
                                 {k: np.array(v) for k, v in data.items()}))

    def trajectory_frame(self, frame: int, ids: np.ndarray, points: np.ndarray,
                         frame_rate: float, description: str, *,
                         orientation: np.ndarray | None = None,
                         walkable_wkt: str | None = None, z: np.ndarray | None = None,
                         place: Sequence[str] | None = None) -> None:
        points = np.asarray(points, float).reshape(-1, 2)
        building = z is not None
        rows = np.empty(len(points), dtype=BUILDING_TRAJECTORY_DTYPE if building
                        else TRAJECTORY_DTYPE)
        rows["id"] = np.asarray(ids, np.int64)
        rows["frame"] = frame
        rows["x"] = points[:, 0]
        rows["y"] = points[:, 1]
        if building:
            rows["z"] = np.asarray(z, float)
            rows["place"] = list(place) if place is not None else ""
        self.trajectory.append(rows)
        self.frame_rate = float(frame_rate)

    def finish(self, **summary: Any) -> dict[str, Any]:
        self.summary = json_safe({**self.header, **summary})
        return self.summary

    def result(self) -> RunResult:
        """What the run made, as a :class:`~pedmesh.run.results.RunResult` (the type a
        run folder is read as)."""
        ev = np.array(self.evacuation, float).reshape(-1, 2)
        t_out = np.array([r[0] for r in self.outflow_rows], float)
        flows = np.array([r[1] for r in self.outflow_rows], float).reshape(
            len(self.outflow_rows), len(self.exit_names))
        traj = (np.concatenate(self.trajectory) if self.trajectory
                else np.zeros(0, TRAJECTORY_DTYPE))
        return RunResult(None, self.summary, MemoryOutput(
            evacuation=(ev[:, 0], ev[:, 1]), outflow=(t_out, flows, list(self.exit_names)),
            tables=self.tables, density=self.density, pedestrians=self.pedestrians,
            trajectories=traj, frame_rate=self.frame_rate, triangles=self.triangles))
