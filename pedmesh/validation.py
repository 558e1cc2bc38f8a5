"""Validation against experiments: one measurement for real and simulated trajectories.

The experiments are the Jülich uni-directional corridor runs (Düsseldorf 2009; Zhang,
Klingsch, Schadschneider, Seyfried, J. Stat. Mech. P06004, 2011; Pedestrian Dynamics Data
Archive of Forschungszentrum Jülich), described in ``shared/experiments/README.md``. The
same functions measure an experiment file (:func:`load_experiment`) and a pedmesh run's
``trajectories.txt`` (:func:`load_run`), both read into :class:`pedpy.TrajectoryData`, so a
difference between simulation and experiment is never a difference of method.

The measurement (:func:`measure`), everything in SI units:

* **Flow** J [1/s] at a line: the time each pedestrian first crosses the line
  (:func:`passage_times`, PedPy's crossing frames / frame rate), sorted,
  t_(1) <= ... <= t_(n). The q-quantile of the crossing times is the order statistic
  t_(k_q) with k_q = ceil(q n) (the inverted-CDF quantile, an observed crossing time), and
  J = (k_0.8 - k_0.2) / (t_(k_0.8) - t_(k_0.2)): the passages between the 20 % and the
  80 % quantile of the crossing times divided by that time span (:func:`quantile_flow`).
* **Steady state**: the frames whose time t satisfies t_(k_0.2) <= t <= t_(k_0.8) at the
  line ``steady_line`` of the setup, for the corridor the line y = 0 where people enter
  the measurement area, i.e. exactly the flow window at y = 0. On the five experiments this
  rule reproduces the README's densities within 1.1 % and its speeds within 4 % (all but
  one, see :data:`REFERENCE_NOTES`).
* **Voronoi density and speed** [1/m^2, m/s] in the measurement area per frame (PedPy's
  :func:`pedpy.compute_voronoi_density` / :func:`pedpy.compute_voronoi_speed` without a
  cut-off, cells clipped to the walkable area), the individual speed from the displacement
  over +-:data:`SPEED_HALF_WINDOW_S` (5 frames at the experiments' 16 frames/s, 3 frames
  at a run's 10 frames/s), one-sided at the ends of a trajectory. The steady-state means
  are the means over the steady-state frames; those frames' (density, speed) pairs, or
  with ``fd_frames="all"`` every frame's, are the fundamental-diagram samples
  (:func:`bin_fd` bins them).

PedPy is imported inside the functions, so ``import pedmesh.validation`` works without it;
a function that needs it raises :class:`~pedmesh.errors.ParameterError` naming the extra
(``pip install pedmesh[validate]``).
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .errors import ParameterError
from .io.run_folder import TRAJECTORIES_TXT

__all__ = [
    "CORRIDOR_WIDTH_M",
    "EXPERIMENT_FRAME_RATE_HZ",
    "EXPERIMENT_TABLE",
    "FREE_SPEED_MS",
    "FREE_SPEED_SD_MS",
    "REFERENCE_NOTES",
    "SPECIFIC_BOTTLENECK_FLOW_PER_MS",
    "SPEED_HALF_WINDOW_S",
    "WEIDMANN_FREE_SPEED_MS",
    "WEIDMANN_GAMMA_PER_M2",
    "WEIDMANN_JAM_DENSITY_PER_M2",
    "MeasurementSetup",
    "bin_fd",
    "corridor_setup",
    "experiment_exit_width",
    "load_experiment",
    "load_run",
    "mean_speed_in_area",
    "measure",
    "passage_times",
    "quantile_flow",
    "quantile_window",
    "weidmann_speed",
]

#: width [m] of the Jülich corridor (x in [0, 1.8]); it is 8 m long (y in [-4, 4])
CORRIDOR_WIDTH_M = 1.8
#: frame rate [1/s] of the experiment files (coordinates in cm)
EXPERIMENT_FRAME_RATE_HZ = 16.0
#: half width [s] of the window of the individual speed: 5 frames at 16 frames/s
SPEED_HALF_WINDOW_S = 5.0 / EXPERIMENT_FRAME_RATE_HZ
#: the quantiles [-] of the crossing times that bound the flow window and the steady state
FLOW_QUANTILES = (0.2, 0.8)

# --------------------------------------------------------------------------- references
#: The measured values of ``shared/experiments/README.md`` (PedPy 1.5): people [-],
#: entrance and exit width [m], flow at the exit line y = -4 and at y = 0 [1/s], specific
#: exit flow [1/(m s)], steady-state mean Voronoi density [1/m^2] and speed [m/s] in the
#: area (0, -2)-(1.8, 0).
EXPERIMENT_TABLE: dict[str, dict[str, float]] = {
    "uo-070-180-180": {"people": 111, "entrance_m": 0.70, "exit_m": 1.80, "J_exit": 1.53,
                       "J_per_b_exit": 0.85, "J_y0": 1.54, "density": 0.66, "speed": 1.00},
    "uo-100-180-180": {"people": 121, "entrance_m": 1.00, "exit_m": 1.80, "J_exit": 2.35,
                       "J_per_b_exit": 1.31, "J_y0": 2.37, "density": 1.12, "speed": 1.16},
    "uo-145-180-180": {"people": 175, "entrance_m": 1.45, "exit_m": 1.80, "J_exit": 2.71,
                       "J_per_b_exit": 1.51, "J_y0": 2.84, "density": 1.54, "speed": 1.01},
    "uo-180-180-180": {"people": 220, "entrance_m": 1.80, "exit_m": 1.80, "J_exit": 2.85,
                       "J_per_b_exit": 1.58, "J_y0": 2.91, "density": 1.64, "speed": 0.98},
    "uo-180-180-095": {"people": 159, "entrance_m": 1.80, "exit_m": 0.95, "J_exit": 1.76,
                       "J_per_b_exit": 1.85, "J_y0": 1.83, "density": 2.36, "speed": 0.45},
}

#: Values of :data:`EXPERIMENT_TABLE` that the measurement does not reproduce, and why.
REFERENCE_NOTES: dict[tuple[str, str], str] = {
    ("uo-070-180-180", "speed"): (
        "the table's 1.00 m/s contradicts its own flow and density: J / (rho w) = "
        "1.54 / (0.66 x 1.8) = 1.30 m/s; the Voronoi speed in the area is 1.33 m/s in the "
        "steady state and 1.24-1.43 m/s (quartiles) over the whole run, so no choice of "
        "window gives 1.00 m/s"),
}

#: Weidmann's fundamental diagram (Weidmann 1993): free speed [m/s], gamma [1/m^2],
#: jam density [1/m^2]
WEIDMANN_FREE_SPEED_MS = 1.34
WEIDMANN_GAMMA_PER_M2 = 1.913
WEIDMANN_JAM_DENSITY_PER_M2 = 5.4
#: specific flow [1/(m s)] through bottlenecks of width 0.8-2.5 m (Seyfried et al. 2009,
#: Liddle et al. 2011)
SPECIFIC_BOTTLENECK_FLOW_PER_MS = 1.9
#: published points within this fraction of a width (at least BAND_MIN_TOLERANCE_M) count
#: for that width's band
BAND_WIDTH_TOLERANCE = 0.12
BAND_MIN_TOLERANCE_M = 0.1
#: [1/m^2] the densities in front of entrances that pressing crowds reach (Adrian, Seyfried
#: & Sieben 2020: 6-9 /m^2)
PRESSING_FRONT_DENSITY_PER_M2 = (6.0, 9.0)


def published_bottleneck_flows() -> list[dict[str, Any]]:
    """The published bottleneck series (``pedmesh/data/bottleneck_literature.json``): a list
    of {key, label, source, points: (k, 2) array of width [m], flow J [1/s]}. For
    validation only: nothing is fitted to them."""
    import json

    data = json.loads((Path(__file__).resolve().parent / "data"
                       / "bottleneck_literature.json").read_text())
    return [{**s, "points": np.asarray(s["points"], float)} for s in data["series"]]


def published_band(width_m: float, opening: str | None = None) -> tuple[float, float, int]:
    """(lowest, highest) published specific flow J/b [1/(m s)] of the points of
    :func:`published_bottleneck_flows` whose width is within ``BAND_WIDTH_TOLERANCE`` of
    ``width_m`` [m] (at least ``BAND_MIN_TOLERANCE_M``), and how many points there are
    ((nan, nan, 0) if none). ``opening``: only the series of that kind, ``"short"`` (doors
    and openings in a wall) or ``"long"`` (corridor-like openings); None: all."""
    if opening not in (None, "short", "long"):
        raise ParameterError(f"opening must be 'short', 'long' or None, got {opening!r}")
    tol = max(BAND_MIN_TOLERANCE_M, BAND_WIDTH_TOLERANCE * width_m) + 1e-12
    jb = [float(J / b) for s in published_bottleneck_flows()
          if opening is None or s.get("opening") == opening
          for b, J in s["points"] if abs(b - width_m) <= tol]
    return (min(jb), max(jb), len(jb)) if jb else (math.nan, math.nan, 0)


#: free walking speed [m/s]: mean and standard deviation (Weidmann 1993)
FREE_SPEED_MS = 1.34
FREE_SPEED_SD_MS = 0.26


def weidmann_speed(density: float | np.ndarray, *, free_speed: float = WEIDMANN_FREE_SPEED_MS,
                   gamma: float = WEIDMANN_GAMMA_PER_M2,
                   jam_density: float = WEIDMANN_JAM_DENSITY_PER_M2) -> float | np.ndarray:
    """Weidmann's fundamental diagram v(rho) = v0 (1 - exp(-gamma (1/rho - 1/rho_jam)))
    [m/s] at density ``density`` [1/m^2]: ``free_speed`` at rho <= 0, 0 from the jam
    density on."""
    rho = np.asarray(density, dtype=float)
    with np.errstate(divide="ignore"):
        inv = np.where(rho > 0, 1.0 / np.where(rho > 0, rho, 1.0), np.inf)
    v = free_speed * (1.0 - np.exp(-gamma * (inv - 1.0 / jam_density)))
    v = np.where(rho >= jam_density, 0.0, v)
    return float(v) if v.ndim == 0 else v


# --------------------------------------------------------------------------- pedpy access
def _pedpy():
    """The pedpy module, or a ParameterError naming the extra to install."""
    try:
        import pedpy
    except ImportError as exc:
        raise ParameterError("pedmesh.validation needs PedPy: pip install pedmesh[validate]"
                             ) from exc
    return pedpy


# --------------------------------------------------------------------------- geometry
@dataclass(frozen=True)
class MeasurementSetup:
    """Where to measure: the walkable area (a shapely polygon [m]; Voronoi cells are
    clipped to it), named flow lines (two end points [m] each), the measurement area
    (polygon [m]) of density and speed, and the name of the line whose flow window is the
    steady state."""

    walkable: Any
    lines: Mapping[str, Sequence[Sequence[float]]] = field(default_factory=dict)
    area: Sequence[Sequence[float]] = ()
    steady_line: str = "y0"

    def __post_init__(self) -> None:
        if self.steady_line not in self.lines:
            raise ParameterError(f"steady-state line '{self.steady_line}' is not one of the "
                                 f"lines ({', '.join(self.lines) or 'none'})")
        if len(self.area) < 3:
            raise ParameterError("the measurement area needs at least three corners")


def experiment_exit_width(run: str | Path) -> float:
    """The exit width [m] of a run named ``uo-<entrance cm>-<corridor cm>-<exit cm>``."""
    m = re.fullmatch(r"uo-(\d+)-(\d+)-(\d+)", Path(run).stem)
    if m is None:
        raise ParameterError(f"'{Path(run).stem}' is not a corridor run name "
                             "(uo-<entrance cm>-<corridor cm>-<exit cm>)")
    return int(m.group(3)) / 100.0


def corridor_setup(walkable: Any = None, *, exit_width_m: float = CORRIDOR_WIDTH_M
                   ) -> MeasurementSetup:
    """The measurement geometry of the corridor experiments [m]: the lines ``exit``
    (y = -4) and ``y0`` (y = 0) across the corridor (x in [0, 1.8]), the area
    (0, -2)-(1.8, 0), the steady state from the flow window at ``y0``.

    ``walkable`` (a shapely polygon, e.g. ``room.walkable`` of a simulated room) is the
    walkable area; by default the experiment's: the corridor x in [0, 1.8], y in [-4, 4],
    with 3.8 m wide spaces (x in [-1, 2.8]) in front of it up to y = 8.5 and behind it down
    to y = -6.5, where the trajectories begin and end, and for an exit narrower than the
    corridor (``exit_width_m``) a 0.1 m wall at y = -4 with the exit centred in it."""
    from shapely.geometry import Polygon, box
    from shapely.ops import unary_union

    w = CORRIDOR_WIDTH_M
    if walkable is None:
        parts = [box(0.0, -4.0, w, 4.0), box(-1.0, 4.0, w + 1.0, 8.5),
                 box(-1.0, -6.5, w + 1.0, -4.1)]
        if not 0 < exit_width_m <= w:
            raise ParameterError(f"exit width must be in (0, {w}] m, got {exit_width_m!r}")
        x0 = 0.5 * (w - exit_width_m)
        parts.append(box(x0, -4.1, x0 + exit_width_m, -4.0))
        if exit_width_m >= w:
            parts.append(box(-1.0, -4.1, w + 1.0, -4.0))
        walkable = unary_union(parts)
        if not isinstance(walkable, Polygon):
            raise ParameterError("the experiment's walkable area is not one polygon")
    return MeasurementSetup(
        walkable=walkable,
        lines={"exit": ((0.0, -4.0), (w, -4.0)), "y0": ((0.0, 0.0), (w, 0.0))},
        area=((0.0, -2.0), (w, -2.0), (w, 0.0), (0.0, 0.0)),
        steady_line="y0")


# --------------------------------------------------------------------------- loading
def load_experiment(path: str | Path, *, frame_rate_hz: float = EXPERIMENT_FRAME_RATE_HZ):
    """An experiment trajectory file (columns ``id frame x y height``, centimetres, no
    header, ``frame_rate_hz`` frames/s) as :class:`pedpy.TrajectoryData` in metres."""
    pedpy = _pedpy()
    return pedpy.load_trajectory_from_txt(trajectory_file=Path(path),
                                          default_unit=pedpy.TrajectoryUnit.CENTIMETER,
                                          default_frame_rate=frame_rate_hz)


def load_run(path: str | Path):
    """A pedmesh SFM run's trajectories (``trajectories.txt`` in metres, the frame rate
    in its header) as :class:`pedpy.TrajectoryData`; ``path`` is the run directory or the
    file."""
    pedpy = _pedpy()
    path = Path(path)
    if path.is_dir():
        path = path / TRAJECTORIES_TXT
    if not path.is_file():
        raise ParameterError(f"{path}: no trajectory file (an SFM run writes "
                             f"{TRAJECTORIES_TXT})")
    return pedpy.load_trajectory_from_txt(trajectory_file=path,
                                          default_unit=pedpy.TrajectoryUnit.METER)


# --------------------------------------------------------------------------- flow
def passage_times(traj, line: Sequence[Sequence[float]]) -> np.ndarray:
    """Sorted times [s] at which each pedestrian first crosses ``line`` (two or more points
    [m]): PedPy's crossing frame (the frame a movement across the line starts, a movement
    ending on the line not counted) divided by the frame rate."""
    frames = _crossing_frames(traj, line)[_pedpy().FRAME_COL].to_numpy(dtype=float)
    return np.sort(frames) / traj.frame_rate


def _crossing_frames(traj, line: Sequence[Sequence[float]]):
    """PedPy's table of each pedestrian's crossing frame of ``line`` (id, frame)."""
    pedpy = _pedpy()
    _, crossing = pedpy.compute_n_t(traj_data=traj,
                                    measurement_line=pedpy.MeasurementLine(list(line)))
    return crossing


def crossings(traj, line: Sequence[Sequence[float]]) -> tuple[np.ndarray, np.ndarray]:
    """When and where each pedestrian first crosses ``line``: times [s] (as
    :func:`passage_times`, sorted) and the positions (n, 2) [m] at those frames, in the
    same order."""
    pedpy = _pedpy()
    crossing = _crossing_frames(traj, line)
    at = crossing[[pedpy.ID_COL, pedpy.FRAME_COL]].merge(
        traj.data[[pedpy.ID_COL, pedpy.FRAME_COL, pedpy.X_COL, pedpy.Y_COL]],
        on=[pedpy.ID_COL, pedpy.FRAME_COL], how="left")
    frames = at[pedpy.FRAME_COL].to_numpy(dtype=float)
    order = np.argsort(frames, kind="stable")
    xy = at[[pedpy.X_COL, pedpy.Y_COL]].to_numpy(dtype=float)[order]
    return frames[order] / traj.frame_rate, xy


def quantile_window(times: Sequence[float], lo: float = FLOW_QUANTILES[0],
                    hi: float = FLOW_QUANTILES[1]) -> tuple[float, float, int]:
    """The ``lo`` and ``hi`` quantiles [s] of crossing times and the passages between them:
    with the times sorted t_(1) <= ... <= t_(n), the q-quantile is t_(k_q), k_q =
    ceil(q n), and the passages are k_hi - k_lo. (nan, nan, 0) if there are fewer than two
    crossings."""
    if not 0 <= lo < hi <= 1:
        raise ParameterError(f"quantiles must satisfy 0 <= lo < hi <= 1, got {lo}, {hi}")
    t = np.sort(np.asarray(times, dtype=float))
    n = len(t)
    if n < 2:
        return math.nan, math.nan, 0
    k_lo = max(1, math.ceil(lo * n - 1e-9))
    k_hi = max(1, math.ceil(hi * n - 1e-9))
    return float(t[k_lo - 1]), float(t[k_hi - 1]), k_hi - k_lo


def quantile_flow(times: Sequence[float], lo: float = FLOW_QUANTILES[0],
                  hi: float = FLOW_QUANTILES[1]) -> float:
    """Flow J [1/s]: the passages between the ``lo`` and ``hi`` quantiles of the crossing
    times ``times`` [s] divided by that time span (:func:`quantile_window`); nan if the
    span is empty."""
    t_lo, t_hi, passages = quantile_window(times, lo, hi)
    if not t_hi > t_lo:
        return math.nan
    return passages / (t_hi - t_lo)


# --------------------------------------------------------------------------- density, speed
def _speed_frame_step(frame_rate_hz: float, half_window_s: float) -> int:
    return max(1, round(half_window_s * frame_rate_hz))


def _individual_speed(traj, half_window_s: float):
    pedpy = _pedpy()
    return pedpy.compute_individual_speed(
        traj_data=traj, frame_step=_speed_frame_step(traj.frame_rate, half_window_s),
        speed_calculation=pedpy.SpeedCalculation.BORDER_SINGLE_SIDED)


def _frames(traj, first: int, last: int):
    """The trajectory restricted to frames first..last (inclusive)."""
    pedpy = _pedpy()
    df = traj.data
    keep = (df[pedpy.FRAME_COL] >= first) & (df[pedpy.FRAME_COL] <= last)
    cols = [pedpy.ID_COL, pedpy.FRAME_COL, pedpy.X_COL, pedpy.Y_COL]
    return pedpy.TrajectoryData(data=df.loc[keep, cols].reset_index(drop=True),
                                frame_rate=traj.frame_rate)


def _voronoi_cells(part, walkable):
    """PedPy's Voronoi cells of every row of ``part``. A frame on which GEOS fails (a
    degenerate diagram, e.g. a start lattice with four people on one circle) is found by
    bisection and computed again with the positions moved by at most 1e-6 m (seeded by
    the frame number); a frame that fails even so is left out."""
    import pandas as pd
    from shapely.errors import GEOSException

    pedpy = _pedpy()
    try:
        return pedpy.compute_individual_voronoi_polygons(traj_data=part, walkable_area=walkable)
    except GEOSException:
        pass
    df = part.data
    frames = np.sort(df[pedpy.FRAME_COL].unique())
    if len(frames) > 1:
        half = frames[len(frames) // 2]
        return pd.concat([_voronoi_cells(_frames(part, frames[0], half - 1), walkable),
                          _voronoi_cells(_frames(part, half, frames[-1]), walkable)],
                         ignore_index=True)
    rng = np.random.default_rng(int(frames[0]))
    moved = df.copy()
    for col in (pedpy.X_COL, pedpy.Y_COL):
        moved[col] = moved[col] + rng.uniform(-1e-6, 1e-6, len(moved))
    moved = moved.drop(columns=[pedpy.POINT_COL], errors="ignore")
    try:
        cells = pedpy.compute_individual_voronoi_polygons(
            traj_data=pedpy.TrajectoryData(data=moved, frame_rate=part.frame_rate),
            walkable_area=walkable)
    except GEOSException:
        return pd.DataFrame(columns=[pedpy.ID_COL, pedpy.FRAME_COL, pedpy.POLYGON_COL,
                                     pedpy.DENSITY_COL])
    return cells


def _voronoi_fd(traj, setup: MeasurementSetup, first: int, last: int,
                half_window_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Frames, Voronoi density [1/m^2] and Voronoi speed [m/s] in the area per frame for
    the frames first..last."""
    pedpy = _pedpy()
    part = _frames(traj, first, last)
    if part.data.empty:
        return np.zeros(0, int), np.zeros(0), np.zeros(0)
    area = pedpy.MeasurementArea(list(setup.area))
    walkable = pedpy.WalkableArea(setup.walkable)
    cells = _voronoi_cells(part, walkable)
    density, inter = pedpy.compute_voronoi_density(individual_voronoi_data=cells,
                                                   measurement_area=area)
    speed_ind = _individual_speed(traj, half_window_s)
    keys = [pedpy.ID_COL, pedpy.FRAME_COL]
    inter = inter.merge(speed_ind[keys], on=keys)  # only cells with a speed
    speed = pedpy.compute_voronoi_speed(traj_data=part, individual_voronoi_intersection=inter,
                                        individual_speed=speed_ind, measurement_area=area)
    d = density.set_index(pedpy.FRAME_COL)[pedpy.DENSITY_COL]
    v = speed.set_index(pedpy.FRAME_COL)[pedpy.SPEED_COL]
    frames = np.arange(first, last + 1)
    frames = frames[np.isin(frames, part.data[pedpy.FRAME_COL].unique())]
    return (frames, d.reindex(frames, fill_value=0.0).to_numpy(float),
            v.reindex(frames, fill_value=0.0).to_numpy(float))


def measure(traj, setup: MeasurementSetup, *, quantiles: tuple[float, float] = FLOW_QUANTILES,
            speed_half_window_s: float = SPEED_HALF_WINDOW_S,
            fd_frames: str = "steady") -> dict[str, Any]:
    """Measure trajectories ``traj`` (:class:`pedpy.TrajectoryData`, metres) in ``setup``.

    Returns a dict (SI units):

    * ``flow``: {line name: J [1/s]} by :func:`quantile_flow`; ``flow_window_s``: {line:
      (t_lo, t_hi) [s]}; ``passages``: {line: passages in the window}; ``crossings``:
      {line: pedestrians who crossed};
    * ``steady_state_s``: (t_lo, t_hi) [s], the flow window at ``setup.steady_line``;
    * ``density`` [1/m^2], ``speed`` [m/s]: the means of the Voronoi density and speed in
      the area over the steady-state frames (nan without a steady state);
    * ``fd_time_s``, ``fd_density``, ``fd_speed``: the per-frame samples (numpy arrays
      [s], [1/m^2], [m/s]) for a fundamental diagram (:func:`bin_fd`): of the steady-state
      frames (``fd_frames="steady"``) or of every frame in which someone's Voronoi cell
      reaches into the area (``"all"``: transients too, more Voronoi work);
    * ``frame_rate_hz``.
    """
    if fd_frames not in ("steady", "all"):
        raise ParameterError(f"fd_frames must be 'steady' or 'all', got {fd_frames!r}")
    lo, hi = quantiles
    rate = float(traj.frame_rate)
    out: dict[str, Any] = {"flow": {}, "flow_window_s": {}, "passages": {}, "crossings": {},
                           "frame_rate_hz": rate}
    for name, line in setup.lines.items():
        times = passage_times(traj, line)
        t_lo, t_hi, passages = quantile_window(times, lo, hi)
        out["flow"][name] = quantile_flow(times, lo, hi)
        out["flow_window_s"][name] = (t_lo, t_hi)
        out["passages"][name] = passages
        out["crossings"][name] = len(times)
    t_lo, t_hi = out["flow_window_s"][setup.steady_line]
    out["steady_state_s"] = (t_lo, t_hi)
    steady = math.isfinite(t_lo) and t_hi > t_lo
    first, last = (round(t_lo * rate), round(t_hi * rate)) if steady else (0, -1)
    if fd_frames == "all" and not traj.data.empty:
        frames = traj.data[_pedpy().FRAME_COL]
        frames, dens, speed = _voronoi_fd(traj, setup, int(frames.min()), int(frames.max()),
                                          speed_half_window_s)
        fd = dens > 0
        fd_frames_, fd_dens, fd_speed = frames[fd], dens[fd], speed[fd]
        keep = (frames >= first) & (frames <= last)
        frames, dens, speed = frames[keep], dens[keep], speed[keep]
    else:
        frames, dens, speed = _voronoi_fd(traj, setup, first, last, speed_half_window_s)
        fd_frames_, fd_dens, fd_speed = frames, dens, speed
    out["density"] = float(dens.mean()) if len(dens) else math.nan
    out["speed"] = float(speed.mean()) if len(speed) else math.nan
    out["fd_time_s"] = fd_frames_ / rate
    out["fd_density"] = fd_dens
    out["fd_speed"] = fd_speed
    return out


def mean_speed_in_area(traj, area: Sequence[Sequence[float]], *,
                       speed_half_window_s: float = SPEED_HALF_WINDOW_S) -> tuple[float, int]:
    """Mean individual speed [m/s] of the samples (one per pedestrian and frame) whose
    position lies in the polygon ``area`` [m], and how many samples there were; the speed
    as in :func:`measure`. Meant for free walkers, far apart."""
    import shapely

    pedpy = _pedpy()
    df = traj.data
    inside = shapely.contains_xy(shapely.Polygon(area), df[pedpy.X_COL].to_numpy(),
                                 df[pedpy.Y_COL].to_numpy())
    keys = [pedpy.ID_COL, pedpy.FRAME_COL]
    sel = df.loc[inside, keys]
    speed = _individual_speed(traj, speed_half_window_s).merge(sel, on=keys)
    n = len(speed)
    return (float(speed[pedpy.SPEED_COL].mean()) if n else math.nan), n


# --------------------------------------------------------------------------- binning
def bin_fd(density: Iterable[float], speed: Iterable[float],
           centres: Sequence[float] = (1.0, 2.0, 3.0), half_width: float = 0.25
           ) -> list[dict[str, float]]:
    """Fundamental-diagram samples binned by density: for each centre c [1/m^2] the mean
    speed [m/s] of the samples with c - half_width <= density < c + half_width and their
    count. Returns [{"density": c, "speed": mean or nan, "n": count}, ...]."""
    if not half_width > 0:
        raise ParameterError(f"half_width must be positive, got {half_width!r}")
    rho = np.asarray(list(density) if not isinstance(density, np.ndarray) else density,
                     dtype=float).ravel()
    v = np.asarray(list(speed) if not isinstance(speed, np.ndarray) else speed,
                   dtype=float).ravel()
    if rho.shape != v.shape:
        raise ParameterError(f"{len(rho)} densities but {len(v)} speeds")
    out = []
    for c in centres:
        sel = (rho >= c - half_width) & (rho < c + half_width) & np.isfinite(v)
        n = int(sel.sum())
        out.append({"density": float(c), "speed": float(v[sel].mean()) if n else math.nan,
                    "n": n})
    return out
