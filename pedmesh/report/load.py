"""What the report reads: which kind of folder pedmesh wrote (:func:`folder_kind`), a run
folder (:class:`Run`, its density frames :class:`Frames`), an ensemble folder
(:class:`Ensemble`) and the folders of one report (:func:`load_folders`).

A run folder's files are read through :class:`~pedmesh.run.results.RunResult`, the one
reader of run folders; :class:`Run` adds what the report needs of them (its room file, the
frames laid out for drawing, notes on what is missing)."""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from ..errors import PedmeshError
from ..io.run_folder import (COMPARISON_CSV, DENSITY_DIR, DENSITY_PVD, ENSEMBLE_CSV,
                             ENSEMBLE_JSON, ENSEMBLE_MEMBERS, EVACUATION, EXITS, SUMMARY)
from .text import float_or_none, is_num, number

__all__ = ["ReportError", "folder_kind", "Run", "Frames", "Ensemble", "load_folders"]


class ReportError(PedmeshError):
    """A folder cannot be reported on (missing, or not a run, compare or ensemble folder)."""


def folder_kind(path: str | Path) -> str:
    """``"run"``, ``"compare"`` or ``"ensemble"``: what pedmesh wrote into ``path``;
    :class:`ReportError` for anything else."""
    p = Path(path)
    if not p.exists():
        raise ReportError(f"{p}: no such folder")
    if not p.is_dir():
        raise ReportError(f"{p}: not a folder (give a run, compare or ensemble folder)")
    if (p / ENSEMBLE_CSV).is_file():
        return "ensemble"
    if (p / COMPARISON_CSV).is_file():
        return "compare"
    if (p / SUMMARY).is_file():
        try:
            s = json.loads((p / SUMMARY).read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise ReportError(f"{p / SUMMARY}: not readable as JSON ({exc})") from None
        if not isinstance(s, dict) or "pedmesh_version" not in s or "model" not in s:
            raise ReportError(f"{p / SUMMARY}: not the summary of a pedmesh run")
        return "run"
    raise ReportError(f"{p}: not a pedmesh run, compare or ensemble folder (it has no "
                      "summary.json, comparison.csv or ensemble.csv)")


def _read_csv_rows(path: Path) -> list[dict[str, str]]:
    try:
        with open(path, newline="", encoding="utf-8") as f:
            return list(csv.DictReader(f))
    except (UnicodeDecodeError, csv.Error) as exc:
        raise ReportError(f"{path}: not a CSV table of pedmesh's ({exc})") from None


class Run:
    """One run folder, read lazily."""

    def __init__(self, path: Path, label: str | None = None) -> None:
        from ..run.results import RunResult

        self.path = Path(path)
        self.result = RunResult.load(self.path)
        self.summary: dict = self.result.summary
        self.label = label or self.path.name
        self.notes: list[str] = []  # what the report itself found (room file, frames)
        #: a building's layout (:mod:`pedmesh.run.layout`), set when its frames are read
        self.layout = None
        self.exit_passages  # (exits.csv read now: a broken one stops the report, named)

    @property
    def s(self) -> dict:
        return self.summary

    @cached_property
    def status(self) -> str:
        return self.result.status or "unknown"

    @cached_property
    def safety(self) -> dict | None:
        """summary.json's crowd-safety record; None if there is none or it holds the error
        that stopped it (:attr:`safety_missing` says why)."""
        sf = self.summary.get("safety")
        return sf if isinstance(sf, dict) and "error" not in sf else None

    @cached_property
    def safety_missing(self) -> str:
        """Why the run has no crowd-safety record, in words ('' if it has one)."""
        sf = self.summary.get("safety")
        if self.safety is not None:
            return ""
        if isinstance(sf, dict) and sf.get("error"):
            return f"they could not be computed: {sf['error']}"
        status = self.status
        if status == "running":
            return ("the run is still running, so they are not computed yet (they are when "
                    "it ends)")
        if status in ("interrupted", "failed"):
            return f"the run was {status} before they were computed"
        return "the run was made before pedmesh recorded them in summary.json"

    @cached_property
    def geometry(self):
        """The room or building of the run's room file; None (and a note) if it is not
        found or cannot be read."""
        from ..io import load_room
        from ..run.layout import find_room_file

        sha = (self.summary.get("settings") or {}).get("room_sha256")
        path, note = find_room_file(self.summary.get("geometry"), self.path, sha)
        if note:
            self.notes.append(note)
        if path is None:
            return None
        try:
            return load_room(path)
        except PedmeshError as exc:
            self.notes.append(f"the room file {path} could not be read: {exc}")
            return None

    @cached_property
    def room(self):
        """The run's room (None for a building: drawn from its mesh, laid out flat, see
        :attr:`frames`; None if the room file is not found)."""
        from ..geometry.site import is_building

        room = self.geometry
        return None if room is None or is_building(room) else room

    @cached_property
    def exit_widths(self) -> dict[str, float]:
        """Width [m] of each exit by name, its length along the wall (every level's of a
        building); {} if the room file is not found."""
        from ..geometry.site import is_building

        g = self.geometry
        if g is None:
            return {}
        rooms = [lv.room for lv in g.levels] if is_building(g) else [g]
        return {e.name: r.exit_length(k) for r in rooms for k, e in enumerate(r.exits)}

    @cached_property
    def evacuation(self) -> tuple[np.ndarray, np.ndarray]:
        """The evacuation curve; a note if evacuation.csv is missing (a run that failed
        before its first step), a one-line error naming it if it cannot be read."""
        if not (self.path / EVACUATION).exists():
            self.notes.append("evacuation.csv is missing: no evacuation curve")
            return np.zeros(0), np.zeros(0)
        return self.result.evacuation

    @cached_property
    def outflow(self) -> tuple[np.ndarray, np.ndarray, list[str]]:
        return self.result.outflow

    @cached_property
    def exit_passages(self) -> dict[str, list[float]]:
        """Exit times [s] by exit of everyone who left (particle models; exits.csv)."""
        out: dict[str, list[float]] = {}
        if not self.result.has_table(EXITS):
            return out
        _, names, times = self.result.crossings
        for name, t in zip(names, times):
            out.setdefault(name, []).append(float(t))
        return out

    @cached_property
    def frames(self) -> "Frames | None":
        fr = Frames.read(self.result)
        if fr is None:
            self.notes.append("no density frames were saved (density.pvd missing or empty)")
        elif fr.z_span > 0:  # a building: one panel per level (pedmesh.run.layout)
            from ..run.layout import building_layout

            self.layout, note = building_layout(self.summary, self.path, len(fr.triangles))
            if note:
                self.notes.append(note)
            if self.layout is not None:
                fr.frame_triangles = fr.triangles
                fr.points = np.asarray(self.layout.points)
                fr.triangles = np.asarray(self.layout.triangles)
                fr.layout = self.layout
        return fr

    @cached_property
    def ped_frames(self) -> list[tuple[float, Path]]:
        return self.result.pedestrian_frames

    def positions_at(self, t: float) -> np.ndarray | None:
        """Pedestrian positions [m] of the saved frame at ``t`` (particle models), None if
        none is within 1e-6 s."""
        fr = self.ped_frames
        if not fr:
            return None
        times = np.array([ft for ft, _ in fr])
        k = int(np.argmin(np.abs(times - t)))
        if abs(times[k] - t) > 1e-6:
            return None
        from ..io.vtk import read_vtp

        pts, data = read_vtp(fr[k][1])
        if not len(pts):
            return np.zeros((0, 2))
        if self.layout is not None and "piece" in data:
            return self.layout.crowd(pts, data["piece"])
        return np.asarray(pts)[:, :2]

    def exits(self) -> list[dict[str, Any]]:
        """Per exit: name, people, first and last passage [s] (None where unknown)."""
        names = list(self.outflow[2])
        counted = self.summary.get("exits") if isinstance(self.summary.get("exits"),
                                                          dict) else {}
        sexits = (self.safety or {}).get("exits") or {}
        for n in list(counted) + list(sexits):
            if n not in names:
                names.append(n)
        t, flows, fnames = self.outflow
        rows = []
        for n in names:
            row = {"name": n, "people": None, "first": None, "last": None}
            if n in sexits and isinstance(sexits[n], dict):
                row.update({k: sexits[n].get(k) for k in ("people", "first", "last")})
            if row["people"] is None and n in counted:
                row["people"] = counted[n]
            if row["people"] is None and n in fnames and len(t) > 1:
                k = fnames.index(n)
                row["people"] = float(np.sum(flows[1:, k] * np.diff(t)))
            if row["first"] is None and self.exit_passages.get(n):
                row["first"] = min(self.exit_passages[n])
                row["last"] = max(self.exit_passages[n])
            rows.append(row)
        return rows


@dataclass
class Frames:
    """The density frames of a run: times [s], files, the mesh (points [m], triangles)."""

    times: np.ndarray
    paths: list[Path]
    points: np.ndarray
    triangles: np.ndarray
    z_span: float = 0.0  # [m] the height range of the frames' points (0: one plane)
    _n_points: int = 0  # the first frame's points
    layout: Any = None  # a building's layout (its atlas), where points are drawn
    #: the frames' own triangles (their point data's), where ``triangles`` are the layout's
    frame_triangles: np.ndarray | None = None
    _cache: dict = field(default_factory=dict, repr=False)

    @classmethod
    def read(cls, result) -> "Frames | None":
        """The frames of a run folder (its :class:`~pedmesh.run.results.RunResult`); None
        if the run saved none; a one-line error naming the file if its index or a frame is
        not whole or cannot be read."""
        from ..io.vtk import check_frames_whole, frame_density, read_vtu

        run_dir = result.path
        p = run_dir / DENSITY_PVD
        saved = sorted((run_dir / DENSITY_DIR).glob("density_*.vtu")) \
            if (run_dir / DENSITY_DIR).is_dir() else []
        if not p.exists():
            if saved:
                raise ReportError(f"{p}: missing, though density/ holds {len(saved)} frames "
                                  "(the index of the frames is lost: rerun the run)")
            return None
        index = result.density_frames
        if not index:
            if saved:
                raise ReportError(f"{p}: lists no frames, though density/ holds "
                                  f"{len(saved)} (rerun the run)")
            return None
        check_frames_whole(f for _, f in index)  # (not only the frames the report shows)
        pts, tri, pd, cd = read_vtu(index[0][1])
        self = cls(np.array([t for t, _ in index], float), [f for _, f in index],
                   np.asarray(pts)[:, :2].copy(), tri, float(np.ptp(np.asarray(pts)[:, 2])))
        self._n_points = len(pts)
        self._cache[0] = frame_density(index[0][1], pd, cd, tri)
        return self

    @cached_property
    def areas(self) -> np.ndarray:
        p = self.points[self.triangles]
        return 0.5 * np.abs((p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1])
                            - (p[:, 2, 0] - p[:, 0, 0]) * (p[:, 1, 1] - p[:, 0, 1]))

    @cached_property
    def centroids(self) -> np.ndarray:
        return self.points[self.triangles].mean(axis=1)

    def density(self, k: int) -> np.ndarray | None:
        """Cell density [ped/m^2] of frame ``k``; a one-line error naming it if it cannot be
        read, has no density field or its mesh differs from the first frame's."""
        if k in self._cache:
            return self._cache[k]
        rho, _ = self._read(k)
        if len(self._cache) < 4096:
            self._cache[k] = rho
        return rho

    def fields(self, k: int) -> tuple[np.ndarray, np.ndarray | None]:
        """(cell density [ped/m^2], cell speed [m/s] or None) of frame ``k``: the speed is
        the length of the frame's velocity (a cell field, or a vertex field averaged over
        the cells); None if the frame has none. Errors as :meth:`density`'s."""
        rho, fields = self._read(k)
        pd, cd, own = fields
        if "velocity" in cd:
            v = np.asarray(cd["velocity"], float)
        elif "velocity" in pd:
            v = np.asarray(pd["velocity"], float)[own].mean(axis=1)
        else:
            return rho, None
        return rho, np.linalg.norm(v.reshape(len(v), -1), axis=1)

    def _read(self, k: int):
        """(cell density, (point fields, cell fields, the frame's own triangles)) of frame
        ``k``, its mesh checked against the first frame's."""
        from ..io.vtk import check_same_mesh, frame_density, read_vtu

        pts, tri, pd, cd = read_vtu(self.paths[k])
        own = self.triangles if self.frame_triangles is None else self.frame_triangles
        check_same_mesh(self.paths[k], pts, tri, self._n_points, own)
        return frame_density(self.paths[k], pd, cd, own), (pd, cd, own)

    @cached_property
    def peak(self) -> tuple[np.ndarray, np.ndarray]:
        """(largest density [ped/m^2] of each cell over the frames, time [s] of it)."""
        best = np.zeros(len(self.triangles))
        when = np.zeros(len(self.triangles))
        for k in range(len(self.times)):
            rho = self.density(k)
            up = rho > best
            best[up] = rho[up]
            when[up] = self.times[k]
            self._cache.pop(k, None)  # the snapshots read the few frames they show again
        return best, when


def _ensemble_meta_problem(meta: Any) -> str | None:
    """What is wrong with ``meta`` as ensemble.json (None if nothing the report reads)."""
    if not isinstance(meta, dict):
        return "not a JSON object"
    if meta.get("sweep") is not None and not isinstance(meta["sweep"], dict):
        return "'sweep' is not an object"
    points = meta.get("points")
    if points is not None and not (isinstance(points, list)
                                   and all(isinstance(p, dict) for p in points)):
        return "'points' is not a list of objects"
    return None


class Ensemble:
    """An ensemble folder: its members' table, the percentiles, the members' runs."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self.rows = _read_csv_rows(self.path / ENSEMBLE_CSV)
        need = {"member", "point", "status"}
        if self.rows and not need <= set(self.rows[0]):
            raise ReportError(f"{self.path / ENSEMBLE_CSV}: not pedmesh's members table "
                              f"(no column '{sorted(need - set(self.rows[0]))[0]}')")
        self.meta: dict = {}
        jp = self.path / ENSEMBLE_JSON
        if jp.exists():
            try:
                self.meta = json.loads(jp.read_text(encoding="utf-8"))
            except (OSError, ValueError):
                self.meta = {}
            problem = _ensemble_meta_problem(self.meta)
            if problem:
                raise ReportError(f"{jp}: not pedmesh's ensemble record ({problem})")
        self.sweep = list((self.meta.get("sweep") or {}).keys())
        if not self.sweep and self.rows:
            cols = list(self.rows[0])
            if "seed" in cols and "status" in cols:
                self.sweep = cols[cols.index("seed") + 1:cols.index("status")]

    @property
    def label(self) -> str:
        return self.path.name

    def finished(self, point: str | None = None) -> list[dict]:
        from ..run.results import FINISHED_STATUSES

        return [r for r in self.rows if r.get("status") in FINISHED_STATUSES
                and (point is None or r.get("point") == point)]

    @cached_property
    def points(self) -> list[dict]:
        """Per sweep point: values, members, finished, failed and the 5/50/95 percentiles,
        mean and standard deviation of T50/T90/T100 (ensemble.json's, else computed as
        pedmesh.ensembles does)."""
        if self.meta.get("points"):
            return list(self.meta["points"])
        from ..ensembles import percentile_stats

        out = []
        for p in sorted({r.get("point", "0") for r in self.rows}, key=lambda x: int(x or 0)):
            grp = [r for r in self.rows if r.get("point", "0") == p]
            done = self.finished(p)
            e = {"point": int(p or 0), "values": {k: grp[0].get(k) for k in self.sweep},
                 "members": len(grp), "finished": len(done),
                 "failed": sum(r.get("status") == "failed" for r in grp)}
            for k in ("t_evac_50", "t_evac_90", "t_evac_100"):
                e[k] = percentile_stats([float_or_none(r.get(k)) for r in done])
            out.append(e)
        return out

    def point_label(self, entry: Mapping) -> str:
        vals = entry.get("values") or {}
        return ", ".join(f"{k} = {number(v) if is_num(v) else v}" for k, v in vals.items()) \
            or "all members"

    def member_dir(self, member: str) -> Path:
        return self.path / ENSEMBLE_MEMBERS / member

    @cached_property
    def typical(self) -> Run | None:
        """The finished member of the first sweep point whose T90 is nearest the median."""
        pts = self.points
        if not pts:
            return None
        done = self.finished(str(pts[0].get("point", 0)))
        vals = [(float_or_none(r.get("t_evac_90")), r["member"]) for r in done]
        vals = [(v, m) for v, m in vals if v is not None
                and (self.member_dir(m) / SUMMARY).exists()]
        if not vals:
            return None
        med = float(np.median([v for v, _ in vals]))
        _, member = min(vals, key=lambda vm: (abs(vm[0] - med), vm[1]))
        return Run(self.member_dir(member), label=f"member {member}")


def load_folders(folders: Sequence[str | Path]) -> tuple[list[Run], list[dict], list[Ensemble]]:
    """The runs (a compare folder's in its table's order), the comparison tables and the
    ensembles of ``folders``."""
    runs: list[Run] = []
    comparisons: list[dict] = []
    ensembles: list[Ensemble] = []
    if not folders:
        raise ReportError("no folder given")
    for f in folders:
        p = Path(f)
        kind = folder_kind(p)
        if kind == "run":
            runs.append(Run(p))
        elif kind == "compare":
            rows = _read_csv_rows(p / COMPARISON_CSV)
            labels = [r.get("label") for r in rows if r.get("label")]
            missing = [lab for lab in labels if not (p / lab / SUMMARY).is_file()]
            if missing:
                raise ReportError(f"{p}: the run folder of '{missing[0]}' in comparison.csv "
                                  "is missing")
            if not labels:
                raise ReportError(f"{p / COMPARISON_CSV}: no models listed")
            runs.extend(Run(p / lab, label=lab) for lab in labels)
            comparisons.append({"path": p, "rows": rows})
        else:
            ensembles.append(Ensemble(p))
    # labels that tell the runs apart
    names = [r.label for r in runs]
    if len(set(names)) < len(names):
        for r in runs:
            r.label = f"{r.path.parent.name}/{r.path.name}"
    return runs, comparisons, ensembles
