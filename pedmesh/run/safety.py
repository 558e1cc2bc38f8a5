"""The crowd-safety measures of a run (:mod:`pedmesh.analysis.safety` applied to its
output): the numbers every run records under ``"safety"`` in summary.json, and the
per-cell maps of ``safety.vtu``.

:func:`safety_measures` reads a run folder (density.pvd, pedestrians.pvd, exits.csv,
outflow.csv, summary.json); :func:`safety_from_memory` does the same for a run kept in
memory (:class:`~pedmesh.run.memory.MemoryWriter`). The shape of the record is
:data:`SAFETY_KEYS`; docs/safety.md explains each number.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterable

import numpy as np

from ..analysis import safety as S
from ..errors import PedmeshError
from ..parameters import DEFAULTS as D
from ..geometry.site import is_building
from ..io import run_folder as F
from ..io.run_folder import good_summary, json_safe
from .results import RunResult

__all__ = ["safety_measures", "safety_from_memory", "write_safety_vtu", "KeptDensity",
           "SAFETY_VTU", "SAFETY_KEYS", "LOS_SCALE"]

#: the file of the per-cell safety maps in a run folder
SAFETY_VTU = F.SAFETY_VTU

#: the keys of summary.json's "safety" record (or {"error": "..."} if it failed)
SAFETY_KEYS = ("peak_density", "area_time_above", "area_time_unit", "time_above",
               "level_of_service", "crowd_pressure", "exits", "clear_times")

#: the level-of-service scale of the summary (the queuing one is in safety.vtu)
LOS_SCALE = "walkway"

#: [ped] an area counts as clear once fewer than this many people are in it (the same
#: half person as a continuum run's ``empty_below`` and the exits' first/last passage)
CLEAR_BELOW = 0.5


@dataclass
class _RunData:
    """What the measures need of a run, whether read from files or kept in memory."""

    t: np.ndarray  # (F,) frame times [s]
    points: np.ndarray  # (n, 2) [m]
    triangles: np.ndarray  # (m, 3)
    density: np.ndarray  # (F, m) cell densities [ped/m^2]
    particle: bool  # the density is a particle model's kernel density at the vertices
    pedestrians: Callable[..., Iterable[tuple]] | None  # (t, positions, velocities) frames
    exit_names: list[str]
    crossings: tuple[np.ndarray, np.ndarray, np.ndarray] | None  # ids, exits, times
    outflow: tuple[np.ndarray, np.ndarray]  # t [s], flows (k, exits) [ped/s]
    R: float  # [m] the kernel width of the particle model's density


class KeptDensity:
    """The cell densities ``rho`` of a run's density frames kept in memory as the run
    writes them (a continuum's; the run driver keeps them), so that :func:`safety_measures`
    need not read every frame back from its file at the end of the run (125 frames of
    Example 2: 0.1 s). The frames' files hold the very same numbers (float64 and float32
    arrays are written as they are); the kept ones are only used where they are the frames
    density.pvd lists, at the same times in the same order (else, e.g. after a write
    failed, the files are read). Nothing is kept of frames without a cell field ``rho``
    (a particle model's), of frames on different meshes, or beyond ``max_bytes``."""

    #: [bytes] the most kept (beyond it the files are read, as without it)
    MAX_BYTES = 1 << 28

    def __init__(self, max_bytes: int | None = None) -> None:
        self.max_bytes = self.MAX_BYTES if max_bytes is None else int(max_bytes)
        self.mesh = None
        #: (t [s], rho (m,)) of each frame; None once a frame could not be kept
        self.frames: list[tuple[float, np.ndarray]] | None = []
        self._bytes = 0

    def add(self, t: float, mesh, cell_data) -> None:
        """Keep frame ``t`` [s] on ``mesh`` (the arguments of a writer's ``density_frame``;
        a copy of its ``rho``)."""
        if self.frames is None:
            return
        rho = (cell_data or {}).get("rho")
        rho = rho if isinstance(rho, np.ndarray) else None
        if (rho is None or rho.ndim != 1 or rho.dtype not in (np.float64, np.float32)
                or (self.mesh is not None and mesh is not self.mesh)
                or len(rho) != getattr(mesh, "n_triangles", -1)
                or self._bytes + rho.nbytes > self.max_bytes):
            self.frames = None  # (from here on the files are read)
            return
        self.mesh = mesh
        self.frames.append((float(t), rho.copy()))
        self._bytes += rho.nbytes

    def matching(self, frames) -> list[np.ndarray] | None:
        """The kept densities of ``frames`` ((t [s], file) of density.pvd), if they are
        those kept (the same times in the same order), else None."""
        kept = self.frames
        if not kept or len(kept) != len(frames) or any(
                a != b for (a, _), (b, _) in zip(kept, frames)):
            return None
        return [rho for _, rho in kept]


def _areas_centroids(points: np.ndarray, triangles: np.ndarray):
    p = points[triangles]
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    areas = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    return areas, p.mean(axis=1)


def _velocities(data: dict, n: int, dims: int = 2) -> np.ndarray:
    v = np.asarray(data.get("velocity", np.zeros((n, dims))), float)
    return v[:, :dims] if v.ndim == 2 and len(v) == n and v.shape[1] >= dims \
        else np.zeros((n, dims))


def _cell_density(particle: bool, triangles: np.ndarray, field: np.ndarray) -> np.ndarray:
    if particle:  # the kernel density at the vertices, averaged to the cells
        return np.asarray(field, float)[triangles].mean(axis=1)
    return np.asarray(field, float)


def _from_result(res, mesh, R: float, kept: KeptDensity | None = None) -> _RunData:
    """What the measures need of a run (a :class:`~pedmesh.run.results.RunResult`, in
    memory or read from its folder frame by frame; its density frames' ``rho`` from
    ``kept`` where it holds them, see :class:`KeptDensity`)."""
    from ..io.vtk import read_vtp, read_vtu

    where = res.path if res.path is not None else "the run"
    if res.path is not None and not res.file(F.DENSITY_PVD).exists():
        raise PedmeshError(f"{where}: no {F.DENSITY_PVD}")
    frames = res.density_frames
    if not frames:
        raise PedmeshError(f"{where}: no density frames" if res.path is None else
                           f"{res.file(F.DENSITY_PVD)} lists no frames")
    rhos = kept.matching(frames) if kept is not None and res.path is not None else None
    ts, dens = [], []
    points = triangles = None
    particle = False
    for k, (t, f) in enumerate(frames):
        if rhos is not None:  # (the numbers of the frame's file, kept as it was written)
            pd, cd = {}, {"rho": rhos[k]}
            pts, tri = np.asarray(kept.mesh.points), np.asarray(kept.mesh.triangles)
        elif f is None:  # (in memory: the fields as the model gave them, on the run's mesh)
            _, pd, cd = res.density[k]
            pts, tri = np.asarray(mesh.points), np.asarray(mesh.triangles)
        else:
            pts, tri, pd, cd = read_vtu(f, point_arrays=("density",), cell_arrays=("rho",))
        if k == 0:
            points, triangles = pts[:, :2], tri
            particle = "rho" not in cd
        if particle and "density" not in pd:
            raise PedmeshError(f"{f or where}: neither a cell field 'rho' nor a point field "
                               "'density'")
        ts.append(t)
        dens.append(_cell_density(particle, triangles, pd["density"] if particle
                                  else cd["rho"]))
    if mesh is not None:
        if mesh.n_triangles != len(triangles):
            raise PedmeshError(f"{where}: the frames have {len(triangles)} cells, the mesh "
                               f"{mesh.n_triangles}")
        points, triangles = np.asarray(mesh.points)[:, :2], np.asarray(mesh.triangles)
    peds = None
    if particle and res.pedestrian_frames:
        pframes = res.pedestrian_frames

        def peds(three_d: bool = False):
            """(t, positions, velocities) of each pedestrian frame: in the plan, or with
            ``three_d`` as written (a building's: (k, 3) positions and velocities along
            the surface, and the piece each stands on, as a fourth item)."""
            names = ("velocity", "piece") if three_d else ("velocity",)
            for k, (t, f) in enumerate(pframes):
                if f is None:
                    _, pts, data = res.pedestrians[k]
                else:
                    pts, data = read_vtp(f, arrays=names)
                if three_d:
                    piece = data.get("piece")
                    yield (t, np.asarray(pts, float), _velocities(data, len(pts), 3),
                           None if piece is None else np.asarray(piece, np.int64))
                else:
                    yield t, np.asarray(pts)[:, :2], _velocities(data, len(pts))

    ot, of, names = res.outflow
    crossings = res.crossings if particle and res.has_table(F.EXITS) else None
    return _RunData(np.array(ts, float), points, triangles, np.array(dens), particle, peds,
                    list(names), crossings, (ot, of), R)


def _room_of(summary: dict, d: Path | None):
    """The room a run was made from, if its file is still there unchanged."""
    from .output import file_sha256

    geometry = summary.get("geometry")
    want = (summary.get("settings") or {}).get("room_sha256")
    if not geometry or not want:
        return None
    for p in ([Path(geometry)] + ([d / geometry] if d is not None else [])):
        if p.is_file() and file_sha256(p) == want:
            from ..io import load_room

            return load_room(p)
    return None


def _building_view(data: _RunData, surface) -> tuple[_RunData, np.ndarray, list, np.ndarray]:
    """``data`` of a building run seen on its atlas (:mod:`pedmesh.mesh.atlas`: every
    level and stair flat, apart from each other, so that a 1 m^2 disk never reaches from one
    floor to the one above), its pedestrian frames too (written in 3-D with the piece each
    stands on: each carried into its piece's chart, as :func:`_atlas_frames`); and the
    piece of each cell, the pieces and their atlas offsets [m]."""
    import dataclasses

    from ..mesh.atlas import build_atlas

    atlas = build_atlas(surface)
    peds = None
    if data.pedestrians is not None:
        frames = data.pedestrians

        def peds():
            return _atlas_frames(frames(three_d=True), surface.pieces, atlas.offset)

    view = dataclasses.replace(data, points=np.asarray(atlas.open.points)[:, :2],
                               triangles=np.asarray(atlas.open.triangles), pedestrians=peds)
    return view, np.asarray(atlas.glued.piece), list(surface.pieces), atlas.offset


def _atlas_frames(frames, pieces, offset: np.ndarray):
    """The pedestrian frames of a building (t, 3-D positions, 3-D velocities, piece) on its
    atlas: each position in its piece's chart plus the piece's offset, each velocity in the
    chart's axes (an isometry: speeds and their spread are the surface's). A frame without
    the pieces (written before they were) is skipped."""
    axes = np.stack([p.axes for p in pieces])  # (p, 2, 3)
    origin = np.stack([p.origin for p in pieces])  # (p, 3)
    for t, pts, vel, piece in frames:
        if piece is None or len(piece) != len(pts):
            continue
        a = axes[piece]
        rel = pts - origin[piece]
        xy = np.einsum("kj,kij->ki", rel, a) + offset[piece]
        uv = np.einsum("kj,kij->ki", vel, a)
        yield t, xy, uv


def _density_record(t, local, areas, centroids, over: str) -> tuple[dict, object, np.ndarray]:
    """The density part of the record (peak, area and time above the thresholds, level of
    service) of the cells' 1 m^2 densities ``local`` (F, m); and the peak and the worst
    level of service per cell."""
    peak = S.peak_density(t=t, density=local, centroids=centroids)
    thresholds = S.DENSITY_THRESHOLDS
    area_time = S.area_time_above(t=t, density=local, areas=areas, thresholds=thresholds)
    time_top = S.time_above(t=t, density=local, thresholds=thresholds)
    worst = S.worst_level_of_service(density=local, scale=LOS_SCALE)
    counts = np.bincount(worst, minlength=6)
    return {
        "peak_density": {"value": peak.value, "unit": "ped/m^2", "t": peak.t, "x": peak.x,
                         "y": peak.y, "over": over},
        "area_time_above": {f"{k:g}": v for k, v in area_time.items()},
        "area_time_unit": "m^2 s",
        "time_above": {f"{k:g}": v for k, v in time_top.items()},
        "level_of_service": {
            "scale": f"Fruin {LOS_SCALE}",
            "worst": S.los_letter(int(worst.max())) if len(worst) else "A",
            "cells_by_worst": {S.LOS_LETTERS[k]: int(counts[k]) for k in range(6)}},
    }, peak, worst


def _compute(data: _RunData, room, n_initial, mesh=None) -> tuple[dict, dict[str, np.ndarray]]:
    """The summary record and the per-cell fields of safety.vtu. A building's (``mesh``
    its surface) are measured on its atlas, with a record per level under ``"levels"``
    (positions in the level's plan)."""
    from ..geometry.site import is_building, site_levels

    building = is_building(room) and mesh is not None
    if building:
        data, piece, pieces, offset = _building_view(data, mesh)
    areas, centroids = _areas_centroids(data.points, data.triangles)
    t = data.t
    local = S.local_density(density=data.density, centroids=centroids, areas=areas)
    r = S.ONE_SQUARE_METRE_RADIUS
    over = (f"1 m^2 disk average (cells with centroids within {r:.3f} m) of the "
            + (f"kernel density (R = {data.R:g} m) at the vertices averaged to the cells"
               if data.particle else "cell densities"))
    thresholds = S.DENSITY_THRESHOLDS
    dens_record, peak, worst = _density_record(t, local, areas, centroids, over)
    worst_q = S.worst_level_of_service(density=local, scale="queuing")
    w = S.frame_weights(t=t)
    fields: dict[str, np.ndarray] = {
        "peak_density": peak.per_cell,
        "peak_density_time": peak.t_per_cell,
        "worst_los": worst.astype(np.int32),
        "worst_los_queuing": worst_q.astype(np.int32),
    }
    for th in thresholds:
        fields[f"time_above_{th:g}"] = w @ (local > th)

    pressure = None
    if data.pedestrians is not None:
        pp = S.peak_crowd_pressure(frames=data.pedestrians(), points=centroids, R=data.R)
        fields["max_crowd_pressure"] = pp.per_point
        pressure = {"max": pp.max, "unit": "1/s^2", "t": pp.t, "x": pp.x, "y": pp.y}

    names = data.exit_names
    if data.crossings is not None:
        _, ex, et = data.crossings
        usage = S.exit_usage_from_crossings(exits=ex, times=et, names=names)
    else:
        usage = S.exit_usage_from_flow(t=data.outflow[0], flow=data.outflow[1], names=names)
    exits = {n: {"people": u.people, "first": u.first, "last": u.last}
             for n, u in usage.items()}

    start_areas: dict[str, float | None] = {}
    measurement: dict[str, float | None] = {}
    if room is not None:
        levels = site_levels(room)
        pairs = [(lv, a, r) for lv, _, r in levels for a in r.start_areas]
        plain = [a.name for _, a, _ in pairs]
        # (a building's start areas by name, with their level where a name repeats)
        names_sa = [n if plain.count(n) == 1 else f"{lv}: {n}"
                    for (lv, _, _), n in zip(pairs, plain)]
        start_areas = dict.fromkeys(names_sa)
        if data.crossings is not None and n_initial is not None:
            counts_sa = [len(a.positions(r.walkable)) for _, a, r in pairs]
            if sum(counts_sa) == int(n_initial):
                ids, _, et = data.crossings
                times = np.full(int(n_initial), np.nan)
                ok = (ids >= 0) & (ids < len(times))
                times[ids[ok]] = et[ok]
                start_areas = dict(zip(names_sa, S.group_clear_times(exit_times=times,
                                                                     counts=counts_sa)))
        for lv, _, r in levels:
            shift = offset[[p.name for p in pieces].index(lv)] if building else (0.0, 0.0)
            for m in r.measurement_areas:
                import shapely.affinity

                shape = shapely.affinity.translate(m.shape, *shift)
                frac = S.cell_fractions(points=data.points, triangles=data.triangles,
                                        polygon=shape)
                content = S.area_content(density=data.density, areas=areas, fractions=frac)
                measurement[m.name] = S.clear_time(t=t, content=content, below=CLEAR_BELOW)

    record = {
        **dens_record,
        "crowd_pressure": pressure,
        "exits": exits,
        "clear_times": {"start_areas": start_areas, "measurement_areas": measurement},
    }
    if building:  # the whole building's peak in its level's plan, and a record per level
        names = [p.name for p in pieces]
        record["peak_density"]["level"] = None
        for where in (record["peak_density"], pressure):  # (the crowd pressure's alike)
            if where is not None and where.get("x") is not None:
                _to_level_plan(where, centroids, piece, offset, names)
        record["levels"] = {}
        for j, p in enumerate(pieces):
            if p.kind != "level":
                continue
            cells = np.flatnonzero(piece == j)
            sub_rec, _, _ = _density_record(t, local[:, cells], areas[cells],
                                            centroids[cells] - offset[j], over)
            record["levels"][p.name] = sub_rec
    return record, fields


def _to_level_plan(where: dict, centroids, piece, offset, names) -> None:
    """A building's record of a place on its atlas (``x``, ``y`` [m]) given as the level
    (or stair) of the nearest cell, ``level``, and the place in that one's plan."""
    k = int(np.argmin(np.hypot(centroids[:, 0] - where["x"], centroids[:, 1] - where["y"])))
    where["level"] = names[piece[k]]
    where["x"] -= float(offset[piece[k]][0])
    where["y"] -= float(offset[piece[k]][1])


def write_safety_vtu(path: str | Path, *, points: np.ndarray, triangles: np.ndarray,
                     fields: dict[str, np.ndarray]) -> Path:
    """Write the per-cell safety maps to a ``.vtu`` (one frame, cell fields) ParaView
    opens next to density.pvd."""
    from types import SimpleNamespace

    from ..io.vtk import write_cells_vtu

    pts = np.asarray(points, float)
    pts = pts if pts.shape[1] == 3 else pts[:, :2]  # (a building's surface in 3-D)
    tri = np.asarray(triangles)
    mesh = SimpleNamespace(points=pts, triangles=tri, n_points=len(pts),
                           n_triangles=len(tri))
    return write_cells_vtu(path, mesh, fields)


def safety_measures(run_dir: str | Path, room=None, mesh=None, *,
                    n_initial: float | None = None, write_fields: bool = False,
                    kept: KeptDensity | None = None) -> dict:
    """The crowd-safety measures of the run in ``run_dir`` (see :data:`SAFETY_KEYS` and
    docs/safety.md), as recorded in summary.json under ``"safety"``.

    ``room``: the run's :class:`~pedmesh.geometry.Room` (default: its room file, if it is
    still there with the hash the run recorded), for the start and measurement areas;
    ``mesh``: its mesh (default: the frames' own); ``n_initial``: the number of
    pedestrians at the start (default: summary.json's, unless the run was given its own
    start positions), to tell the start areas' people apart (their ids follow the start
    areas' order; without it their clear times are None). ``write_fields``: also write
    the per-cell maps to ``safety.vtu`` in the folder; ``kept``: the frames' densities as
    the run wrote them (:class:`KeptDensity`, the run driver's: the same numbers without
    reading the frames' files). Raises :class:`~pedmesh.errors.PedmeshError` if the folder
    has no density frames.
    """
    d = Path(run_dir)
    summary = good_summary(d) or {}
    if room is None:
        room = _room_of(summary, d)
    if n_initial is None and "positions" not in (
            (summary.get("settings") or {}).get("model_options") or {}):
        n_initial = summary.get("n_initial")  # (not for a run given its own positions)
    R = float((summary.get("parameters") or {}).get("R") or D["R"])
    data = _from_result(RunResult(d, summary), mesh, R, kept)
    record, fields = _compute(data, room, n_initial, mesh)
    if write_fields:  # (a building's on its surface in 3-D, over its density frames)
        on = mesh if mesh is not None and is_building(room) else data
        write_safety_vtu(d / F.SAFETY_VTU, points=on.points, triangles=on.triangles,
                         fields=fields)
    return json_safe(record)


def safety_from_memory(writer, room, mesh, *, n_initial: float | None = None,
                       R: float | None = None) -> dict:
    """:func:`safety_measures` of a run kept in memory (a
    :class:`~pedmesh.run.memory.MemoryWriter`) on ``mesh``."""
    if R is None:
        R = float((writer.header.get("parameters") or {}).get("R") or D["R"])
    record, _ = _compute(_from_result(writer.result(), mesh, R), room, n_initial, mesh)
    return json_safe(record)
