"""Reading a finished (or interrupted) run directory back."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import PedmeshError
from ..io.vtk import read_pvd_index

__all__ = ["RunResult", "FINISHED_STATUSES"]

#: the statuses of a run that ran to its end (everyone out, or t_end reached)
FINISHED_STATUSES = ("finished", "stopped at t_end")


def _csv(path: Path) -> tuple[list[str], np.ndarray]:
    with open(path, encoding="utf-8") as f:
        header = f.readline().strip().split(",")
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    return header, data


@dataclass
class RunResult:
    """The outputs of one run (see :mod:`pedmesh.run.output`)."""

    path: Path
    summary: dict = field(repr=False)

    @classmethod
    def load(cls, path: str | Path) -> "RunResult":
        p = Path(path)
        s = p / "summary.json"
        if not s.exists():
            raise PedmeshError(f"{p}: not a run directory (no summary.json)")
        return cls(p, json.loads(s.read_text()))

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
        _, d = _csv(self.path / "evacuation.csv")
        return d[:, 0], d[:, 1]

    @cached_property
    def outflow(self) -> tuple[np.ndarray, np.ndarray, list[str]]:
        """(t [s], flow per exit [ped/s] (k, n_exits), exit names)."""
        p = self.path / "outflow.csv"
        if not p.exists():
            return np.zeros(0), np.zeros((0, 0)), []
        h, d = _csv(p)
        return d[:, 0], d[:, 1:], h[1:]

    @cached_property
    def exit_times(self) -> np.ndarray:
        """Exit times [s] of the pedestrians who left (particle models)."""
        p = self.path / "exits.csv"
        if not p.exists():
            return np.zeros(0)
        rows = p.read_text().splitlines()[1:]
        return np.array([float(r.split(",")[2]) for r in rows if r])

    @cached_property
    def density_frames(self) -> list[tuple[float, Path]]:
        p = self.path / "density.pvd"
        return read_pvd_index(p) if p.exists() else []

    def density_at(self, t: float, mesh) -> tuple[float, np.ndarray, np.ndarray]:
        """(frame time, cell density [ped/m^2], cell velocity [m/s]) of the frame nearest
        to ``t``. Vertex fields (particle models) are averaged to the cells."""
        import pyvista as pv

        frames = self.density_frames
        if not frames:
            raise PedmeshError(f"{self.path}: no density frames")
        k = int(np.argmin([abs(ft - t) for ft, _ in frames]))
        ft, f = frames[k]
        m = pv.read(f)
        if "rho" in m.cell_data:
            rho = np.asarray(m.cell_data["rho"])
            vel = np.asarray(m.cell_data["velocity"])[:, :2]
        else:
            tri = mesh.triangles
            rho = np.asarray(m.point_data["density"])[tri].mean(axis=1)
            v = m.point_data["velocity"] if "velocity" in m.point_data else None
            vel = np.zeros((len(tri), 2)) if v is None else np.asarray(v)[:, :2][tri].mean(axis=1)
        return ft, rho, vel
