"""A run's outputs, read back: one type, :class:`RunResult`, whether the run kept them in
memory (the Python API without ``out_dir``) or wrote a run folder (``pedmesh run``,
``out_dir=``). Every consumer of a run's output (the report, ``pedmesh compare``, the
ensembles, ``pedmesh animate``, the API) reads it here; the folder's file names are those of
:mod:`pedmesh.io.run_folder`."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import PedmeshError
from ..io.vtk import read_pvd_index
from ..io import run_folder as F
from ..io.run_folder import FINISHED_STATUSES
from .tables import crossings_from_rows, read_number_table, read_rows

__all__ = ["RunResult", "FINISHED_STATUSES", "TRAJECTORY_DTYPE",
           "BUILDING_TRAJECTORY_DTYPE", "MemoryOutput"]

#: one row of a trajectory: pedestrian id, frame number, position [m]
TRAJECTORY_DTYPE = np.dtype([("id", np.int64), ("frame", np.int64), ("x", float),
                             ("y", float)])
#: a building's rows: also the height z [m] and the level or stair (its name)
BUILDING_TRAJECTORY_DTYPE = np.dtype([("id", np.int64), ("frame", np.int64), ("x", float),
                                      ("y", float), ("z", float), ("place", object)])


def _check_frame_mesh(path: Path, frame_points: np.ndarray, frame_tri: np.ndarray,
                      mesh) -> None:
    """A one-line error unless ``mesh`` is the mesh of the frame read from ``path`` (its
    points (n, 3) [m] and triangles)."""
    pts = np.asarray(getattr(mesh, "points", np.zeros((0, 2))))
    n_tri = getattr(mesh, "n_triangles", None)
    why = None
    if len(frame_tri) != n_tri or len(frame_points) != len(pts):
        why = (f"the run's mesh has {len(frame_points)} vertices and {len(frame_tri)} "
               f"triangles, the mesh given {len(pts)} and {n_tri}")
    elif pts.ndim != 2 or not np.allclose(np.asarray(frame_points)[:, :pts.shape[1]], pts,
                                          rtol=0.0, atol=1e-9):
        why = "the vertices of the mesh given are not the run's"
    if why:
        raise PedmeshError(f"{path}: not a frame of this mesh ({why}); give the mesh the run "
                           "was made on")


@dataclass
class MemoryOutput:
    """What a run kept in memory (:class:`~pedmesh.run.memory.MemoryWriter`), the
    in-memory counterpart of the files of its folder."""

    evacuation: tuple[np.ndarray, np.ndarray]
    outflow: tuple[np.ndarray, np.ndarray, list[str]]
    #: name -> (header, rows as lists of fields) of the tables a model appends to
    tables: dict
    density: list
    pedestrians: list
    trajectories: np.ndarray
    frame_rate: float | None
    #: the triangles (m, 3) of the density frames' mesh (None: no frames)
    triangles: np.ndarray | None = None


def _planar(values: np.ndarray) -> np.ndarray:
    """A vector field or positions read from a VTK frame as the model gave them: VTK pads
    2-D vectors to three components, so a third column of zeros is dropped."""
    a = np.asarray(values)
    if a.ndim == 2 and a.shape[1] == 3 and not np.any(a[:, 2]):
        return a[:, :2]
    return a


def _fields(data: dict) -> dict:
    return {k: _planar(v) for k, v in data.items()}


def _read_trajectories(path: Path) -> tuple[np.ndarray, float | None]:
    """(rows, frame rate [1/s]) of trajectories.txt (a building's: also z and the place,
    percent-decoded)."""
    from urllib.parse import unquote

    rate = None
    building = False
    ids, frames, xs, ys, zs, places = [], [], [], [], [], []
    with open(path, encoding="utf-8") as f:
        for line in f:
            if line.startswith("#"):
                if line.startswith("# framerate:"):
                    rate = float(line.split(":", 1)[1].split()[0])
                elif line.startswith("# id frame x y z place"):
                    building = True
                continue
            parts = line.split()
            if len(parts) < (6 if building else 4):
                continue  # (a last line cut short by a killed run)
            ids.append(int(parts[0]))
            frames.append(int(parts[1]))
            xs.append(float(parts[2]))
            ys.append(float(parts[3]))
            if building:
                zs.append(float(parts[4]))
                places.append(unquote(parts[5]))
    rows = np.empty(len(ids), BUILDING_TRAJECTORY_DTYPE if building else TRAJECTORY_DTYPE)
    rows["id"], rows["frame"], rows["x"], rows["y"] = ids, frames, xs, ys
    if building:
        rows["z"] = zs
        rows["place"] = places
    return rows, rate


@dataclass
class RunResult:
    """The outputs of one run, in memory (``path`` None) or in its folder: the same
    attributes either way.

    * ``summary`` (the dict of summary.json), ``model``, ``status``, ``finished``,
      ``times`` (T50, T90, T100 [s]), ``settings``;
    * ``evacuation``: (t [s], cumulative number out); ``outflow``: (t [s], flow per exit
      [ped/s] (k, n_exits), exit names); ``outflow_kernel`` (particle models: the same
      measured by the kernel density; empty otherwise); ``crossings``: (ids, exit names,
      times [s]) of everyone who left (particle models), ``exit_times`` the times;
    * ``density``: (t [s], point data, cell data) per frame, e.g. the continuum's cell
      density ``rho`` [ped/m^2] and ``velocity`` [m/s], the particle models' vertex
      ``density``; ``density_times``; :meth:`density_at` (the frame nearest a time, as
      cell density and velocity) and :meth:`density_fields_at` (its fields as written);
    * ``pedestrians``: (t [s], positions (n, 2) [m] (a building's (n, 3)), per-pedestrian
      data) per frame (particle models);
    * ``trajectories``: a structured array (id, frame, x [m], y [m]; on a building also z
      [m] and place, the level or stair) at ``frame_rate`` frames/s (particle models; frame
      k is at t = k / frame_rate). Read back from a folder, positions are those of
      trajectories.txt (4 decimals, 0.1 mm).
    """

    path: Path | None
    summary: dict = field(repr=False)
    memory: MemoryOutput | None = field(default=None, repr=False)

    @classmethod
    def load(cls, path: str | Path) -> "RunResult":
        """The run in ``path``; a one-line :class:`~pedmesh.errors.PedmeshError` naming the
        file if there is no summary.json or it is broken (truncated, not a JSON object,
        wrong-typed fields: :class:`~pedmesh.io.run_folder.BrokenSummaryError`)."""
        p = Path(path)
        return cls(p, F.load_summary(p))

    # ------------------------------------------------------------------ the summary
    @property
    def model(self) -> str:
        return self.summary["model"]

    @property
    def status(self) -> str | None:
        """The recorded status, except that a run whose process is gone while its summary
        still says ``running`` (killed) reads as ``interrupted``."""
        if self.path is None:
            return self.summary.get("status")
        return F.run_status(self.path, self.summary)

    @property
    def finished(self) -> bool:
        return self.status in FINISHED_STATUSES

    @property
    def times(self) -> dict[str, float | None]:
        """T50, T90 and T100 [s] (None where not reached)."""
        return {k: self.summary.get(f"t_evac_{k[1:]}") for k in ("T50", "T90", "T100")}

    @property
    def settings(self) -> dict:
        """What the run was asked to do (see :func:`pedmesh.run.driver.run_settings`);
        empty for runs written before settings were recorded."""
        return dict(self.summary.get("settings") or {})

    def settings_differences(self, wanted: dict) -> list[tuple[str, Any, Any]]:
        """(key, recorded, wanted) for every setting that differs from ``wanted``, in key
        order; empty if they are all the same."""
        have = self.settings
        return [(k, have.get(k), wanted.get(k)) for k in sorted(set(have) | set(wanted))
                if have.get(k) != wanted.get(k)]

    def file(self, name: str) -> Path | None:
        """The path of the folder's file ``name`` (a name of :mod:`pedmesh.io.run_folder`), or
        None in memory."""
        return None if self.path is None else self.path / name

    def has_table(self, name: str) -> bool:
        """Whether the run wrote the table ``name`` (e.g. :data:`pedmesh.io.run_folder.EXITS`;
        a file of its folder, or kept in memory)."""
        if self.memory is not None:
            return name in self.memory.tables
        return (self.path / name).exists()

    # ------------------------------------------------------------------ time series
    @cached_property
    def evacuation(self) -> tuple[np.ndarray, np.ndarray]:
        """(t [s], cumulative number out)."""
        if self.memory is not None:
            return self.memory.evacuation
        _, d = read_number_table(self.path / F.EVACUATION, 2)
        return d[:, 0], d[:, 1]

    def _flow_table(self, name: str) -> tuple[np.ndarray, np.ndarray, list[str]]:
        if self.memory is not None:
            header, rows = self.memory.tables.get(name, ((), []))
            if not rows:
                return np.zeros(0), np.zeros((0, 0)), []
            d = np.array(rows, float).reshape(len(rows), -1)
            return d[:, 0], d[:, 1:], list(header)[1:]
        p = self.path / name
        if not p.exists():
            return np.zeros(0), np.zeros((0, 0)), []
        h, d = read_number_table(p)
        return d[:, 0], d[:, 1:], h[1:]

    @cached_property
    def outflow(self) -> tuple[np.ndarray, np.ndarray, list[str]]:
        """(t [s], flow per exit [ped/s] (k, n_exits), exit names)."""
        if self.memory is not None:
            return self.memory.outflow
        return self._flow_table(F.OUTFLOW)

    @cached_property
    def outflow_kernel(self) -> tuple[np.ndarray, np.ndarray, list[str]]:
        """(particle models) the exits' flow measured by the kernel density: (t [s], flow
        per exit [ped/s], exit names); empty arrays where the run has none."""
        return self._flow_table(F.OUTFLOW_KERNEL)

    @cached_property
    def crossings(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(ids, exit names, times [s]) of the pedestrians who left (particle models)."""
        if self.memory is not None:
            return crossings_from_rows(self.memory.tables.get(F.EXITS, ((), []))[1])
        p = self.path / F.EXITS
        if not p.exists():
            return crossings_from_rows([])
        return crossings_from_rows(read_rows(p)[1], p)

    @property
    def exit_times(self) -> np.ndarray:
        """Exit times [s] of the pedestrians who left (particle models)."""
        return self.crossings[2]

    # ------------------------------------------------------------------ frames
    @cached_property
    def density_frames(self) -> list[tuple[float, Path | None]]:
        """(t [s], the frame's file) of each density frame (in memory: no file, None)."""
        if self.memory is not None:
            return [(t, None) for t, _, _ in self.memory.density]
        p = self.path / F.DENSITY_PVD
        return read_pvd_index(p) if p.exists() else []

    @property
    def density_times(self) -> np.ndarray:
        """The times [s] of the density frames."""
        return np.array([t for t, _ in self.density_frames], float)

    @cached_property
    def pedestrian_frames(self) -> list[tuple[float, Path | None]]:
        """(t [s], the frame's file) of each pedestrian frame (particle models; in memory:
        no file, None)."""
        if self.memory is not None:
            return [(t, None) for t, _, _ in self.memory.pedestrians]
        p = self.path / F.PEDESTRIANS_PVD
        return read_pvd_index(p) if p.exists() else []

    @cached_property
    def density(self) -> list[tuple[float, dict, dict]]:
        """(t [s], point data, cell data) of each density frame."""
        if self.memory is not None:
            return self.memory.density
        from ..io.vtk import read_vtu

        out = []
        for t, f in self.density_frames:
            _, _, pd, cd = read_vtu(f)
            out.append((t, _fields(pd), _fields(cd)))
        return out

    @cached_property
    def pedestrians(self) -> list[tuple[float, np.ndarray, dict]]:
        """(t [s], positions (n, 2) [m], per-pedestrian data) of each pedestrian frame."""
        if self.memory is not None:
            return self.memory.pedestrians
        from ..io.vtk import read_vtp

        out = []
        for t, f in self.pedestrian_frames:
            pts, data = read_vtp(f)
            out.append((t, _planar(np.asarray(pts, float)), _fields(data)))
        return out

    @cached_property
    def _trajectories(self) -> tuple[np.ndarray, float | None]:
        if self.memory is not None:
            return self.memory.trajectories, self.memory.frame_rate
        p = self.path / F.TRAJECTORIES_TXT
        if not p.exists():
            return np.zeros(0, TRAJECTORY_DTYPE), None
        return _read_trajectories(p)

    @property
    def trajectories(self) -> np.ndarray:
        """The trajectory rows (see the class docstring)."""
        return self._trajectories[0]

    @property
    def frame_rate(self) -> float | None:
        """[frames/s] of :attr:`trajectories` (None: no trajectories)."""
        return self._trajectories[1]

    def _nearest(self, t: float) -> int:
        frames = self.density_frames
        if not frames:
            where = self.path if self.path is not None else "the run"
            raise PedmeshError(f"{where}: no density frames")
        return int(np.argmin([abs(ft - t) for ft, _ in frames]))

    def density_fields_at(self, t: float) -> tuple[float, dict, dict]:
        """The density frame nearest to ``t`` [s] as written: (its time [s], point data,
        cell data)."""
        k = self._nearest(t)
        if self.memory is not None:
            return self.memory.density[k]
        from ..io.vtk import read_vtu

        ft, f = self.density_frames[k]
        _, _, pd, cd = read_vtu(f)
        return ft, _fields(pd), _fields(cd)

    def density_at(self, t: float, mesh=None) -> tuple[float, np.ndarray, np.ndarray]:
        """(frame time [s], cell density [ped/m^2], cell velocity [m/s]) of the frame
        nearest to ``t``. Vertex fields (particle models) are averaged to the cells.
        ``mesh``: optionally the mesh the run was made on, to check the frame against
        (another mesh is refused: its vertices or triangles differ from the frame's)."""
        from ..io.vtk import frame_density, read_vtu

        k = self._nearest(t)
        if self.memory is not None:
            ft, pd, cd = self.memory.density[k]
            tri = self.memory.triangles
            f = "the run's frame"
        else:
            ft, f = self.density_frames[k]
            pts, tri, pd, cd = read_vtu(f)  # (a broken frame: FrameReadError naming it)
            if mesh is not None:
                _check_frame_mesh(f, pts, tri, mesh)
        rho = frame_density(f, pd, cd, tri)
        if "rho" in cd:  # (a continuum's velocity per cell, a particle model's per vertex)
            v = cd.get("velocity")
            vel = np.zeros((len(rho), 2)) if v is None else np.asarray(v)[:, :2]
        else:
            v = pd.get("velocity")
            vel = np.zeros((len(tri), 2)) if v is None else np.asarray(v)[:, :2][tri].mean(axis=1)
        return ft, rho, vel
