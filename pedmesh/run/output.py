"""Run output written as the run goes, so an interrupted run keeps what it computed.

Files in the output directory:

* ``summary.json``: model, status, evacuation times, counts, parameters, timing; written
  at the start (status ``running``) and rewritten at the end;
* ``evacuation.csv``: ``t,evacuated`` (cumulative number of pedestrians out), a row every
  ``sample_interval`` seconds, flushed as written;
* ``outflow.csv`` (continuum models): ``t`` and the flow [ped/s] through each exit;
* ``density.pvd`` + frames: the density on the mesh; ``pedestrians.pvd`` + ``.vtp`` frames
  (particle models): positions with velocity, speed and local density;
* ``trajectories.txt`` (particle models): ``id frame x y`` in metres, readable by PedPy's
  ``load_trajectory_from_txt`` (the frame rate is stated in the header).
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from .. import __version__
from ..io.vtk import PVDWriter

__all__ = ["RunWriter", "evacuation_times", "evacuation_times_from_curve"]


def _atomic_write(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + ".part")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, path)


def _clean(obj: Any) -> Any:
    """JSON-safe copy: numpy scalars to Python, NaN/inf to None."""
    if isinstance(obj, Mapping):
        return {str(k): _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _clean(obj.tolist())
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        f = float(obj)
        return f if math.isfinite(f) else None
    return obj


def evacuation_times(exit_times: np.ndarray, n_initial: int,
                     fractions: Sequence[float] = (0.5, 0.9, 1.0)) -> list[float | None]:
    """Times [s] by which the given fractions of ``n_initial`` pedestrians have left
    (``None`` if not reached): the ``ceil(f N)``-th exit time."""
    t = np.sort(np.asarray(exit_times, float)[np.isfinite(exit_times)])
    out: list[float | None] = []
    for f in fractions:
        k = max(int(math.ceil(f * n_initial - 1e-9)), 1)
        out.append(float(t[k - 1]) if len(t) >= k else None)
    return out


def evacuation_times_from_curve(t: np.ndarray, evacuated: np.ndarray, n_initial: float,
                                fractions: Sequence[float] = (0.5, 0.9, 1.0)) -> list[float | None]:
    """First times [s] at which a cumulative evacuation curve reaches ``f * n_initial``
    (linear interpolation between samples); ``None`` if not reached."""
    t = np.asarray(t, float)
    e = np.asarray(evacuated, float)
    out: list[float | None] = []
    for f in fractions:
        target = f * n_initial
        idx = np.flatnonzero(e >= target - 1e-9 * max(n_initial, 1.0))
        if len(idx) == 0:
            out.append(None)
            continue
        k = int(idx[0])
        if k == 0 or e[k] == e[k - 1]:
            out.append(float(t[k]))
        else:
            w = (target - e[k - 1]) / (e[k] - e[k - 1])
            out.append(float(t[k - 1] + min(max(w, 0.0), 1.0) * (t[k] - t[k - 1])))
    return out


class RunWriter:
    """Incremental writer of one run's output directory (see module docstring)."""

    def __init__(self, out_dir: str | Path, header: Mapping[str, Any], *,
                 exit_names: Sequence[str] = (), outflow: bool = False) -> None:
        self.dir = Path(out_dir)
        self.dir.mkdir(parents=True, exist_ok=True)
        self.header = dict(header)
        self.header.setdefault("pedmesh_version", __version__)
        self._summary_path = self.dir / "summary.json"
        self._write_summary({**self.header, "status": "running"})
        self._evac = open(self.dir / "evacuation.csv", "w", encoding="utf-8")
        self._evac.write("t,evacuated\n")
        self._evac.flush()
        self._outflow = None
        if outflow:
            self._outflow = open(self.dir / "outflow.csv", "w", encoding="utf-8")
            self._outflow.write("t," + ",".join(exit_names) + "\n")
            self._outflow.flush()
        self._density: PVDWriter | None = None
        self._peds: PVDWriter | None = None
        self._traj = None
        self._extra: dict = {}
        self.frames = 0

    # ------------------------------------------------------------------ pieces
    def _write_summary(self, data: Mapping[str, Any]) -> None:
        _atomic_write(self._summary_path, json.dumps(_clean(data), indent=2) + "\n")

    def sample(self, t: float, evacuated: float) -> None:
        """Append a row to evacuation.csv."""
        val = f"{int(evacuated)}" if float(evacuated).is_integer() else f"{evacuated:.6g}"
        self._evac.write(f"{t:.4f},{val}\n")
        self._evac.flush()

    def outflow(self, t: float, flows: Sequence[float]) -> None:
        """Append a row to outflow.csv (flow [ped/s] per exit)."""
        if self._outflow is not None:
            self._outflow.write(f"{t:.4f}," + ",".join(f"{f:.6g}" for f in flows) + "\n")
            self._outflow.flush()

    def append_rows(self, name: str, header: str, rows: Sequence[str]) -> None:
        """Append text rows to a CSV file of the run (created with ``header``)."""
        path = self.dir / name
        if name not in self._extra:
            self._extra[name] = open(path, "w", encoding="utf-8")
            self._extra[name].write(header + "\n")
        f = self._extra[name]
        if rows:
            f.write("\n".join(rows) + "\n")
        f.flush()

    def density_frame(self, t: float, mesh, point_data=None, cell_data=None) -> None:
        """Add a frame to density.pvd."""
        if self._density is None:
            self._density = PVDWriter(self.dir / "density.pvd")
        self._density.write_mesh(t, mesh, point_data, cell_data)

    def pedestrian_frame(self, t: float, points: np.ndarray, data: Mapping[str, np.ndarray]) -> None:
        """Add a frame to pedestrians.pvd."""
        if self._peds is None:
            self._peds = PVDWriter(self.dir / "pedestrians.pvd")
        self._peds.write_points(t, points, data)

    def trajectory_frame(self, frame: int, ids: np.ndarray, points: np.ndarray,
                         frame_rate: float, description: str) -> None:
        """Append one frame to trajectories.txt (PedPy text format)."""
        if self._traj is None:
            self._traj = open(self.dir / "trajectories.txt", "w", encoding="utf-8")
            self._traj.write(f"# pedmesh {__version__}: {description}\n")
            self._traj.write(f"# framerate: {frame_rate:g} fps (frame k is at t = k / framerate s)\n")
            self._traj.write("# unit: x/m, y/m (coordinates in metres)\n")
            self._traj.write("# id frame x y\n")
        lines = "".join(f"{int(i)} {frame} {p[0]:.4f} {p[1]:.4f}\n" for i, p in zip(ids, points))
        self._traj.write(lines)
        self._traj.flush()

    def finish(self, **summary: Any) -> dict[str, Any]:
        """Close the files and write the final summary; returns it."""
        for f in (self._evac, self._outflow, self._traj, *self._extra.values()):
            if f is not None and not f.closed:
                f.close()
        for w in (self._density, self._peds):
            if w is not None:
                w.close()
        data = {**self.header, **summary}
        self._write_summary(data)
        return _clean(data)
