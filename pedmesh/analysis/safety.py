"""Crowd-safety measures: peak density on 1 m^2, area-time above a density, Fruin's levels
of service, crowd pressure, exit usage and times to clear.

Pure, keyword-only functions on arrays (like PedPy's API); :func:`pedmesh.run.safety.
safety_measures` applies them to a run folder. Densities are in ped/m^2, times in s,
positions in m, velocities in m/s. The page ``docs/safety.md`` explains each measure with
its source.

Frames are snapshots at times ``t`` (1 s apart in a pedmesh run). A sum over time gives
each frame the time halfway to its neighbours (:func:`frame_weights`, the trapezoidal
rule of a quantity that is held between frames), so that frames at 0, 1, ..., 10 s cover
10 s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterable, Sequence

import numpy as np

from ..parameters import DEFAULTS as D

__all__ = [
    "FT2", "LOS_LETTERS", "ServiceLevel", "FRUIN_WALKWAY", "FRUIN_QUEUING", "FRUIN_SCALES",
    "DENSITY_THRESHOLDS", "ONE_SQUARE_METRE_RADIUS",
    "frame_weights", "disk_average_matrix", "local_density", "PeakDensity", "peak_density",
    "area_time_above", "time_above", "level_of_service", "worst_level_of_service",
    "los_letter", "CrowdPressure", "crowd_pressure", "PeakPressure", "peak_crowd_pressure",
    "ExitUsage", "exit_usage_from_crossings", "exit_usage_from_flow", "group_clear_times",
    "cell_fractions", "area_content", "clear_time",
]

#: square metres in a square foot (Fruin's tables are in ft^2 per person)
FT2 = 0.09290304

#: the letters of the levels of service, best (0) to worst (5)
LOS_LETTERS = "ABCDEF"

#: [ped/m^2] the densities of the area-time measures
DENSITY_THRESHOLDS = (2.0, 4.0, 6.0)

#: [m] the radius of a disk of 1 m^2
ONE_SQUARE_METRE_RADIUS = 1.0 / math.sqrt(math.pi)


@dataclass(frozen=True)
class ServiceLevel:
    """One of Fruin's levels of service: it holds where the space per person is at least
    ``min_space_ft2`` [ft^2/ped] (and below the next better level's)."""

    letter: str
    min_space_ft2: float
    description: str

    @property
    def min_space_m2(self) -> float:
        """[m^2/ped]"""
        return self.min_space_ft2 * FT2

    @property
    def max_density(self) -> float:
        """[ped/m^2] the highest density of the level (inf for F)."""
        return 1.0 / self.min_space_m2 if self.min_space_ft2 > 0 else math.inf


#: Fruin's levels of service for walkways (J. J. Fruin, *Pedestrian Planning and Design*,
#: Metropolitan Association of Urban Designers and Environmental Planners, New York, 1971):
#: average area per person [ft^2/ped]
FRUIN_WALKWAY: tuple[ServiceLevel, ...] = (
    ServiceLevel("A", 35.0, "free choice of speed and path; conflicts unlikely"),
    ServiceLevel("B", 25.0, "normal speeds; minor conflicts in reverse and cross flows"),
    ServiceLevel("C", 15.0, "speed and passing somewhat restricted; conflicts in reverse "
                            "and cross flows"),
    ServiceLevel("D", 10.0, "most people's normal speed restricted; passing difficult"),
    ServiceLevel("E", 5.0, "nearly everyone's speed restricted, shuffling at the low end; "
                           "flow near capacity with stoppages"),
    ServiceLevel("F", 0.0, "shuffling with frequent unavoidable contact; flow sporadic, at "
                           "times at a standstill"),
)

#: Fruin's levels of service for queuing (standing) areas (Fruin 1971): average area per
#: person [ft^2/ped]
FRUIN_QUEUING: tuple[ServiceLevel, ...] = (
    ServiceLevel("A", 13.0, "standing and moving through the queue freely"),
    ServiceLevel("B", 10.0, "standing; moving through partly restricted"),
    ServiceLevel("C", 7.0, "standing; moving through disturbs others"),
    ServiceLevel("D", 3.0, "standing without touching; moving through severely restricted"),
    ServiceLevel("E", 2.0, "standing in unavoidable contact; no moving through"),
    ServiceLevel("F", 0.0, "everyone in close contact; no movement possible"),
)

#: the scales by name
FRUIN_SCALES: dict[str, tuple[ServiceLevel, ...]] = {"walkway": FRUIN_WALKWAY,
                                                     "queuing": FRUIN_QUEUING}


def frame_weights(*, t: np.ndarray) -> np.ndarray:
    """The time [s] each frame stands for: half the interval to the previous frame plus
    half that to the next (the first and last frames get half an interval), so the weights
    add up to ``t[-1] - t[0]``. One frame gets zero."""
    t = np.asarray(t, float).ravel()
    w = np.zeros(len(t))
    if len(t) > 1:
        d = np.diff(t)
        w[:-1] += 0.5 * d
        w[1:] += 0.5 * d
    return w


def disk_average_matrix(*, centroids: np.ndarray, areas: np.ndarray, area: float = 1.0):
    """The averaging over a disk of ``area`` [m^2] around each cell, as a sparse (m, m)
    matrix: row i weights the cells whose centroids lie within the disk around cell i's
    centroid by their areas [m^2] and adds up to 1. Cell i itself is always in, so where
    cells are larger than the disk a cell keeps its own value (which is then an average
    over more than ``area``)."""
    from scipy.sparse import csr_matrix
    from scipy.spatial import cKDTree

    c = np.asarray(centroids, float).reshape(-1, 2)
    a = np.asarray(areas, float).ravel()
    m = len(c)
    pairs = cKDTree(c).query_pairs(math.sqrt(area / math.pi), output_type="ndarray") \
        if m else np.zeros((0, 2), np.int64)
    rows = np.concatenate([np.arange(m), pairs[:, 0], pairs[:, 1]])
    cols = np.concatenate([np.arange(m), pairs[:, 1], pairs[:, 0]])
    w = a[cols]
    sums = np.bincount(rows, weights=w, minlength=m)
    return csr_matrix((w / sums[rows], (rows, cols)), shape=(m, m))


def local_density(*, density: np.ndarray, centroids: np.ndarray, areas: np.ndarray,
                  area: float = 1.0) -> np.ndarray:
    """Cell densities [ped/m^2], (m,) or (frames, m), averaged over a disk of ``area``
    [m^2] around each cell (:func:`disk_average_matrix`): the density "on 1 m^2"."""
    d = np.asarray(density, float)
    W = disk_average_matrix(centroids=centroids, areas=areas, area=area)
    return (W @ d.T).T if d.ndim == 2 else W @ d


@dataclass(frozen=True)
class PeakDensity:
    """The highest density over time and space, where and when, and each cell's peak."""

    value: float  #: [ped/m^2]
    t: float  #: [s] the frame of the peak
    x: float  #: [m] the centroid of the cell of the peak
    y: float  #: [m]
    cell: int  #: the cell of the peak
    per_cell: np.ndarray  #: (m,) each cell's highest density [ped/m^2]
    t_per_cell: np.ndarray  #: (m,) the frame time [s] of each cell's peak (NaN: always 0)


def peak_density(*, t: np.ndarray, density: np.ndarray, centroids: np.ndarray) -> PeakDensity:
    """The peak of ``density`` (frames, m) [ped/m^2] over frames and cells (e.g. the
    1 m^2 density of :func:`local_density`), with its time ``t`` [s] and the cell's
    centroid [m]; the first frame and cell where it is reached."""
    d = np.atleast_2d(np.asarray(density, float))
    t = np.asarray(t, float).ravel()
    c = np.asarray(centroids, float).reshape(-1, 2)
    if d.size == 0:
        return PeakDensity(0.0, float(t[0]) if len(t) else 0.0, math.nan, math.nan, -1,
                           np.zeros(d.shape[1]), np.full(d.shape[1], np.nan))
    k = np.argmax(d, axis=0)
    per_cell = d[k, np.arange(d.shape[1])]
    f, i = np.unravel_index(int(np.argmax(d)), d.shape)
    return PeakDensity(float(d[f, i]), float(t[f]), float(c[i, 0]), float(c[i, 1]), int(i),
                       per_cell, np.where(per_cell > 0, t[k], np.nan))


def _thresholds(thresholds: Iterable[float]) -> list[float]:
    return [float(v) for v in thresholds]


def area_time_above(*, t: np.ndarray, density: np.ndarray, areas: np.ndarray,
                    thresholds: Sequence[float] = DENSITY_THRESHOLDS) -> dict[float, float]:
    """Area-time above each threshold [m^2 s]: the sum over frames of the area [m^2] of the
    cells whose density (frames, m) [ped/m^2] is above the threshold, times the frame's
    time (:func:`frame_weights`). A crowd above 4 /m^2 on 20 m^2 for 10 s gives 200."""
    d = np.atleast_2d(np.asarray(density, float))
    w = frame_weights(t=t)
    a = np.asarray(areas, float).ravel()
    return {th: float(w @ ((d > th) @ a)) for th in _thresholds(thresholds)}


def time_above(*, t: np.ndarray, density: np.ndarray,
               thresholds: Sequence[float] = DENSITY_THRESHOLDS) -> dict[float, float]:
    """The time [s] during which some cell's density (frames, m) [ped/m^2] is above each
    threshold (the frames where one is, with their :func:`frame_weights`)."""
    d = np.atleast_2d(np.asarray(density, float))
    w = frame_weights(t=t)
    top = d.max(axis=1) if d.shape[1] else np.zeros(len(d))
    return {th: float(w @ (top > th)) for th in _thresholds(thresholds)}


def _scale(scale: str | Sequence[ServiceLevel]) -> tuple[ServiceLevel, ...]:
    if isinstance(scale, str):
        try:
            return FRUIN_SCALES[scale]
        except KeyError:
            raise ValueError(f"unknown level-of-service scale '{scale}' (known: "
                             f"{', '.join(FRUIN_SCALES)})") from None
    return tuple(scale)


def level_of_service(*, density: np.ndarray,
                     scale: str | Sequence[ServiceLevel] = "walkway") -> np.ndarray:
    """Fruin's level of service, 0 (A) to 5 (F), of each density [ped/m^2] (any shape):
    the space per person 1/density [m^2/ped] against the scale's lower bounds (``walkway``
    or ``queuing``, :data:`FRUIN_WALKWAY`, :data:`FRUIN_QUEUING`). A space exactly on a
    bound belongs to the better level; zero density is A."""
    levels = _scale(scale)
    limits = np.array([lv.max_density for lv in levels[:-1]])  # ascending densities
    d = np.nan_to_num(np.asarray(density, float), nan=0.0)
    return np.searchsorted(limits, d, side="left").astype(np.int8)


def worst_level_of_service(*, density: np.ndarray,
                           scale: str | Sequence[ServiceLevel] = "walkway") -> np.ndarray:
    """Each cell's worst level of service (0 A to 5 F) over the frames of ``density``
    (frames, m) [ped/m^2]."""
    d = np.atleast_2d(np.asarray(density, float))
    if d.shape[0] == 0:
        return np.zeros(d.shape[1], np.int8)
    return level_of_service(density=d.max(axis=0), scale=scale)


def los_letter(level: int) -> str:
    """The letter of a level of service 0..5."""
    return LOS_LETTERS[int(level)]


@dataclass(frozen=True)
class CrowdPressure:
    """The fields of :func:`crowd_pressure` at the evaluation points."""

    density: np.ndarray  #: (p,) local density rho [ped/m^2]
    velocity: np.ndarray  #: (p, 2) local velocity V [m/s]
    variance: np.ndarray  #: (p,) local velocity variance [m^2/s^2]
    pressure: np.ndarray  #: (p,) rho times the variance [1/s^2]


def crowd_pressure(*, positions: np.ndarray, velocities: np.ndarray, points: np.ndarray,
                   R: float = D['R'], cutoff: float = D['density_cutoff']) -> CrowdPressure:
    """Crowd pressure ``P = rho Var(V)`` [1/s^2] at ``points`` (Helbing, Johansson &
    Al-Abideen, Phys. Rev. E 75, 046109 (2007)), from pedestrian positions [m] and
    velocities [m/s] with the paper's Gaussian weight
    ``f(d) = exp(-d^2 / R^2) / (pi R^2)`` (truncated at ``cutoff * R``):

    * local density ``rho(r) = sum_j f(|r_j - r|)`` [ped/m^2];
    * local velocity ``V(r) = sum_j v_j f_j / sum_j f_j`` [m/s];
    * local velocity variance ``Var(r) = sum_j |v_j - V(r)|^2 f_j / sum_j f_j``
      [m^2/s^2]: the weighted spread of the velocities around V within the kernel, at
      this instant (the paper estimates the variance from the fluctuations of the local
      velocity in video; pedmesh's frames are 1 s apart, see docs/safety.md).

    A single walker, or a crowd moving as one, has zero pressure. Zero where nobody is
    within the cut-off.
    """
    from scipy.spatial import cKDTree

    pos = np.asarray(positions, float).reshape(-1, 2)
    vel = np.asarray(velocities, float).reshape(-1, 2)
    pts = np.asarray(points, float).reshape(-1, 2)
    p = len(pts)
    rho, var = np.zeros(p), np.zeros(p)
    V = np.zeros((p, 2))
    if len(pos) and p:
        m = cKDTree(pts).sparse_distance_matrix(cKDTree(pos), cutoff * R,
                                                output_type="ndarray")
        i, j, d = m["i"], m["j"], m["v"]
        w = np.exp(-(d / R) ** 2)
        den = np.bincount(i, weights=w, minlength=p)
        ok = den > 0
        for k in range(2):
            V[:, k] = np.bincount(i, weights=w * vel[j, k], minlength=p)
        V[ok] /= den[ok, None]
        dv = vel[j] - V[i]
        var[ok] = np.bincount(i, weights=w * np.einsum("ij,ij->i", dv, dv),
                              minlength=p)[ok] / den[ok]
        rho = den / (math.pi * R * R)
    return CrowdPressure(rho, V, var, rho * var)


@dataclass(frozen=True)
class PeakPressure:
    """The highest crowd pressure over the frames, where and when, and each point's."""

    max: float  #: [1/s^2]
    t: float  #: [s]
    x: float  #: [m]
    y: float  #: [m]
    per_point: np.ndarray  #: (p,) each point's highest pressure [1/s^2]


def peak_crowd_pressure(*, frames: Iterable[tuple[float, np.ndarray, np.ndarray]],
                        points: np.ndarray, R: float = D['R'],
                        cutoff: float = D['density_cutoff']) -> PeakPressure:
    """The maximum over ``frames`` ((t [s], positions (n, 2) [m], velocities (n, 2) [m/s])
    each) and ``points`` [m] of :func:`crowd_pressure`, with its time and place (the first
    where it is reached)."""
    pts = np.asarray(points, float).reshape(-1, 2)
    per = np.zeros(len(pts))
    best, bt, bi = -1.0, math.nan, -1
    for t, pos, vel in frames:
        P = crowd_pressure(positions=pos, velocities=vel, points=pts, R=R,
                           cutoff=cutoff).pressure
        np.maximum(per, P, out=per)
        if len(P):
            i = int(np.argmax(P))
            if P[i] > best:
                best, bt, bi = float(P[i]), float(t), i
    if bi < 0:
        return PeakPressure(0.0, math.nan, math.nan, math.nan, per)
    return PeakPressure(best, bt, float(pts[bi, 0]), float(pts[bi, 1]), per)


@dataclass(frozen=True)
class ExitUsage:
    """The people out through one exit and when."""

    people: float  #: [ped]
    first: float | None  #: [s] first passage (None if nobody passed)
    last: float | None  #: [s] last passage
    t: np.ndarray  #: [s] times of the curves below
    cumulative: np.ndarray  #: [ped] people out through the exit by time t
    flow: np.ndarray  #: [ped/s] flow through the exit around time t


def _reach(t: np.ndarray, c: np.ndarray, level: float) -> float | None:
    """The first time a non-decreasing curve ``c(t)`` reaches ``level`` (linear
    interpolation between samples)."""
    idx = np.flatnonzero(c >= level - 1e-9)
    if len(idx) == 0:
        return None
    k = int(idx[0])
    if k == 0 or c[k] == c[k - 1]:
        return float(t[k])
    w = (level - c[k - 1]) / (c[k] - c[k - 1])
    return float(t[k - 1] + min(max(w, 0.0), 1.0) * (t[k] - t[k - 1]))


def _passages(t: np.ndarray, c: np.ndarray) -> tuple[float, float | None, float | None]:
    """(people, first, last): the curve's end, and when it reaches 0.5 and n - 0.5."""
    n = float(c[-1]) if len(c) else 0.0
    if n < 0.5:
        return n, None, None
    first = _reach(t, c, 0.5)
    last = _reach(t, c, max(n - 0.5, 0.5))
    return n, first, last


def exit_usage_from_crossings(*, exits: Sequence[str], times: np.ndarray,
                              names: Sequence[str], t: np.ndarray | None = None,
                              window: float = 2.0) -> dict[str, ExitUsage]:
    """Usage of each exit in ``names`` from individual crossings (a particle model's
    exits.csv): ``exits[i]`` is the exit pedestrian i left by at ``times[i]`` [s]. The
    first and last passage are the first and last crossing; the flow [ped/s] at ``t``
    (default every 0.5 s to the last crossing) counts the crossings in a ``window`` [s]
    around it (:func:`pedmesh.analysis.crossing_rate`)."""
    from .outflow import crossing_rate

    ex = np.asarray(exits, dtype=object)
    tt = np.asarray(times, float)
    if t is None:
        end = float(np.max(tt)) if len(tt) else 0.0
        t = np.arange(0.0, end + window + 0.25, 0.5)
    t = np.asarray(t, float)
    out = {}
    for name in names:
        mine = np.sort(tt[ex == name])
        out[name] = ExitUsage(
            float(len(mine)), float(mine[0]) if len(mine) else None,
            float(mine[-1]) if len(mine) else None, t,
            np.searchsorted(mine, t, side="right").astype(float),
            crossing_rate(exit_times=mine, t=t, window=window))
    return out


def exit_usage_from_flow(*, t: np.ndarray, flow: np.ndarray,
                         names: Sequence[str]) -> dict[str, ExitUsage]:
    """Usage of each exit from flows [ped/s] (k, len(names)) at times ``t`` [s] (k,), each
    the mean since the previous time (outflow.csv; the first row's is not counted): the
    people out are the integrated flow, the first and last passage the times the
    cumulative flow reaches 0.5 and n - 0.5 people (n: the exit's total; None if n < 0.5).
    """
    t = np.asarray(t, float).ravel()
    f = np.asarray(flow, float).reshape(len(t), len(names))
    dt = np.diff(t, prepend=t[0] if len(t) else 0.0)
    cum = np.cumsum(f * dt[:, None], axis=0)
    out = {}
    for k, name in enumerate(names):
        n, first, last = _passages(t, cum[:, k])
        out[name] = ExitUsage(n, first, last, t, cum[:, k], f[:, k])
    return out


def group_clear_times(*, exit_times: np.ndarray, counts: Sequence[int]) -> list[float | None]:
    """Time [s] by which each group of pedestrians has left: ``exit_times`` (N,) [s] by
    pedestrian id (NaN or inf for those still inside), the groups consecutive runs of ids
    of the given ``counts`` (the start areas, in order). None for a group of which someone
    did not leave; 0 for an empty group."""
    et = np.asarray(exit_times, float).ravel()
    out: list[float | None] = []
    start = 0
    for c in counts:
        mine = et[start:start + int(c)]
        start += int(c)
        if len(mine) < int(c) or not np.all(np.isfinite(mine)):
            out.append(None)
        else:
            out.append(float(mine.max()) if len(mine) else 0.0)
    return out


def cell_fractions(*, points: np.ndarray, triangles: np.ndarray, polygon) -> np.ndarray:
    """The fraction (0..1) of each triangle (of ``points`` [m]) inside ``polygon`` (a
    shapely polygon, e.g. a measurement area)."""
    import shapely

    pts = np.asarray(points, float)[:, :2]
    tris = shapely.polygons(pts[np.asarray(triangles)])
    frac = np.zeros(len(tris))
    hit = shapely.intersects(tris, polygon)
    if np.any(hit):
        frac[hit] = (shapely.area(shapely.intersection(tris[hit], polygon))
                     / shapely.area(tris[hit]))
    return np.clip(frac, 0.0, 1.0)


def area_content(*, density: np.ndarray, areas: np.ndarray,
                 fractions: np.ndarray) -> np.ndarray:
    """People [ped] in an area at each frame: the cell densities (frames, m) [ped/m^2]
    times the cell areas [m^2] inside the area (``fractions`` of :func:`cell_fractions`)."""
    d = np.atleast_2d(np.asarray(density, float))
    return d @ (np.asarray(areas, float) * np.asarray(fractions, float))


def clear_time(*, t: np.ndarray, content: np.ndarray, below: float = 0.5) -> float | None:
    """The time [s] after which ``content`` [ped] (at frames ``t`` [s]) stays below
    ``below`` [ped]: linearly interpolated between the last frame at or above it and the
    next; ``t[0]`` if it never is; None if the last frame still is."""
    t = np.asarray(t, float).ravel()
    c = np.asarray(content, float).ravel()
    if len(t) == 0:
        return None
    high = np.flatnonzero(c >= below)
    if len(high) == 0:
        return float(t[0])
    k = int(high[-1])
    if k == len(t) - 1:
        return None
    w = (c[k] - below) / (c[k] - c[k + 1])
    return float(t[k] + min(max(w, 0.0), 1.0) * (t[k + 1] - t[k]))
