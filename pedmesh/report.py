"""Self-contained HTML reports of runs, comparisons and ensembles (``pedmesh report``).

:func:`write_report` turns one or more folders that pedmesh wrote into one HTML page that a
person reads in any browser, offline: every plot is an inline PNG (a ``data:`` URI), the
little JavaScript that drives the time slider is inline, and nothing is fetched from
anywhere. A folder is

* a run folder (``pedmesh run``: ``summary.json``, ``evacuation.csv``, ``outflow.csv``,
  ``density.pvd``; see :mod:`pedmesh.run.output`),
* a compare folder (``pedmesh compare``: ``comparison.csv`` and a run folder per model), or
* an ensemble folder (``pedmesh ensemble``: ``ensemble.csv``, ``ensemble.json`` and the
  members' run folders under ``members/``).

Several folders are shown side by side. The page holds a plain-language summary, the room
plan, the evacuation curves with T50/T90/T100 (the numbers of ``summary.json``, never
recomputed), the exit usage, the peak-density and level-of-service maps, the crowd-safety
measures of ``summary.json`` (key ``safety``; "not available" for runs made before pedmesh
recorded them), density snapshots with a time slider, and every setting, parameter and
warning of the runs. Ensembles add the 5-95 % bands of the evacuation curves and the
percentiles of T50/T90/T100.

The peak-density map is the largest density each mesh cell had in the saved frames of
``density.pvd`` (the cell values; a particle model's vertex densities are averaged to the
cells); the level-of-service map classifies it with Fruin's thresholds
(:data:`FRUIN_LEVELS`). Both are drawn from the frames, for runs with and without the
safety measures.
"""

from __future__ import annotations

import base64
import csv
import datetime as _dt
import html
import io
import json
import math
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

from ._version import __version__
from .analysis.safety import FRUIN_SCALES, level_of_service
from .errors import PedmeshError

__all__ = ["ReportError", "write_report", "build_report", "folder_kind", "FRUIN_LEVELS",
           "DEFAULT_FRAMES"]

#: density snapshots on the slider unless asked otherwise
DEFAULT_FRAMES = 24
#: most snapshots the slider takes (each is an inline image)
MAX_FRAMES = 60

#: Fruin's levels of service A-F by density [ped/m^2]: the upper densities of A, B, C, D
#: and E (F above), walkway and queuing, from the one definition of the tables in
#: :mod:`pedmesh.analysis.safety` (Fruin 1971, in ft^2 per person)
FRUIN_LEVELS: dict[str, tuple[float, ...]] = {
    name: tuple(lv.max_density for lv in levels[:-1]) for name, levels in FRUIN_SCALES.items()}
_LOS = "ABCDEF"
_LOS_COLORS = ["#1a9850", "#91cf60", "#d9ef8b", "#fee08b", "#fc8d59", "#d73027"]
#: density [ped/m^2] at the top of the colour scale of the density maps
_VMAX = 6.0
_THRESHOLDS = ("2", "4", "6")


class ReportError(PedmeshError):
    """A folder cannot be reported on (missing, or not a run, compare or ensemble folder)."""


# ------------------------------------------------------------------ small helpers
def _esc(v: Any) -> str:
    """Text for an element's content."""
    return html.escape(str(v), quote=False)


def _attr(v: Any) -> str:
    """Text for an attribute's value (in double quotes)."""
    return html.escape(str(v), quote=True)


def _num(v: Any, digits: int = 4) -> str:
    """A number for people: ``digits`` significant digits, no exponent below 10^6; '-' for
    None; other values as text."""
    if v is None:
        return "–"
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
        return str(v)
    f = float(v)
    if not math.isfinite(f):
        return "–"
    if float(f).is_integer() and abs(f) < 1e15:
        return f"{int(f):,}".replace(",", " ") if abs(f) >= 1e4 else str(int(f))
    if abs(f) >= 10 ** digits:
        return f"{f:,.0f}".replace(",", " ")
    return f"{f:.{digits}g}"


def _sec(v: Any, missing: str = "not reached") -> str:
    """A time [s] as ``pedmesh run`` prints it (one decimal)."""
    if v is None or not isinstance(v, (int, float)) or not math.isfinite(float(v)):
        return missing
    return f"{float(v):.1f} s"


def _people(v: Any) -> str:
    """People as a whole number for display (a continuum model's fractional mass is kept
    exact in its files)."""
    if v is None:
        return "–"
    return str(int(round(float(v))))


def _unit(u: Any) -> str:
    """A unit as the report writes units: m² rather than m^2."""
    return str(u).replace("ped/m^2", "/m²").replace("^2", "²")


def _exact(v: Any) -> str:
    """A value exactly as json writes it (and so as summary.json has it)."""
    return json.dumps(v)


def _is_num(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(float(v))


def _plt():
    from .plotting import _plt as plt

    return plt()


def _png(fig, dpi: int = 100) -> str:
    """The figure as a PNG data URI, cropped to what is drawn (the figure is closed)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight", pad_inches=0.08)
    _plt().close(fig)
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


def _png_keep(fig, dpi: int = 100) -> str:
    """The figure as a PNG data URI; the figure stays open (the snapshots redraw it)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


def _img(uri: str, alt: str, cls: str = "plot") -> str:
    return f'<img class="{cls}" src="{uri}" alt="{_attr(alt)}">'


def _table(header: Sequence[str], rows: Iterable[Sequence[Any]], cls: str = "") -> str:
    head = "".join(f"<th>{h}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{c}</td>" for c in r) + "</tr>" for r in rows)
    c = f' class="{cls}"' if cls else ""
    return f"<table{c}><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def _read_csv_rows(path: Path) -> list[dict[str, str]]:
    try:
        with open(path, newline="", encoding="utf-8") as f:
            return list(csv.DictReader(f))
    except (UnicodeDecodeError, csv.Error) as exc:
        raise ReportError(f"{path}: not a CSV table of pedmesh's ({exc})") from None


def _float_or_none(text: Any) -> float | None:
    try:
        f = float(text)
    except (TypeError, ValueError):
        return None
    return f if math.isfinite(f) else None


def _moving_mean(t: np.ndarray, flow: np.ndarray, window: float = 2.0) -> np.ndarray:
    """The mean of a flow sampled at ``t`` over the ``window`` [s] centred on each sample
    (the flow of row k covers (t[k-1], t[k]]): the cumulative count differenced."""
    if len(t) < 2:
        return flow
    dt = np.diff(t, prepend=t[0])
    cum = np.cumsum(flow * dt)
    lo = np.interp(t - 0.5 * window, t, cum, left=0.0)
    hi = np.interp(t + 0.5 * window, t, cum)
    span = np.minimum(t + 0.5 * window, t[-1]) - np.maximum(t - 0.5 * window, t[0])
    return np.where(span > 0, (hi - lo) / np.where(span > 0, span, 1.0), 0.0)


def _los_index(rho: np.ndarray, scale: str = "walkway") -> np.ndarray:
    """Fruin's level of service (0 = A ... 5 = F) of densities ``rho`` [ped/m^2]
    (:func:`pedmesh.analysis.safety.level_of_service`)."""
    return level_of_service(density=np.asarray(rho, float),
                            scale=scale if scale in FRUIN_SCALES else "walkway")


def _los_scale(safety: Mapping | None) -> str:
    los = (safety or {}).get("level_of_service") or {}
    scale = str(los.get("scale") or "walkway").lower()
    return "queuing" if scale.startswith("queu") else "walkway"


# ------------------------------------------------------------------ folders
def folder_kind(path: str | Path) -> str:
    """``"run"``, ``"compare"`` or ``"ensemble"``: what pedmesh wrote into ``path``;
    :class:`ReportError` for anything else."""
    p = Path(path)
    if not p.exists():
        raise ReportError(f"{p}: no such folder")
    if not p.is_dir():
        raise ReportError(f"{p}: not a folder (give a run, compare or ensemble folder)")
    if (p / "ensemble.csv").is_file():
        return "ensemble"
    if (p / "comparison.csv").is_file():
        return "compare"
    if (p / "summary.json").is_file():
        try:
            s = json.loads((p / "summary.json").read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise ReportError(f"{p / 'summary.json'}: not readable as JSON ({exc})") from None
        if not isinstance(s, dict) or "pedmesh_version" not in s or "model" not in s:
            raise ReportError(f"{p / 'summary.json'}: not the summary of a pedmesh run")
        return "run"
    raise ReportError(f"{p}: not a pedmesh run, compare or ensemble folder (it has no "
                      "summary.json, comparison.csv or ensemble.csv)")


class _Run:
    """One run folder, read lazily."""

    def __init__(self, path: Path, label: str | None = None) -> None:
        from .run.results import RunResult

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
    def room(self):
        from .io import load_room
        from .run.layout import find_room_file

        sha = (self.summary.get("settings") or {}).get("room_sha256")
        path, note = find_room_file(self.summary.get("geometry"), self.path, sha)
        if note:
            self.notes.append(note)
        if path is None:
            return None
        try:
            room = load_room(path)
        except PedmeshError as exc:
            self.notes.append(f"the room file {path} could not be read: {exc}")
            return None
        from .geometry.site import is_building

        if is_building(room):  # drawn from its mesh, laid out flat (frames)
            return None
        return room

    @cached_property
    def evacuation(self) -> tuple[np.ndarray, np.ndarray]:
        """The evacuation curve; a note if evacuation.csv is missing (a run that failed
        before its first step), a one-line error naming it if it cannot be read."""
        if not (self.path / "evacuation.csv").exists():
            self.notes.append("evacuation.csv is missing: no evacuation curve")
            return np.zeros(0), np.zeros(0)
        return self.result.evacuation

    @cached_property
    def outflow(self) -> tuple[np.ndarray, np.ndarray, list[str]]:
        return self.result.outflow

    @cached_property
    def exit_passages(self) -> dict[str, list[float]]:
        """Exit times [s] by exit of everyone who left (particle models; exits.csv)."""
        p = self.path / "exits.csv"
        out: dict[str, list[float]] = {}
        if not p.exists():
            return out
        from .run.tables import crossings_from_rows, read_rows

        _, names, times = crossings_from_rows(read_rows(p)[1], p)
        for name, t in zip(names, times):
            out.setdefault(name, []).append(float(t))
        return out

    @cached_property
    def frames(self) -> "_Frames | None":
        fr = _Frames.read(self.path)
        if fr is None:
            self.notes.append("no density frames were saved (density.pvd missing or empty)")
        elif fr.z_span > 0:  # a building: one panel per level (pedmesh.run.layout)
            from .run.layout import building_layout

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
        from .io.vtk import read_pvd_index

        p = self.path / "pedestrians.pvd"
        return read_pvd_index(p) if p.exists() else []

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
        from .io.vtk import read_vtp

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
class _Frames:
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
    def read(cls, run_dir: Path) -> "_Frames | None":
        """The frames of ``run_dir``; None if the run saved none; a one-line error naming
        the file if its index or a frame is not whole or cannot be read."""
        from .io.vtk import check_frames_whole, frame_density, read_pvd_index, read_vtu

        p = run_dir / "density.pvd"
        saved = sorted((run_dir / "density").glob("density_*.vtu")) \
            if (run_dir / "density").is_dir() else []
        if not p.exists():
            if saved:
                raise ReportError(f"{p}: missing, though density/ holds {len(saved)} frames "
                                  "(the index of the frames is lost: rerun the run)")
            return None
        index = read_pvd_index(p)
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
        from .io.vtk import check_same_mesh, frame_density, read_vtu

        pts, tri, pd, cd = read_vtu(self.paths[k])
        own = self.triangles if self.frame_triangles is None else self.frame_triangles
        check_same_mesh(self.paths[k], pts, tri, self._n_points, own)
        rho = frame_density(self.paths[k], pd, cd, own)
        if len(self._cache) < 4096:
            self._cache[k] = rho
        return rho

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


class _Ensemble:
    """An ensemble folder: its members' table, the percentiles, the members' runs."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self.rows = _read_csv_rows(self.path / "ensemble.csv")
        need = {"member", "point", "status"}
        if self.rows and not need <= set(self.rows[0]):
            raise ReportError(f"{self.path / 'ensemble.csv'}: not pedmesh's members table "
                              f"(no column '{sorted(need - set(self.rows[0]))[0]}')")
        self.meta: dict = {}
        jp = self.path / "ensemble.json"
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
        from .run.results import FINISHED_STATUSES

        return [r for r in self.rows if r.get("status") in FINISHED_STATUSES
                and (point is None or r.get("point") == point)]

    @cached_property
    def points(self) -> list[dict]:
        """Per sweep point: values, members, finished, failed and the 5/50/95 percentiles,
        mean and standard deviation of T50/T90/T100 (ensemble.json's, else computed as
        pedmesh.ensembles does)."""
        if self.meta.get("points"):
            return list(self.meta["points"])
        from .ensembles import _stats

        out = []
        for p in sorted({r.get("point", "0") for r in self.rows}, key=lambda x: int(x or 0)):
            grp = [r for r in self.rows if r.get("point", "0") == p]
            done = self.finished(p)
            e = {"point": int(p or 0), "values": {k: grp[0].get(k) for k in self.sweep},
                 "members": len(grp), "finished": len(done),
                 "failed": sum(r.get("status") == "failed" for r in grp)}
            for k in ("t_evac_50", "t_evac_90", "t_evac_100"):
                e[k] = _stats([_float_or_none(r.get(k)) for r in done])
            out.append(e)
        return out

    def point_label(self, entry: Mapping) -> str:
        vals = entry.get("values") or {}
        return ", ".join(f"{k} = {_num(v) if _is_num(v) else v}" for k, v in vals.items()) \
            or "all members"

    def member_dir(self, member: str) -> Path:
        return self.path / "members" / member

    @cached_property
    def typical(self) -> _Run | None:
        """The finished member of the first sweep point whose T90 is nearest the median."""
        pts = self.points
        if not pts:
            return None
        done = self.finished(str(pts[0].get("point", 0)))
        vals = [(_float_or_none(r.get("t_evac_90")), r["member"]) for r in done]
        vals = [(v, m) for v, m in vals if v is not None
                and (self.member_dir(m) / "summary.json").exists()]
        if not vals:
            return None
        med = float(np.median([v for v, _ in vals]))
        _, member = min(vals, key=lambda vm: (abs(vm[0] - med), vm[1]))
        return _Run(self.member_dir(member), label=f"member {member}")


def _load(folders: Sequence[str | Path]) -> tuple[list[_Run], list[dict], list[_Ensemble]]:
    """The runs (a compare folder's in its table's order), the comparison tables and the
    ensembles of ``folders``."""
    runs: list[_Run] = []
    comparisons: list[dict] = []
    ensembles: list[_Ensemble] = []
    if not folders:
        raise ReportError("no folder given")
    for f in folders:
        p = Path(f)
        kind = folder_kind(p)
        if kind == "run":
            runs.append(_Run(p))
        elif kind == "compare":
            rows = _read_csv_rows(p / "comparison.csv")
            labels = [r.get("label") for r in rows if r.get("label")]
            missing = [lab for lab in labels if not (p / lab / "summary.json").is_file()]
            if missing:
                raise ReportError(f"{p}: the run folder of '{missing[0]}' in comparison.csv "
                                  "is missing")
            if not labels:
                raise ReportError(f"{p / 'comparison.csv'}: no models listed")
            runs.extend(_Run(p / lab, label=lab) for lab in labels)
            comparisons.append({"path": p, "rows": rows})
        else:
            ensembles.append(_Ensemble(p))
    # labels that tell the runs apart
    names = [r.label for r in runs]
    if len(set(names)) < len(names):
        for r in runs:
            r.label = f"{r.path.parent.name}/{r.path.name}"
    return runs, comparisons, ensembles


# ------------------------------------------------------------------ words
def _where(room, x: Any, y: Any) -> str:
    """Where (x, y) [m] is, in words: by an exit, in a measurement or start area, or the
    coordinates."""
    if not (_is_num(x) and _is_num(y)):
        return ""
    at = f"at x = {float(x):.1f} m, y = {float(y):.1f} m"
    if room is None:
        return at
    try:
        from shapely.geometry import Point

        pt = Point(float(x), float(y))
        best = min(((e.shape.distance(pt), e.name) for e in room.exits), default=None)
        if best is not None and best[0] <= 3.0:
            return f"in front of exit '{best[1]}' ({at})"
        for a in room.measurement_areas:
            if a.shape.covers(pt):
                return f"in measurement area '{a.name}' ({at})"
        if best is not None and best[0] <= 8.0:
            return f"{best[0]:.0f} m from exit '{best[1]}' ({at})"
    except Exception:
        return at
    return at


def _run_sentences(run: _Run) -> list[str]:
    """The plain-language summary of one run."""
    s = run.s
    n0 = s.get("n_initial")
    out: list[str] = []
    t50, t90, t100 = s.get("t_evac_50"), s.get("t_evac_90"), s.get("t_evac_100")
    who = f"all {_people(n0)} people" if n0 is not None else "everyone"
    if run.status == "finished" and _is_num(t100):
        out.append(f"Everyone out after {_sec(t100)}: {who} left the room; half were out "
                   f"after {_sec(t50)} and 90 % after {_sec(t90)}.")
    else:
        left = s.get("n_evacuated")
        stop = s.get("t_stop")
        what = {"stopped at t_end": "stopped at its end time",
                "interrupted": "was interrupted", "failed": "failed",
                "running": "was still running when this report was made"}.get(
                    run.status, f"has status '{run.status}'")
        times = [f"{name} after {_sec(v)}" for name, v in
                 (("half were out", t50), ("90 %", t90), ("everyone", t100)) if _is_num(v)]
        missed = [name for name, v in (("T50", t50), ("T90", t90), ("T100", t100))
                  if not _is_num(v)]
        if missed:
            miss = ", ".join(missed[:-1]) + (" and " if len(missed) > 1 else "") + missed[-1]
            times.append(f"{miss} not reached")
        tail = "; ".join(times)
        out.append(f"The run {what} at t = {_sec(stop, '?')}, with {_people(left)} of "
                   f"{_people(n0)} people out; {tail}.")
    sf = run.safety
    room = run.room
    if sf is not None:
        pk = sf.get("peak_density") or {}
        if _is_num(pk.get("value")):
            unit = _unit(pk.get("unit") or "/m²")
            where = _where(room, pk.get("x"), pk.get("y"))
            sentence = (f"The densest place was {_num(pk['value'], 3)} {unit} (averaged over "
                        f"1 m²) at t = {_sec(pk.get('t'), '?')}"
                        + (f", {where}" if where else ""))
            ta = sf.get("time_above") or {}
            if _is_num(ta.get("4")):
                sentence += f"; the density was above 4 /m² for {_num(ta['4'], 3)} s"
                if _is_num(ta.get("6")) and ta["6"] > 0:
                    sentence += f" and above 6 /m² for {_num(ta['6'], 3)} s"
            out.append(sentence + ".")
        los = sf.get("level_of_service") or {}
        if los.get("worst"):
            out.append(f"The worst level of service (Fruin, {los.get('scale') or 'walkway'}) "
                       f"was {los['worst']}.")
        cp = sf.get("crowd_pressure")
        if isinstance(cp, dict) and _is_num(cp.get("max")):
            out.append(f"The crowd pressure (the local density times the spread of the "
                       f"people's velocities; Helbing et al. 2007 saw crowd turbulence above "
                       f"about 0.02 /s²) peaked at {_num(cp['max'], 3)} "
                       f"{_unit(cp.get('unit') or '')} at t = {_sec(cp.get('t'), '?')}.")
    else:
        msg = f"The crowd-safety measures are not available for this run ({run.safety_missing})"
        fr = run.frames
        if fr is not None:
            peak, when = fr.peak
            k = int(np.argmax(peak))
            x, y = fr.centroids[k]
            msg += (f"; the highest density in a mesh cell of the saved frames was "
                    f"{peak[k]:.1f} /m² at t = {when[k]:.0f} s, {_where(room, x, y)}")
        out.append(msg + ".")
    ex = [e for e in run.exits() if _is_num(e["people"])]
    total = sum(float(e["people"]) for e in ex)
    if len(ex) > 1 and total > 0:
        parts = [f"'{e['name']}' {_people(e['people'])} ({100 * float(e['people']) / total:.0f} %)"
                 for e in sorted(ex, key=lambda e: -float(e["people"]))]
        out.append("People per exit: " + ", ".join(parts) + ".")
    if s.get("warnings"):
        out.append(f"The run has {len(s['warnings'])} warning(s); see its settings below.")
    return out


# ------------------------------------------------------------------ figures
def _draw_room(ax, room, frames: _Frames | None, *, labels: bool = True, lw: float = 1.0):
    """Walls, obstacles, exits (named); the mesh outline if the room file is missing."""
    from matplotlib.patches import Polygon as MplPolygon

    if room is None:
        if frames is not None and frames.layout is not None:
            frames.layout.draw(ax, lw=lw, labels=labels)
            ax.autoscale()
        elif frames is not None:
            _draw_mesh_outline(ax, frames)
        ax.set_aspect("equal")
        return
    out = np.asarray(room.outline + (room.outline[0],))
    ax.plot(out[:, 0], out[:, 1], "k-", lw=lw)
    for o in room.obstacles:
        ax.add_patch(MplPolygon(np.asarray(o.polygon), closed=True, fc="0.55", ec="k", lw=lw,
                                zorder=3))
    for k, e in enumerate(room.exits):
        pl = np.asarray(room.exit_polyline(k))
        ax.plot(pl[:, 0], pl[:, 1], "-", color="#00a651", lw=4 * lw, solid_capstyle="butt",
                zorder=4)
        if labels:
            mid = pl[len(pl) // 2] if len(pl) > 2 else pl.mean(axis=0)
            ax.annotate(e.name, mid, xytext=(4, 4), textcoords="offset points",
                        color="#006b34", fontsize=8, fontweight="bold", zorder=5)
    ax.set_aspect("equal")


def _draw_mesh_outline(ax, frames: _Frames) -> None:
    tri = frames.triangles
    edges = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
    uniq, count = np.unique(edges, axis=0, return_counts=True)
    b = uniq[count == 1]
    from matplotlib.collections import LineCollection

    ax.add_collection(LineCollection(frames.points[b], colors="k", linewidths=1.0))
    ax.autoscale()


def _aspect(room, frames: _Frames | None) -> float:
    """Height / width of the room's bounding box."""
    if room is not None:
        x0, y0, x1, y1 = room.bounds
    elif frames is not None:
        (x0, y0), (x1, y1) = frames.points.min(axis=0), frames.points.max(axis=0)
    else:
        return 0.6
    return float(np.clip((y1 - y0) / max(x1 - x0, 1e-9), 0.15, 3.0))


def _map_size(aspect: float, rows: int = 1, cols: int = 1, width: float = 8.0, *,
              colorbar: bool = True, extra: float = 0.5) -> tuple[float, float]:
    """A figure size [in] whose panels of the room (``aspect`` = height / width) leave
    little blank: room for the colour bar, the axis labels and the titles."""
    panel_w = (width - (1.3 if colorbar else 0.2)) / cols - 0.75
    h = rows * (panel_w * aspect + 0.85) + extra
    if h > 10.0:  # a tall room: narrower panels
        return _map_size(aspect, rows, cols, width * 10.0 / h, colorbar=colorbar,
                         extra=extra)
    return (width, max(h, 2.2))


def _marker_size(room, frames: _Frames | None, panel_width_in: float) -> float:
    """Scatter marker size [pt^2] of a body of about 0.45 m across on the plot."""
    if room is not None:
        x0, _, x1, _ = room.bounds
    elif frames is not None:
        x0, x1 = frames.points[:, 0].min(), frames.points[:, 0].max()
    else:
        return 4.0
    ppm = panel_width_in * 72.0 / max(x1 - x0, 1e-9)
    return float(np.clip((0.45 * ppm) ** 2, 0.5, 40.0))


def _plan_figure(run: _Run) -> str:
    from matplotlib.patches import Patch, Polygon as MplPolygon
    from matplotlib.lines import Line2D

    plt = _plt()
    room, frames = run.room, run.frames
    fig, ax = plt.subplots(figsize=_map_size(_aspect(room, frames), colorbar=False,
                                             extra=0.9), layout="constrained")
    handles = [Line2D([], [], color="k", lw=1, label="wall"),
               Line2D([], [], color="#00a651", lw=4, label="exit")]
    if room is not None:
        if room.obstacles:
            handles.append(Patch(fc="0.55", ec="k", label="obstacle"))
        walk = room.walkable
        for s in room.start_areas:
            ax.add_patch(MplPolygon(np.asarray(s.polygon), closed=True, fc="#4c72b0",
                                    alpha=0.25, ec="#4c72b0", lw=1))
            try:
                n = len(s.positions(walk))
            except Exception:
                n = s.count
            what = "arrive" if s.arrivals is not None else "at the start"
            c = np.asarray(s.polygon).mean(axis=0)
            ax.text(c[0], c[1], f"{s.name}\n{n} people {what}", ha="center", va="center",
                    fontsize=8, color="#1f3b73")
        if room.start_areas:
            handles.append(Patch(fc="#4c72b0", alpha=0.25, ec="#4c72b0", label="start area"))
        for a in room.measurement_areas:
            ax.add_patch(MplPolygon(np.asarray(a.polygon), closed=True, fill=False,
                                    ec="#8e44ad", ls="--", lw=1.2))
            c = np.asarray(a.polygon).mean(axis=0)
            ax.text(c[0], c[1], a.name, ha="center", va="center", fontsize=7, color="#8e44ad")
        for m in room.measurement_lines:
            pl = np.asarray(m.polyline)
            ax.plot(pl[:, 0], pl[:, 1], ls=":", color="#8e44ad", lw=1.5)
        if room.measurement_areas or room.measurement_lines:
            handles.append(Line2D([], [], color="#8e44ad", ls="--", label="measurement"))
    _draw_room(ax, room, frames)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=5,
              fontsize=8, frameon=False)
    if room is not None:
        title = f"room '{room.name}'"
    elif frames is not None and frames.layout is not None:
        title = (f"building '{run.s.get('room', '?')}': one panel per level; stairs dashed, "
                 "with the level each leads to")
    else:
        title = "mesh outline"
    ax.set_title(title, fontsize=10)
    return _png(fig, 100)


_COLORS = ["#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2",
           "#17becf", "#7f7f7f", "#bcbd22"]


def _evac_figure(runs: Sequence[_Run]) -> str:
    plt = _plt()
    fig, ax = plt.subplots(figsize=(8, 4.2), layout="constrained")
    single = len(runs) == 1
    n_max = 0.0
    for i, r in enumerate(runs):
        t, n = r.evacuation
        c = _COLORS[i % len(_COLORS)]
        if len(t):
            ax.plot(t, n, color=c, lw=1.6, label=r.label if not single else "people out")
        n0 = r.s.get("n_initial") or (n[-1] if len(n) else 0)
        n_max = max(n_max, float(n0 or 0))
        for key, frac, mk in (("t_evac_50", 0.5, "o"), ("t_evac_90", 0.9, "s"),
                              ("t_evac_100", 1.0, "^")):
            tv = r.s.get(key)
            if not _is_num(tv):
                continue
            name = "T" + key.rsplit("_", 1)[1]
            if single:
                ax.axvline(tv, color="0.45", ls=":", lw=1)
                ax.annotate(f"{name} = {tv:.1f} s", (tv, 0.02),
                            xycoords=("data", "axes fraction"),
                            xytext=(-3, 0), textcoords="offset points", rotation=90,
                            ha="right", va="bottom", fontsize=9)
            ax.plot([tv], [frac * float(n0)], mk, color=c, ms=6, mec="k", mew=0.5)
    if n_max:
        ax.axhline(n_max, color="0.75", lw=0.8, ls="--")
    ax.set_xlabel("time t [s]")
    ax.set_ylabel("people out [persons]")
    ax.set_ylim(0, max(n_max * 1.05, 1))
    ax.set_xlim(left=0)
    ax.grid(alpha=0.3)
    if not single:
        from matplotlib.lines import Line2D

        h, _ = ax.get_legend_handles_labels()
        h += [Line2D([], [], ls="", marker=m, color="0.3", label=lab)
              for m, lab in (("o", "T50"), ("s", "T90"), ("^", "T100"))]
        ax.legend(handles=h, fontsize=8, loc="lower right")
    ax.set_title("evacuation: people out over time" + (" (T50, T90, T100 marked)"
                                                       if not single else ""), fontsize=10)
    return _png(fig, 100)


def _flow_figure(runs: Sequence[_Run]) -> str | None:
    plt = _plt()
    exits: list[str] = []
    for r in runs:
        for n in r.outflow[2]:
            if n not in exits:
                exits.append(n)
    if not exits:
        return None
    single = len(runs) == 1
    panels = [None] if single or len(exits) > 6 else exits
    fig, axes = plt.subplots(len(panels), 1, figsize=(8, 2.6 + 1.8 * (len(panels) - 1)),
                             layout="constrained", squeeze=False, sharex=True)
    for pi, which in enumerate(panels):
        ax = axes[pi, 0]
        for i, r in enumerate(runs):
            t, f, names = r.outflow
            if len(t) < 2:
                continue
            if single:
                for k, n in enumerate(names):
                    ax.plot(t, _moving_mean(t, f[:, k]), lw=1.4, label=f"exit '{n}'",
                            color=_COLORS[k % len(_COLORS)])
            elif which is None:
                ax.plot(t, _moving_mean(t, f.sum(axis=1)), lw=1.4, label=r.label,
                        color=_COLORS[i % len(_COLORS)])
            elif which in names:
                ax.plot(t, _moving_mean(t, f[:, names.index(which)]), lw=1.4, label=r.label,
                        color=_COLORS[i % len(_COLORS)])
        ax.set_ylabel("flow [ped/s]")
        ax.grid(alpha=0.3)
        ax.set_ylim(bottom=0)
        ax.set_xlim(left=0)
        title = ("all exits" if which is None and not single else
                 f"exit '{which}'" if which is not None else "")
        if title:
            ax.set_title(title, fontsize=9)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=8, loc="upper right")
    axes[-1, 0].set_xlabel("time t [s]")
    fig.suptitle("flow through the exits (mean over 2 s)", fontsize=10)
    return _png(fig, 100)


def _map_grid(n: int) -> tuple[int, int]:
    cols = 1 if n == 1 else 2 if n <= 4 else 3
    return math.ceil(n / cols), cols


def _safety_maps(r: "_Run", fr) -> tuple[np.ndarray, np.ndarray, bool]:
    """Each cell's peak density [ped/m^2] and worst level of service (0-5) of a run: the
    crowd-safety measures' own maps (``safety.vtu``, the density on 1 m^2) where the run
    wrote them on the frames' mesh, else the peaks of the saved frames; and which."""
    path = r.path / "safety.vtu"
    if path.is_file():
        try:
            from .io.vtk import read_vtu

            _, tri, _, cells = read_vtu(path, cell_arrays=("peak_density", "worst_los"))
            if len(tri) == len(fr.triangles):
                return (np.asarray(cells["peak_density"], float),
                        np.asarray(cells["worst_los"]).astype(int), True)
        except Exception:  # (a damaged file: fall back to the frames, and say so)
            r.notes.append(f"{path.name} could not be read; the maps use the saved frames")
    peak, _ = fr.peak
    return peak, _los_index(peak, _los_scale(r.safety)), False


def _maps_figure(runs: Sequence[_Run], what: str) -> str | None:
    """Peak density (``what='peak'``) or worst level of service (``'los'``) per cell,
    one panel per run."""
    from matplotlib.colors import BoundaryNorm, ListedColormap

    plt = _plt()
    have = [r for r in runs if r.frames is not None]
    if not have:
        return None
    rows, cols = _map_grid(len(have))
    w = 8.0 if cols == 1 else 11.0
    fig, axes = plt.subplots(rows, cols, layout="constrained", squeeze=False,
                             figsize=_map_size(_aspect(have[0].room, have[0].frames), rows,
                                               cols, w))
    mappable = None
    for i, ax in enumerate(axes.ravel()):
        if i >= len(have):
            ax.set_axis_off()
            continue
        r = have[i]
        fr = r.frames
        peak, worst, measured = _safety_maps(r, fr)
        if what == "peak":
            mappable = ax.tripcolor(fr.points[:, 0], fr.points[:, 1], fr.triangles,
                                    facecolors=peak, vmin=0, vmax=_VMAX, cmap="magma_r",
                                    shading="flat")
        else:
            idx = worst
            cmap = ListedColormap(_LOS_COLORS)
            mappable = ax.tripcolor(fr.points[:, 0], fr.points[:, 1], fr.triangles,
                                    facecolors=idx.astype(float), cmap=cmap,
                                    norm=BoundaryNorm(np.arange(-0.5, 6.5), 6), shading="flat")
        _draw_room(ax, r.room, fr, labels=len(have) == 1)
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        if len(have) > 1:
            ax.set_title(r.label, fontsize=9)
    if what == "peak":
        cb = fig.colorbar(mappable, ax=axes, shrink=0.85, extend="max")
        cb.set_label("peak density [ped/m²]" + (" on 1 m²" if measured else ""))
        fig.suptitle("largest density of each mesh cell over the run"
                     + (" (safety.vtu: on 1 m²)" if measured else " (the saved frames)"),
                     fontsize=10)
    else:
        cb = fig.colorbar(mappable, ax=axes, shrink=0.85, ticks=range(6))
        cb.ax.set_yticklabels(list(_LOS))
        scale = _los_scale(have[0].safety)
        cb.set_label(f"worst level of service (Fruin, {scale})")
        fig.suptitle("worst level of service of each mesh cell over the run", fontsize=10)
    return _png(fig, 100)


def _snapshot_times(runs: Sequence[_Run], n: int) -> list[float]:
    """Up to ``n`` times [s] of saved frames, evenly spread from the start to the last
    frame of the longest run."""
    fr = [r.frames for r in runs if r.frames is not None]
    if not fr:
        return []
    longest = max(fr, key=lambda f: f.times[-1])
    times = longest.times
    if len(times) <= n:
        return [float(t) for t in times]
    pick = np.unique(np.round(np.linspace(0, len(times) - 1, n)).astype(int))
    return [float(times[k]) for k in pick]


def _snapshots(runs: Sequence[_Run], n: int) -> tuple[list[str], list[str]]:
    """(images, labels) of the density at the snapshot times, the runs side by side."""
    plt = _plt()
    have = [r for r in runs if r.frames is not None]
    times = _snapshot_times(have, n)
    if not times:
        return [], []
    rows, cols = _map_grid(len(have))
    w = 8.0 if cols == 1 else 11.0
    size = _map_size(_aspect(have[0].room, have[0].frames), rows, cols, w)
    fig, axes = plt.subplots(rows, cols, figsize=size, layout="constrained", squeeze=False)
    dot = _marker_size(have[0].room, have[0].frames, (size[0] - 1.3) / cols - 0.75)
    arts = []
    for i, ax in enumerate(axes.ravel()):
        if i >= len(have):
            ax.set_axis_off()
            continue
        r = have[i]
        fr = r.frames
        tp = ax.tripcolor(fr.points[:, 0], fr.points[:, 1], fr.triangles,
                          facecolors=np.zeros(len(fr.triangles)), vmin=0, vmax=_VMAX,
                          cmap="magma_r", shading="flat")
        _draw_room(ax, r.room, fr, labels=len(have) == 1)
        sc = ax.scatter(np.zeros(0), np.zeros(0), s=dot, c="#1f77b4", lw=0, zorder=6) \
            if r.ped_frames else None
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        arts.append((r, ax, tp, sc))
    cb = fig.colorbar(arts[0][2], ax=axes, shrink=0.85, extend="max")
    cb.set_label("density [ped/m²]")
    for _, ax, _, _ in arts:
        ax.set_title("t = 0000 s", fontsize=9)
    fig.canvas.draw()  # lay the figure out once; the frames only change colours and titles
    fig.set_layout_engine("none")
    images, labels = [], []
    for t in times:
        for r, ax, tp, sc in arts:
            fr = r.frames
            k = int(np.argmin(np.abs(fr.times - t)))
            ended = t > fr.times[-1] + 1e-6
            rho = None if ended else fr.density(k)
            tp.set_array(np.zeros(len(fr.triangles)) if rho is None else rho)
            name = f"{r.label}: " if len(have) > 1 else ""
            if ended:
                ax.set_title(f"{name}run ended at {fr.times[-1]:.0f} s", fontsize=9)
            else:
                ax.set_title(f"{name}t = {fr.times[k]:.0f} s", fontsize=9)
            if sc is not None:
                pos = None if ended else r.positions_at(float(fr.times[k]))
                sc.set_offsets(np.zeros((0, 2)) if pos is None else pos)
        images.append(_png_keep(fig, 100))
        labels.append(f"t = {t:.0f} s")
    plt.close(fig)
    return images, labels


def _bands_figure(ens: _Ensemble) -> str | None:
    from .run.results import RunResult

    plt = _plt()
    fig, ax = plt.subplots(figsize=(8, 4.2), layout="constrained")
    drawn = False
    for i, pt in enumerate(ens.points):
        curves = []
        for r in ens.finished(str(pt.get("point", 0))):
            try:
                curves.append(RunResult.load(ens.member_dir(r["member"])).evacuation)
            except (PedmeshError, OSError, ValueError, IndexError):
                continue
        curves = [c for c in curves if len(c[0])]
        if not curves:
            continue
        t_max = max(float(t[-1]) for t, _ in curves)
        grid = np.linspace(0.0, t_max, 600)
        n = np.array([np.interp(grid, t, e) for t, e in curves])
        lo, med, hi = np.percentile(n, [5, 50, 95], axis=0)
        c = _COLORS[i % len(_COLORS)]
        ax.plot(grid, med, color=c, lw=1.6,
                label=f"{ens.point_label(pt)}: median of {len(curves)} runs")
        ax.fill_between(grid, lo, hi, color=c, alpha=0.25, lw=0, label="5-95 % band")
        drawn = True
    if not drawn:
        plt.close(fig)
        return None
    ax.set_xlabel("time t [s]")
    ax.set_ylabel("people out [persons]")
    ax.set_xlim(left=0)
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="lower right")
    ax.set_title("evacuation over the members: median and 5-95 % band", fontsize=10)
    return _png(fig, 100)


def _spread_figure(ens: _Ensemble) -> str | None:
    """T50/T90/T100 of every finished member, per sweep point."""
    plt = _plt()
    pts = ens.points
    fig, ax = plt.subplots(figsize=(8, 1.2 + 0.9 * max(len(pts), 1)), layout="constrained")
    drawn = False
    rng = np.random.default_rng(0)
    for i, pt in enumerate(pts):
        done = ens.finished(str(pt.get("point", 0)))
        for j, (key, c) in enumerate((("t_evac_50", "#1f77b4"), ("t_evac_90", "#d62728"),
                                      ("t_evac_100", "#2ca02c"))):
            v = np.array([x for x in (_float_or_none(r.get(key)) for r in done)
                          if x is not None])
            if not len(v):
                continue
            y = i + (j - 1) * 0.22 + rng.uniform(-0.06, 0.06, len(v))
            ax.plot(v, y, "o", ms=3.5, color=c, alpha=0.7,
                    label=f"T{key.rsplit('_', 1)[1]}" if i == 0 else None)
            drawn = True
    if not drawn:
        plt.close(fig)
        return None
    ax.set_yticks(range(len(pts)))
    ax.set_yticklabels([ens.point_label(p) for p in pts], fontsize=8)
    ax.set_xlabel("time [s]")
    ax.grid(alpha=0.3, axis="x")
    ax.legend(fontsize=8, loc="best")
    ax.set_title("evacuation times of every member", fontsize=10)
    return _png(fig, 100)


# ------------------------------------------------------------------ HTML pieces
def _key_numbers(runs: Sequence[_Run]) -> str:
    """T50/T90/T100 and the counts per run (one row each), with the exact values of
    summary.json in each cell's title."""
    rows = []
    for r in runs:
        s = r.s
        cells = [_esc(r.label), _esc(r.s.get("model")), _esc(r.status),
                 _people(s.get("n_initial")), _people(s.get("n_evacuated"))]
        for k in ("t_evac_50", "t_evac_90", "t_evac_100"):
            v = s.get(k)
            cells.append(f'<span class="num" title="summary.json: {_attr(_exact(v))}">'
                         f"{_sec(v)}</span>")
        pk = ((r.safety or {}).get("peak_density") or {}).get("value")
        if _is_num(pk):
            cells.append(f"{_num(pk, 3)}")
        elif r.frames is not None:
            cells.append(f"{r.frames.peak[0].max():.2f} (cell)")
        else:
            cells.append("–")
        wall = s.get("wall_time_s")
        cells.append(f"{wall:.1f} s" if _is_num(wall) else "–")
        rows.append(cells)
    table = _table(["run", "model", "status", "people", "out", "T50", "T90", "T100",
                    "peak density [ped/m²]", "computing time"], rows, "numbers")
    return table


def _comparison_table(comp: Mapping) -> str:
    rows = comp["rows"]
    keys = [k for k in rows[0] if k not in ("label", "model", "t_evac_50", "t_evac_90",
                                             "t_evac_100", "steps", "wall_time_s")]
    if not keys:
        return ""
    head = ["model"] + [_esc(k) for k in keys]
    body = [[_esc(r.get("label"))] + [_num(_float_or_none(r.get(k)), 3)
                                       if _float_or_none(r.get(k)) is not None
                                       else _esc(r.get(k) or "–") for k in keys] for r in rows]
    return ("<p>Distances from the first model, as <code>comparison.csv</code> of "
            f"<code>{_esc(comp['path'])}</code> has them (the mean |N<sub>out</sub>(t) - "
            "N<sub>ref</sub>(t)|/N of the evacuation curves, the T90 difference [s], the "
            "relative difference of the outflow curves and the L1 distance of the density "
            "fields / N at the times in the column names):</p>" + _table(head, body))


def _safety_rows(sf: Mapping) -> list[tuple[str, str]]:
    """(measure, value) rows of a run's safety section."""
    rows: list[tuple[str, str]] = []
    pk = sf.get("peak_density") or {}
    if pk:
        unit = _unit(pk.get("unit") or "/m²")
        where = ""
        if _is_num(pk.get("x")) and _is_num(pk.get("y")):
            where = f" at x = {_num(pk['x'])} m, y = {_num(pk['y'])} m"
        over = (f' (<span title="{html.escape(_unit(pk["over"]))}">averaged over 1 m²</span>)'
                if pk.get("over") is not None else "")
        if pk.get("level") is not None:  # a building's: in that level's plan
            where = f" on level '{_esc(pk['level'])}'" + where
        rows.append((f"peak density{over}",
                     f"{_num(pk.get('value'))} {_esc(unit)} at t = {_num(pk.get('t'))} s"
                     + where))
    unit = _unit(sf.get("area_time_unit") or "m² s")
    for k in _THRESHOLDS:
        v = (sf.get("area_time_above") or {}).get(k)
        if v is not None or sf.get("area_time_above"):
            rows.append((f"area-time above {k} /m²", f"{_num(v)} {_esc(unit)}"))
    for k in _THRESHOLDS:
        v = (sf.get("time_above") or {}).get(k)
        if v is not None or sf.get("time_above"):
            rows.append((f"time above {k} /m²", f"{_num(v)} s"))
    los = sf.get("level_of_service") or {}
    if los:
        counts = los.get("cells_by_worst") or {}
        text = f"worst {_esc(los.get('worst', '–'))}"
        if counts:
            text += "; cells by their worst level: " + ", ".join(
                f"{_esc(k)}: {_num(v)}" for k, v in counts.items())
        rows.append((f"level of service (Fruin, {_esc(los.get('scale') or 'walkway')})", text))
    if "crowd_pressure" in sf:
        cp = sf.get("crowd_pressure")
        if isinstance(cp, dict):
            where = ""
            if _is_num(cp.get("x")) and _is_num(cp.get("y")):
                where = f" at x = {_num(cp['x'])} m, y = {_num(cp['y'])} m"
            rows.append(('<span title="the local density times the variance of the people\'s '
                         'velocities (Helbing, Johansson &amp; Al-Abideen 2007); crowd '
                         'turbulence was seen above about 0.02 /s²">crowd pressure ρ Var(v) '
                         '(largest)</span>',
                         f"{_num(cp.get('max'))} {_esc(_unit(cp.get('unit') or ''))} at t = "
                         f"{_num(cp.get('t'))} s{where}"))
        elif "levels" in sf:
            rows.append(("crowd pressure ρ Var(v)", "not computed for buildings yet"))
        else:
            rows.append(("crowd pressure ρ Var(v)", "not applicable (no particle velocities)"))
    for name, e in (sf.get("exits") or {}).items():
        if isinstance(e, dict):
            rows.append((f"exit '{_esc(name)}'",
                         f"{_num(e.get('people'))} people, first at {_num(e.get('first'))} s, "
                         f"last at {_num(e.get('last'))} s"))
    ct = sf.get("clear_times") or {}
    for group, what in (("start_areas", "start area"), ("measurement_areas",
                                                          "measurement area")):
        for name, v in (ct.get(group) or {}).items():
            rows.append((f"{what} '{_esc(name)}' clear after",
                         f"{_num(v)} s" if v is not None else "not cleared"))
    return rows


def _safety_table(runs: Sequence[_Run]) -> str:
    if all(r.safety is None for r in runs):
        why = "; ".join(dict.fromkeys((f"{_esc(r.label)}: " if len(runs) > 1 else "")
                                      + _esc(r.safety_missing) for r in runs))
        return ('<p class="na">Crowd-safety measures: <b>not available</b> (' + why
                + "). The maps above are computed from the saved density frames.</p>")
    per = [dict(_safety_rows(r.safety)) if r.safety is not None else None for r in runs]
    keys: list[str] = []
    for d in per:
        for k in d or {}:
            if k not in keys:
                keys.append(k)
    if len(runs) == 1:
        return _table(["measure", "value"], [(k, per[0][k]) for k in keys], "safety")
    body = [[k] + [(d.get(k, "–") if d is not None else
                    f'not available ({_esc(r.safety_missing)})') for d, r in zip(per, runs)]
            for k in keys]
    return _table(["measure"] + [_esc(r.label) for r in runs], body, "safety")


def _exit_table(runs: Sequence[_Run]) -> str:
    rows = []
    for r in runs:
        ex = r.exits()
        total = sum(float(e["people"]) for e in ex if _is_num(e["people"]))
        for e in ex:
            share = (f"{100 * float(e['people']) / total:.0f} %"
                     if _is_num(e["people"]) and total > 0 else "–")
            row = [f"'{_esc(e['name'])}'", _people(e["people"]), share,
                   _sec(e["first"], "–"), _sec(e["last"], "–")]
            rows.append(([_esc(r.label)] if len(runs) > 1 else []) + row)
    head = (["run"] if len(runs) > 1 else []) + ["exit", "people", "share",
                                                  "first passage", "last passage"]
    return _table(head, rows)


def _level_safety_table(runs: Sequence[_Run]) -> str:
    """Per level of a building run: peak density, area-time above the thresholds, worst
    level of service ("" if no run has levels)."""
    rows = []
    for r in runs:
        levels = (r.safety or {}).get("levels")
        if not isinstance(levels, dict):
            continue
        for name, sf in levels.items():
            if not isinstance(sf, dict):
                continue
            pk = sf.get("peak_density") or {}
            at = sf.get("area_time_above") or {}
            row = [f"'{_esc(name)}'",
                   f"{_num(pk.get('value'), 3)} /m² at {_sec(pk.get('t'), '?')}"
                   if _is_num(pk.get("value")) else "–"]
            row += [_num(at.get(k), 3) for k in _THRESHOLDS]
            row.append(_esc((sf.get("level_of_service") or {}).get("worst", "–")))
            rows.append(([_esc(r.label)] if len(runs) > 1 else []) + row)
    if not rows:
        return ""
    head = (["run"] if len(runs) > 1 else []) + (
        ["level", "peak density (1 m²)"] + [f"area-time above {k} /m² [m² s]"
                                            for k in _THRESHOLDS] + ["worst level of service"])
    return ("<h3>Per level</h3>" + _table(head, rows, "safety")
            + "<p>The same measures on each level alone (positions in the level's own plan); "
            "the stairs' peak densities are in the stair table.</p>")


def _stair_table(runs: Sequence[_Run]) -> str:
    """Per stair of a building run: people (down / up), first and last use, peak flow and
    peak density ("" if no run has stairs)."""
    rows = []
    for r in runs:
        stairs = r.summary.get("stairs")
        if not isinstance(stairs, dict):
            continue
        for name, u in stairs.items():
            if not isinstance(u, dict):
                continue
            flow = u.get("peak_flow")
            rho = u.get("peak_density")
            row = [f"'{_esc(name)}'", _people(u.get("people")),
                   f"{_people(u.get('down'))} / {_people(u.get('up'))}",
                   _sec(u.get("first"), "–"), _sec(u.get("last"), "–"),
                   (f"{flow:.2f} /s at {_sec(u.get('peak_flow_t'), '?')}"
                    if _is_num(flow) and flow > 0 else "–"),
                   (f"{rho:.2f} /m² at {_sec(u.get('peak_density_t'), '?')}"
                    if _is_num(rho) and rho > 0 else "–")]
            rows.append(([_esc(r.label)] if len(runs) > 1 else []) + row)
    if not rows:
        return ""
    head = (["run"] if len(runs) > 1 else []) + [
        "stair", "people", "down / up", "first on", "last on",
        "peak flow (10 s)", "peak density"]
    return _table(head, rows)


def _slider(uid: str, images: list[str], labels: list[str], alt: str) -> str:
    if not images:
        return '<p class="na">No density frames were saved, so there are no snapshots.</p>'
    data = json.dumps({"images": images, "labels": labels}).replace("</", "<\\/")
    n = len(images)
    return (f'<div class="snapshots" id="{uid}">'
            f'<div class="controls"><button type="button" class="play" '
            f'aria-label="play">&#9654; play</button>'
            f'<input type="range" class="slider" min="0" max="{n - 1}" value="0" step="1" '
            f'aria-label="time of the snapshot">'
            f'<span class="snap-label">{_esc(labels[0])}</span></div>'
            f'<img class="snap" src="{images[0]}" alt="{_attr(alt)}">'
            f'<script type="application/json" class="snap-data">{data}</script></div>')


def _settings_block(run: _Run) -> str:
    s = run.s
    st = run.result.settings
    prov = [
        ("model", _esc(s.get("model"))),
        ("status", _esc(run.status) + (f" ({_esc(s.get('error'))})" if s.get("error") else "")),
        ("parameter preset", _esc(st.get("preset") or "–")),
        ("overrides", _esc(", ".join(f"{k}={v}" for k, v in (st.get("overrides") or {}).items())
                           or "none")),
        ("model options", _esc(", ".join(f"{k}={v}" for k, v in
                                         (st.get("model_options") or {}).items()) or "none")),
        ("room file", _esc(s.get("geometry") or "–")),
        ("room name", _esc(s.get("room") or "–")),
        ("room file SHA-256", f"<code>{_esc(st.get('room_sha256') or '–')}</code>"),
        ("end time t_end", f"{_num(s.get('t_end'))} s"),
        ("mesh", _esc(", ".join(f"{k} = {v}" for k, v in (s.get("mesh") or {}).items()))),
        ("pedmesh version", _esc(s.get("pedmesh_version") or st.get("pedmesh_version"))),
        ("time steps", _esc(s.get("steps", "–"))),
        ("computing time", f"{s['wall_time_s']:.1f} s" if _is_num(s.get("wall_time_s"))
         else "–"),
        ("run folder", f"<code>{_esc(run.path)}</code>"),
    ]
    from .parameters import PARAMETERS

    units = s.get("units") or {}
    prows = []
    for k, v in (s.get("parameters") or {}).items():
        decl = PARAMETERS.get(k)
        unit = units.get(k, decl.unit if decl is not None else "")
        prows.append([f"<code>{_esc(k)}</code>", _esc(_exact(v) if not isinstance(v, str)
                                                      else v),
                      _esc(unit or "–"), _esc(decl.description if decl is not None else "")])
    warn = list(s.get("warnings") or [])
    notes = list(dict.fromkeys(run.notes))
    wl = "".join(f"<li>{_esc(w)}</li>" for w in warn) or "<li class='none'>none</li>"
    nl = "".join(f"<li>{_esc(w)}</li>" for w in notes)
    scalars = [(k, v) for k, v in s.items() if not isinstance(v, (dict, list))]
    return (
        _table(["setting", "value"], prov, "settings")
        + f"<h4>Warnings of the run</h4><ul class='warnings'>{wl}</ul>"
        + (f"<h4>Notes of this report</h4><ul class='warnings'>{nl}</ul>" if nl else "")
        + "<details><summary>Every parameter with its unit "
        f"({len(prows)})</summary>"
        + _table(["parameter", "value", "unit", "meaning"], prows, "params") + "</details>"
        + "<details><summary>The numbers of summary.json as recorded</summary>"
        + _table(["key", "value"], [(f"<code>{_esc(k)}</code>", f"<code>{_esc(_exact(v))}</code>")
                                    for k, v in scalars], "raw") + "</details>")


# ------------------------------------------------------------------ page
_CSS = """
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,Helvetica,Arial,sans-serif;
 margin:0;color:#1d1d1f;background:#fafafa;line-height:1.45}
main{max-width:1150px;margin:0 auto;padding:1.2em 1.5em 3em;background:#fff}
h1{font-size:1.6em;margin:.2em 0 .1em}h2{border-bottom:2px solid #e3e3e3;padding-bottom:.2em;
 margin-top:1.8em}h3{margin-top:1.4em}.sub{color:#666;margin-top:0}
.summary{background:#eef5fb;border-left:5px solid #1f77b4;padding:.6em 1em;font-size:1.08em}
.summary p{margin:.35em 0}
table{border-collapse:collapse;margin:.6em 0;font-size:.92em}
th,td{border:1px solid #ddd;padding:.25em .6em;text-align:left;vertical-align:top}
th{background:#f2f2f2}td .num{font-variant-numeric:tabular-nums}
img.plot,img.snap{max-width:100%;height:auto;display:block;margin:.5em 0}
.controls{display:flex;align-items:center;gap:.8em;margin:.4em 0}
.controls input{flex:1}.snap-label{min-width:6em;font-weight:600}
nav a{margin-right:1em}.na{color:#8a4b00;background:#fff6e5;padding:.4em .8em}
ul.warnings li{color:#8a4b00}ul.warnings li.none{color:#1d1d1f}
details{margin:.5em 0}summary{cursor:pointer;color:#1f5f99}
code{font-size:.9em}footer{color:#777;font-size:.85em;margin-top:3em}
"""

_JS = """
(function () {
  function setUp(box) {
    var data = JSON.parse(box.querySelector('script.snap-data').textContent);
    var img = box.querySelector('img.snap');
    var input = box.querySelector('input.slider');
    var label = box.querySelector('.snap-label');
    var button = box.querySelector('button.play');
    var timer = null;
    function show(i) {
      img.src = data.images[i];
      label.textContent = data.labels[i];
      input.value = String(i);
    }
    input.addEventListener('input', function () { show(parseInt(input.value, 10)); });
    button.addEventListener('click', function () {
      if (timer !== null) {
        clearInterval(timer); timer = null; button.innerHTML = '&#9654; play'; return;
      }
      button.innerHTML = '&#10074;&#10074; pause';
      timer = setInterval(function () {
        var i = parseInt(input.value, 10) + 1;
        if (i >= data.images.length) { i = 0; }
        show(i);
      }, 400);
    });
  }
  document.querySelectorAll('.snapshots').forEach(setUp);
})();
"""


class _Page:
    def __init__(self, title: str) -> None:
        self.title = title
        self.parts: list[str] = []
        self.nav: list[tuple[str, str]] = []
        self._uid = 0

    def uid(self, prefix: str) -> str:
        self._uid += 1
        return f"{prefix}-{self._uid}"

    def section(self, anchor: str, title: str, body: str, level: int = 2) -> None:
        if level == 2:
            self.nav.append((anchor, title))
        self.parts.append(f'<section id="{anchor}"><h{level}>{_esc(title)}</h{level}>'
                          f"{body}</section>")

    def add(self, text: str) -> None:
        self.parts.append(text)

    def html(self, subtitle: str, summary: str) -> str:
        nav = " ".join(f'<a href="#{a}">{_esc(t)}</a>' for a, t in self.nav)
        stamp = _dt.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z")
        return (
            "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            '<meta name="viewport" content="width=device-width, initial-scale=1">'
            '<link rel="icon" href="data:,">'
            f"<title>{_esc(self.title)}</title><style>{_CSS}</style></head><body><main>"
            f"<h1>{_esc(self.title)}</h1><p class=\"sub\">{subtitle}</p>"
            f'<div class="summary" id="summary">{summary}</div>'
            f"<nav>{nav}</nav>" + "".join(self.parts)
            + f"<footer>Made by pedmesh {_esc(__version__)} (<code>pedmesh report</code>) on "
            f"{_esc(stamp)}. The page is self-contained: it loads nothing from anywhere."
            f"</footer></main><script>{_JS}</script></body></html>\n")


def _runs_sections(page: _Page, runs: Sequence[_Run], comparisons: Sequence[Mapping],
                   frames: int, *, prefix: str = "", level: int = 2) -> None:
    """The sections of a group of runs shown side by side (one run: its own report);
    ``level``: of their headings (2: in the page's navigation)."""
    single = len(runs) == 1

    def section(anchor: str, title: str, body: str) -> None:
        page.section(prefix + anchor, title, body, level)

    body = (_key_numbers(runs)
            + "<p>T50, T90 and T100: the times at which half, 90 % and all of the people "
            "were out, as the runs recorded them (hover for the exact value). Peak density: "
            "the safety measure (over 1 m² or as stated) where the run has it, else the "
            "largest cell value of the saved frames.</p>")
    for comp in comparisons:
        body += _comparison_table(comp)
    section("numbers", "Key numbers", body)
    seen: dict = {}
    figs = ""
    for r in runs:
        key = ((r.s.get("settings") or {}).get("room_sha256"), r.s.get("geometry"))
        if key in seen:
            continue
        seen[key] = r
        figs += _img(_plan_figure(r), f"plan of {r.s.get('room') or r.label}")
    building = any(r.frames is not None and r.frames.layout is not None for r in seen.values())
    section("plan", "Room plan", figs
            + "<p>Walls in black, exits in green (named), obstacles grey, the start areas "
            "blue with their people, measurement areas and lines purple.</p>"
            + ("<p>A building: one panel per level, in its own plan (stacked floors apart); "
               "each stair where it is, dashed, on both levels it joins, labelled with the "
               "level it leads to (its cells drawn on its bottom level's panel); the maps "
               "below are drawn the same way.</p>" if building else ""))
    section("evacuation", "Evacuation", _img(_evac_figure(runs),
                                             "evacuation curve: people out against time"))
    flow = _flow_figure(runs)
    section("exits", "Exit usage", _exit_table(runs)
                 + (_img(flow, "flow through the exits against time") if flow else "")
                 + ("<p>People per exit as the run counted them (a continuum model's "
                    "integrated outflow, rounded to whole people); first and last passage "
                    "where known.</p>" if any(r.s.get("model") != "sfm" for r in runs) else
                    "<p>People per exit as the run counted them; first and last passage.</p>"))
    stairs = _stair_table(runs)
    if stairs:
        section("stairs", "Stair use", stairs + (
            "<p>Per stair: the people who stepped onto it (down from its top level, up "
            "from its bottom level), when the first stepped on and the last was on it, the "
            "most people stepping on within 10 s (per second), and the most people on it "
            "at once over its area. A continuum model's people are its inflow through "
            "the stair's edges, integrated: an estimate, within 7 % in our tests.</p>"))
    maps = ""
    peak = _maps_figure(runs, "peak")
    if peak:
        maps += "<h3>Peak density</h3>" + _img(peak, "peak density map")
    los = _maps_figure(runs, "los")
    if los:
        scale = _los_scale(runs[0].safety)
        edges = FRUIN_LEVELS[scale]
        bounds = ", ".join(f"{a} up to {e:.2f}" for a, e in zip(_LOS, edges)) + \
            f", F above {edges[-1]:.2f} ped/m²"
        maps += ("<h3>Level of service</h3>" + _img(los, "level of service map")
                 + f"<p>Fruin's levels of service for {scale}s by density: {bounds} "
                 "(Fruin 1971, his areas per person in m²), of each cell's peak density: "
                 "the worst level the cell had.</p>")
    if not maps:
        maps = '<p class="na">No density frames were saved, so there are no maps.</p>'
    maps += "<h3>Crowd-safety measures</h3>" + _safety_table(runs) + _level_safety_table(runs)
    section("density", "Density and safety", maps)
    images, labels = _snapshots(runs, frames)
    section("snapshots", "Density over time",
                 _slider(page.uid("snap"), images, labels, "density snapshot")
                 + ("<p>Move the slider (or press play) to step through the saved frames. "
                    + ("Dots: the pedestrians. " if any(r.ped_frames for r in runs) else "")
                    + f"Colours saturate at {_VMAX:g} ped/m².</p>" if images else ""))
    body = ""
    for r in runs:
        inner = _settings_block(r)
        body += (inner if single else
                 f"<details><summary><b>{_esc(r.label)}</b></summary>{inner}</details>")
    section("settings", "Settings and provenance", body)


def _ensemble_sections(page: _Page, ens: _Ensemble, frames: int, idx: int) -> str:
    """The sections of an ensemble; returns its summary sentence."""
    pre = f"ens{idx}-"
    pts = ens.points
    rows = []
    for pt in pts:
        row = [_esc(ens.point_label(pt)), f"{pt.get('finished', 0)} of {pt.get('members', 0)}"]
        for k in ("t_evac_50", "t_evac_90", "t_evac_100"):
            st = pt.get(k) or {}
            row.append(" / ".join(_sec(st.get(q), "–") for q in ("p5", "p50", "p95")))
            mean = _sec(st.get("mean"), "–")
            row.append(f"{mean} ± {st['std']:.1f} s" if _is_num(st.get("std")) else mean)
        rows.append(row)
    table = _table(["sweep point", "finished", "T50 p5 / p50 / p95", "T50 mean ± sd",
                    "T90 p5 / p50 / p95", "T90 mean ± sd", "T100 p5 / p50 / p95",
                    "T100 mean ± sd"], rows, "numbers")
    meta = ens.meta
    desc = (f"{_esc(meta.get('model', '?'))} on {_esc(meta.get('geometry', '?'))}, "
            f"{_esc(meta.get('members', '?'))} members per point, seed {_esc(meta.get('seed'))}"
            if meta else "no ensemble.json (percentiles computed from ensemble.csv)")
    body = (f"<p>{desc}. Percentiles over the finished members "
            "(5 %, median, 95 %), as ensemble.json has them.</p>" + table)
    bands = _bands_figure(ens)
    if bands:
        body += (_img(bands, "evacuation bands") + "<p>The median evacuation curve of each "
                 "sweep point and its 5-95 % band: at each time, 90 % of the members had "
                 "between the band's lower and upper number of people out.</p>")
    spread = _spread_figure(ens)
    if spread:
        body += _img(spread, "evacuation times of the members")
    # the members' safety measures, where they have them
    srows = []
    for r in ens.rows:
        d = ens.member_dir(r["member"])
        try:
            s = json.loads((d / "summary.json").read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        sf = s.get("safety")
        if isinstance(sf, dict):
            pk = (sf.get("peak_density") or {}).get("value")
            ta = (sf.get("time_above") or {}).get("4")
            srows.append((pk, ta))
    if srows:
        pk = [v for v, _ in srows if _is_num(v)]
        ta = [v for _, v in srows if _is_num(v)]

        def pct(v):
            if not v:
                return "–"
            a, b, c = np.percentile(v, [5, 50, 95])
            return f"{_num(a, 3)} / {_num(b, 3)} / {_num(c, 3)}"

        body += ("<h3>Crowd-safety measures over the members</h3>"
                 + _table(["measure", "p5 / p50 / p95"],
                          [("peak density [ped/m²]", pct(pk)), ("time above 4 /m² [s]",
                                                                pct(ta))]))
    else:
        body += ('<p class="na">Crowd-safety measures over the members: not available (the '
                 "members were made before pedmesh recorded them).</p>")
    cols = list(ens.rows[0]) if ens.rows else []
    mrows = [[_esc(r.get(c, "")) for c in cols] for r in ens.rows]
    body += ("<details><summary>Every member (ensemble.csv)</summary>"
             + _table([_esc(c) for c in cols], mrows, "members") + "</details>")
    page.section(f"{pre}ensemble", f"Ensemble {ens.label}", body)
    typ = ens.typical
    sentence = ""
    if pts:
        st = pts[0]
        t100 = st.get("t_evac_100") or {}
        t90 = st.get("t_evac_90") or {}
        sentence = (f"Ensemble {_esc(ens.label)} ({_esc(ens.point_label(st))}, "
                    f"{st.get('finished', 0)} finished members): everyone out after "
                    f"{_sec(t100.get('p50'))} in the median (5-95 %: {_sec(t100.get('p5'))} "
                    f"to {_sec(t100.get('p95'))}); 90 % out after {_sec(t90.get('p50'))} "
                    f"(5-95 %: {_sec(t90.get('p5'))} to {_sec(t90.get('p95'))}).")
        if len(pts) > 1:
            sentence += f" {len(pts)} sweep points; see the table."
    if typ is not None:
        page.section(f"{pre}typical", f"A typical member: {typ.label}",
                     "<p>The member of the first sweep point whose T90 is nearest the median, "
                     "shown in full.</p>")
        _runs_sections(page, [typ], [], frames, prefix=f"{pre}typ-", level=3)
    return sentence


def build_report(folders: Sequence[str | Path], *, frames: int = DEFAULT_FRAMES,
                 title: str | None = None) -> str:
    """The HTML page of the run, compare and ensemble ``folders`` (see the module
    docstring); ``frames``: the most density snapshots on the slider."""
    if isinstance(frames, bool) or not isinstance(frames, (int, np.integer)) \
            or not 1 <= frames <= MAX_FRAMES:
        raise ReportError(f"frames must be a whole number from 1 to {MAX_FRAMES}, got "
                          f"{frames!r}")
    runs, comparisons, ensembles = _load(folders)
    if title is None:
        rooms = list(dict.fromkeys(
            [str(r.s.get("room") or r.path.name) for r in runs]
            + [str(e.typical.s.get("room")) if e.typical is not None and e.typical.s.get("room")
               else Path(str(e.meta.get("geometry") or e.label)).stem for e in ensembles]))
        what = (", ".join(r.label for r in runs) if len(runs) <= 4
                else f"{len(runs)} runs") if runs else ""
        if ensembles:
            what = ", ".join(filter(None, [what] + [f"ensemble {e.label}" for e in ensembles]))
        title = f"Evacuation report: {', '.join(rooms)} ({what})"
    page = _Page(title)
    summary_parts: list[str] = []
    if runs:
        if len(runs) == 1:
            summary_parts += [f"<p>{_esc(x)}</p>" for x in _run_sentences(runs[0])]
        else:
            for r in runs:
                summary_parts.append(f"<p><b>{_esc(r.label)}</b>: "
                                     + _esc(" ".join(_run_sentences(r)[:2])) + "</p>")
        _runs_sections(page, runs, comparisons, frames)
    for i, ens in enumerate(ensembles):
        sentence = _ensemble_sections(page, ens, frames, i)
        if sentence:
            summary_parts.append(f"<p>{sentence}</p>")
    srcs = ", ".join(f"<code>{_esc(f)}</code>" for f in folders)
    return page.html(f"From {srcs}.", "".join(summary_parts))


def write_report(folders: Sequence[str | Path], out: str | Path, *,
                 frames: int = DEFAULT_FRAMES, title: str | None = None) -> Path:
    """Write the report of ``folders`` (run, compare or ensemble folders) to the HTML file
    ``out`` and return its path (see :func:`build_report`)."""
    from .io.files import write_whole
    from .run.output import check_writable, write_error

    out = Path(out)
    if out.suffix.lower() not in (".html", ".htm"):
        raise ReportError(f"{out}: the report is an HTML page; use a .html suffix")
    check_writable(out)  # (before the minutes of reading and drawing)
    text = build_report(folders, frames=frames, title=title)
    try:
        return write_whole(out, text)
    except OSError as exc:
        raise write_error(out, exc) from None

