"""Reading a finished (or interrupted) run directory back."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import PedmeshError
from ..io.vtk import read_pvd_index
from .tables import crossings_from_rows, read_number_table, read_rows

__all__ = ["RunResult", "FINISHED_STATUSES"]

#: the statuses of a run that ran to its end (everyone out, or t_end reached)
FINISHED_STATUSES = ("finished", "stopped at t_end")


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
class RunResult:
    """The outputs of one run (see :mod:`pedmesh.run.output`)."""

    path: Path
    summary: dict = field(repr=False)

    @classmethod
    def load(cls, path: str | Path) -> "RunResult":
        """The run in ``path``; a one-line :class:`~pedmesh.errors.PedmeshError` naming the
        file if there is no summary.json or it is broken (truncated, not a JSON object,
        wrong-typed fields: :class:`~pedmesh.run.output.BrokenSummaryError`)."""
        from .output import load_summary

        p = Path(path)
        return cls(p, load_summary(p))

    @property
    def model(self) -> str:
        return self.summary["model"]

    @property
    def status(self) -> str | None:
        """The recorded status, except that a run whose process is gone while its summary
        still says ``running`` (killed) reads as ``interrupted``."""
        from .output import run_status

        return run_status(self.path, self.summary)

    @property
    def finished(self) -> bool:
        return self.status in FINISHED_STATUSES

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

    @cached_property
    def evacuation(self) -> tuple[np.ndarray, np.ndarray]:
        """(t [s], cumulative number out)."""
        _, d = read_number_table(self.path / "evacuation.csv", 2)
        return d[:, 0], d[:, 1]

    @cached_property
    def outflow(self) -> tuple[np.ndarray, np.ndarray, list[str]]:
        """(t [s], flow per exit [ped/s] (k, n_exits), exit names)."""
        p = self.path / "outflow.csv"
        if not p.exists():
            return np.zeros(0), np.zeros((0, 0)), []
        h, d = read_number_table(p)
        return d[:, 0], d[:, 1:], h[1:]

    @cached_property
    def exit_times(self) -> np.ndarray:
        """Exit times [s] of the pedestrians who left (particle models)."""
        p = self.path / "exits.csv"
        if not p.exists():
            return np.zeros(0)
        return crossings_from_rows(read_rows(p)[1], p)[2]

    @cached_property
    def density_frames(self) -> list[tuple[float, Path]]:
        p = self.path / "density.pvd"
        return read_pvd_index(p) if p.exists() else []

    def density_at(self, t: float, mesh) -> tuple[float, np.ndarray, np.ndarray]:
        """(frame time, cell density [ped/m^2], cell velocity [m/s]) of the frame nearest
        to ``t``. Vertex fields (particle models) are averaged to the cells. ``mesh``: the
        mesh the run was made on; another mesh is refused (its vertices or triangles differ
        from the frame's)."""
        from ..io.vtk import frame_density, read_vtu

        frames = self.density_frames
        if not frames:
            raise PedmeshError(f"{self.path}: no density frames")
        k = int(np.argmin([abs(ft - t) for ft, _ in frames]))
        ft, f = frames[k]
        pts, ftri, pd, cd = read_vtu(f)  # (a broken frame: FrameReadError naming it)
        _check_frame_mesh(f, pts, ftri, mesh)
        tri = mesh.triangles
        rho = frame_density(f, pd, cd, tri)
        if "rho" in cd:  # (a continuum's velocity per cell, a particle model's per vertex)
            v = cd.get("velocity")
            vel = np.zeros((len(rho), 2)) if v is None else np.asarray(v)[:, :2]
        else:
            v = pd.get("velocity")
            vel = np.zeros((len(tri), 2)) if v is None else np.asarray(v)[:, :2][tri].mean(axis=1)
        return ft, rho, vel
