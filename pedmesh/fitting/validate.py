"""Validation of the social force model against experiments (and the objective of a fit).

1. **Corridor** (default): the five Jülich uni-directional corridor runs (Düsseldorf 2009;
   Zhang, Klingsch, Schadschneider, Seyfried, J. Stat. Mech. P06004, 2011; Pedestrian
   Dynamics Data Archive of Forschungszentrum Jülich). Each room of
   ``geometries/experiments/`` is simulated with the SFM and the run's trajectories and the
   experiment's are measured by the same functions of :mod:`pedmesh.validation`: flow at
   the exit (y = -4) and at y = 0, steady-state Voronoi density and speed in the area
   (0, -2)-(1.8, 0), and the pooled fundamental diagram at 1, 2, 3 /m^2 against the
   experiment's and Weidmann's (samples from every frame with ``--fd-frames all``, the
   default, or from the steady state only). ``--entrance`` says how people get into the
   corridor: ``door`` (the default; the rooms as they are: a waiting crowd pressing
   through the entrance door) or ``replay`` (the experiment's inflow: the room ends at
   y = 7.75 m and each of the experiment's people enters at the time they crossed
   y = 7.5 m, :func:`replay_room`). The experiment let its people in at a controlled rate
   (``../shared/experiments/README.md``; its waiting area is not recorded), so ``replay``
   is the experiment's boundary condition; ``door`` asks the model to predict the
   entrance flow as well.
2. ``--bottleneck``: 150 people waiting directly in front of a 2.8 m long corridor of width
   b = 0.5, 0.6, 0.8, 1.0, 1.2, 1.8, 2.5 m (the length of Seyfried et al. 2009 / Liddle et
   al. 2011; the room is generated here, its proportions are this script's choice), a crowd
   that presses to get through: specific flow J/b [1/(m s)] at the middle of the corridor
   by the same quantile flow, against the published band at that width
   (:func:`pedmesh.validation.published_band`: Kretz 2006, Seyfried 2009, Liddle /
   Rupprecht 2011, Mueller 1981, Nagai 2006, Daamen 2010, Liao 2014), and PedPy's Voronoi
   density in front of the opening (a FRONT_DEPTH deep area reaching FRONT_MARGIN beyond
   each side, mean over the flow's steady state) against the 6-9 /m^2 of pressing crowds
   (Adrian, Seyfried & Sieben 2020). ``bottleneck.png`` plots both against the published
   points.
3. ``--free``: three pedestrians 15 m apart in a 60 m corridor: mean speed [m/s] against
   the free walking speed 1.34 m/s.

    python -m pedmesh.fitting.validate [--data DIR] [--preset NAME] [--param NAME=VALUE ...]
                                       [--entrance door|replay] [--bottleneck] [--free]
                                       [--only-extra] [--out DIR]

``--data`` is the experiments directory (``data/*.txt``; default ``$PEDMESH_EXPERIMENTS``
or ``<repo>/../shared/experiments``). Simulations run one at a time; set
``NUMBA_NUM_THREADS=1`` on a shared machine. Results go to ``--out`` (default
``runs/validation``): ``validation.json`` (every number, the errors, wall times),
``validation.md`` (the tables) and the runs in ``runs/<part>/<name>/``.

As the objective of a parameter fit (:mod:`pedmesh.fitting.fit_validated`), from Python::

    from pedmesh.fitting.validate import validation_errors
    err = validation_errors({"r": 0.2, "A": 1500.0}, preset="weidmann",
                            parts=("corridor", "bottleneck"))
    err["rms"], err["corridor/uo-100-180-180/J_exit"], err["bottleneck/b=1.2"]

gives the relative errors (sim / reference - 1) as plain floats.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
import time
import warnings
from collections.abc import Iterable, Mapping
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

import pedmesh.validation as V
from pedmesh.geometry import Exit, MeasurementLine, Room, StartArea
from pedmesh.io import load_room
from pedmesh.io.run_folder import json_safe
from pedmesh.mesh import triangulate

#: the source checkout (pedmesh/fitting/ -> the repository): its rooms, next to its data
ROOT = Path(__file__).resolve().parents[2]
ROOMS = ROOT / "geometries" / "experiments"
MESH_OPTIONS = {"max_area": 2.0, "min_angle": 30.0, "feature_area": 0.3, "exit_size": None}
FD_DENSITIES = (1.0, 2.0, 3.0)  # [1/m^2]
FD_HALF_WIDTH = 0.25  # [1/m^2]
#: [frames] the fewest samples a run needs in a density bin, in simulation and experiment
#: alike, to count in that bin's run-by-run comparison (see :func:`paired_fd`)
FD_PAIR_MIN = 10
#: [m] the bottleneck series (issue: Kretz 2006 to Liddle 2011 cover 0.4-2.5 m)
BOTTLENECK_WIDTHS = (0.5, 0.6, 0.8, 1.0, 1.2, 1.8, 2.5)
#: [m] depth of the area in front of the opening where the Voronoi density is measured;
#: the area reaches FRONT_MARGIN beyond each side of the opening
FRONT_DEPTH = 1.0
FRONT_MARGIN = 0.5
BOTTLENECK_LENGTH = 2.8  # [m]
BOTTLENECK_PEOPLE = 150
#: [m] the series of doors in a thin wall (issue 44: 0.4-1.6 m, Kretz et al. 2006's
#: 0.4-1.2 m and Mueller 1981's up to 1.8 m)
WALL_DOOR_WIDTHS = (0.4, 0.5, 0.6, 0.8, 1.0, 1.2, 1.6)
#: [m] the wall's thickness (Kretz et al. 2006: 0.2 m) and the depth of the room behind it
WALL_THICKNESS = 0.2
ROOM_BEHIND = 4.0
PARTS = ("corridor", "bottleneck", "walldoor", "free")
#: [Hz] the rate at which the simulated runs record trajectories (every part's default)
TRAJECTORY_RATE_HZ = 10.0


def default_data_dir() -> Path:
    """``$PEDMESH_EXPERIMENTS``, else ``<repo>/../shared/experiments``."""
    env = os.environ.get("PEDMESH_EXPERIMENTS")
    return Path(env) if env else (ROOT.parent / "shared" / "experiments").resolve()


# --------------------------------------------------------------------------- rooms
def bottleneck_room(width_m: float, *, length_m: float = BOTTLENECK_LENGTH,
                    people: int = BOTTLENECK_PEOPLE) -> Room:
    """A waiting area 8 m wide and 7.5 m deep (y in [0, 7.5]) with ``people`` on a lattice
    (2.5 /m^2 for 150), directly in front of a corridor of width ``width_m`` [m] and length
    ``length_m`` [m] centred on it; the corridor's far end is the exit, the flow line
    ``middle`` lies across the corridor half way along it."""
    w_wait, d_wait = 8.0, 7.5
    xl, xr = 0.5 * (w_wait - width_m), 0.5 * (w_wait + width_m)
    y_end = d_wait + length_m
    outline = [(0, 0), (w_wait, 0), (w_wait, d_wait), (xr, d_wait), (xr, y_end),
               (xl, y_end), (xl, d_wait), (0, d_wait)]
    return Room(outline, exits=[Exit("exit", [(xl, y_end), (xr, y_end)])],
                start_areas=[StartArea("waiting", [(0.2, 0.2), (w_wait - 0.2, 0.2),
                                                   (w_wait - 0.2, d_wait - 0.2),
                                                   (0.2, d_wait - 0.2)], count=people)],
                measurement_lines=[MeasurementLine("middle", [(xl, d_wait + 0.5 * length_m),
                                                              (xr, d_wait + 0.5 * length_m)])],
                name=f"bottleneck-b{width_m:g}")


def wall_door_room(width_m: float, *, people: int = BOTTLENECK_PEOPLE) -> Room:
    """The bottleneck series' waiting area (8 x 7.5 m, ``people`` on a lattice) in front of
    a door of width ``width_m`` [m] in a wall WALL_THICKNESS thick, centred on it, and a
    room 8 m wide and ROOM_BEHIND deep behind the wall, whose far wall is the exit; the flow
    line ``middle`` lies across the door half way through the wall."""
    w_wait, d_wait = 8.0, 7.5
    xl, xr = 0.5 * (w_wait - width_m), 0.5 * (w_wait + width_m)
    y1 = d_wait + WALL_THICKNESS
    y2 = y1 + ROOM_BEHIND
    outline = [(0, 0), (w_wait, 0), (w_wait, d_wait), (xr, d_wait), (xr, y1), (w_wait, y1),
               (w_wait, y2), (0, y2), (0, y1), (xl, y1), (xl, d_wait), (0, d_wait)]
    return Room(outline, exits=[Exit("exit", [(w_wait, y2), (0, y2)])],
                start_areas=[StartArea("waiting", [(0.2, 0.2), (w_wait - 0.2, 0.2),
                                                   (w_wait - 0.2, d_wait - 0.2),
                                                   (0.2, d_wait - 0.2)], count=people)],
                measurement_lines=[MeasurementLine("middle", [
                    (xl, d_wait + 0.5 * WALL_THICKNESS), (xr, d_wait + 0.5 * WALL_THICKNESS)])],
                name=f"walldoor-b{width_m:g}")


def bottleneck_setup(room: Room, width_m: float) -> V.MeasurementSetup:
    """Where a :func:`bottleneck_room` of width ``width_m`` [m] is measured: the flow at
    its line ``middle`` (also the steady state), the density in the area in front of the
    opening, FRONT_DEPTH deep and FRONT_MARGIN wider than the opening on each side."""
    xl = 4.0 - 0.5 * width_m - FRONT_MARGIN
    xr = 4.0 + 0.5 * width_m + FRONT_MARGIN
    y1 = 7.5
    return V.MeasurementSetup(
        walkable=room.walkable, lines={"middle": room.measurement_lines[0].polyline},
        area=[(xl, y1 - FRONT_DEPTH), (xr, y1 - FRONT_DEPTH), (xr, y1), (xl, y1)],
        steady_line="middle")


def free_room(*, length_m: float = 60.0, width_m: float = 4.0) -> Room:
    """A corridor ``length_m`` x ``width_m`` [m] with its far end (x = length) the exit and
    three pedestrians on its axis at x = 1, 16, 31 m (15 m apart: no interaction)."""
    y = 0.5 * width_m
    starts = [StartArea(f"walker-{i}", [(x - 0.4, y - 0.4), (x + 0.4, y - 0.4),
                                        (x + 0.4, y + 0.4), (x - 0.4, y + 0.4)], count=1)
              for i, x in enumerate((1.0, 16.0, 31.0))]
    return Room([(0, 0), (length_m, 0), (length_m, width_m), (0, width_m)],
                exits=[Exit("exit", [(length_m, 0), (length_m, width_m)])],
                start_areas=starts, name="free-walking")


#: [m] the line across the passage where ``--entrance replay`` lets the experiment's people
#: in (the camera's field ends at y = 8 m; everyone of every run crosses y = 7.5 m)
REPLAY_LINE_Y = 7.5
#: [m] half the depth of the entrance strip around that line; the room ends a little above it
REPLAY_HALF_DEPTH = 0.25
ENTRANCES = ("door", "replay")


def replay_room(room: Room, traj) -> Room:
    """``room`` (a corridor run) with its waiting area and entrance door replaced by the
    experiment's measured inflow: the room ends just above y = REPLAY_LINE_Y, and its
    people enter in a strip across that line, between the 2nd and 98th percentile of where
    the experiment's people crossed it, each at the time one of them crossed it (PedPy's
    crossing times, shifted to start at 0; :func:`pedmesh.validation.crossings`)."""
    import shapely
    from shapely.geometry import box

    y0 = REPLAY_LINE_Y
    top = y0 + REPLAY_HALF_DEPTH
    times, xy = V.crossings(traj, [(-10.0, y0), (10.0, y0)])
    cut = room.walkable.intersection(box(-1e3, -1e3, 1e3, top))
    if cut.geom_type != "Polygon":
        raise ValueError(f"{room.name}: cutting the room at y = {top:g} m leaves "
                         f"{cut.geom_type}, not one polygon")
    cut = shapely.set_precision(cut, 1e-9)
    x_lo, x_hi = np.percentile(xy[:, 0], [2.0, 98.0])
    x_min, _, x_max, _ = cut.bounds
    x_lo, x_hi = max(float(x_lo), x_min), min(float(x_hi), x_max)
    strip = [(x_lo, y0 - REPLAY_HALF_DEPTH), (x_hi, y0 - REPLAY_HALF_DEPTH), (x_hi, top),
             (x_lo, top)]
    return Room(list(cut.exterior.coords)[:-1], exits=room.exits,
                start_areas=[StartArea("entrance", strip, count=len(times),
                                       arrivals={"times": [float(t) for t in
                                                           times - times[0]]})],
                measurement_lines=room.measurement_lines,
                measurement_areas=room.measurement_areas, name=f"{room.name}-replay",
                description=f"{room.name} with the experiment's inflow at y = {y0:g} m")


#: where the free speed is measured: x in [36, 58] m (at least 5 m after every start)
FREE_AREA = ((36.0, 0.0), (58.0, 0.0), (58.0, 4.0), (36.0, 4.0))


# --------------------------------------------------------------------------- running
def run_sfm(room: Room, out_dir: Path, *, overrides: Mapping[str, Any] | None = None,
            preset: str | None = None, t_end: float = 600.0,
            trajectory_rate: float = TRAJECTORY_RATE_HZ, geometry: str | None = None,
            model_options: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Simulate ``room`` with the SFM into ``out_dir``; the run's summary plus
    ``wall_s`` (whole wall time [s] including meshing) and ``error`` (None, or why the
    run failed). ``model_options``: more options of the run (``seed``, ``static_routes``)."""
    from pedmesh.errors import PedmeshError
    from pedmesh.run import run_model

    t0 = time.perf_counter()
    try:
        mesh = triangulate(room, **{k: v for k, v in MESH_OPTIONS.items() if v is not None})
        summary = run_model(room, mesh, "sfm", overrides=dict(overrides or {}), t_end=t_end,
                            out_dir=out_dir, quiet=True, geometry=geometry,
                            mesh_options=dict(MESH_OPTIONS),
                            model_options={"trajectory_rate": trajectory_rate,
                                           **(model_options or {})},
                            preset=preset)
        error = None
    except PedmeshError as exc:  # a blow-up or a bad parameter: record it, go on
        summary, error = {"status": "failed"}, f"{type(exc).__name__}: {exc}"
    summary = dict(summary)
    summary["wall_s"] = time.perf_counter() - t0
    summary["error"] = error
    return summary


@lru_cache(maxsize=8)
def measure_experiments(data_dir: str, fd_frames: str = "steady") -> dict[str, dict]:
    """:func:`pedmesh.validation.measure` of every experiment file in ``data_dir/data``
    (cached: the same data give the same numbers)."""
    out = {}
    for name in V.EXPERIMENT_TABLE:
        path = Path(data_dir) / "data" / f"{name}.txt"
        if not path.is_file():
            continue
        traj = V.load_experiment(path)
        setup = V.corridor_setup(exit_width_m=V.experiment_exit_width(name))
        out[name] = V.measure(traj, setup, fd_frames=fd_frames)
    return out


def _rel(sim: float, ref: float) -> float:
    """Relative error sim / ref - 1 [-] (nan if either is missing)."""
    if not (math.isfinite(sim) and math.isfinite(ref)) or ref == 0:
        return math.nan
    return sim / ref - 1.0


def _seed_options(seed: int | None) -> dict[str, Any]:
    """The run options of one realisation (none for ``seed`` None: the unjittered run)."""
    return {} if seed is None else {"seed": int(seed)}


def _seed_dir(runs_dir: Path, name: str, seed: int | None, seeds: tuple) -> Path:
    """A run's directory: ``runs_dir/name``, or ``runs_dir/name/s<seed>`` with several."""
    return runs_dir / name if len(seeds) == 1 else runs_dir / name / f"s{seed}"


def _mean(values: Iterable[float]) -> float:
    """The mean of the finite values (nan if there are none)."""
    v = [float(x) for x in values if x is not None and math.isfinite(float(x))]
    return float(np.mean(v)) if v else math.nan


def corridor_part(data_dir: Path, runs_dir: Path, *, overrides=None, preset=None,
                  t_end: float = 600.0, trajectory_rate: float = TRAJECTORY_RATE_HZ,
                  fd_frames: str = "steady", entrance: str = "door",
                  seeds: Iterable[int | None] = (None,), log=print) -> dict[str, Any]:
    """Simulate and measure the five corridor runs; rows and the pooled FD. ``entrance``:
    ``door`` (the rooms of ``geometries/experiments/``: a waiting crowd and the entrance
    door) or ``replay`` (:func:`replay_room`: the experiment's inflow). ``seeds``: the
    realisations of each run (None: the unjittered one); a row holds the mean of its
    realisations' values (over those that ran) and the FD pools every realisation's
    samples."""
    seeds = tuple(seeds)
    if entrance not in ENTRANCES:
        raise ValueError(f"unknown entrance {entrance!r} (entrances: {', '.join(ENTRANCES)})")
    experiments = measure_experiments(str(data_dir), fd_frames)
    if not experiments:
        raise SystemExit(f"no experiment files in {data_dir / 'data'} "
                         "(--data DIR or PEDMESH_EXPERIMENTS)")
    rows, exp_fd = [], ([], [])
    by_seed: dict[Any, tuple[list, list]] = {}  # a realisation's FD samples of every run
    by_run: dict[str, tuple] = {}  # a run's samples: (sim density, speed, exp density, speed)
    for name, exp in experiments.items():
        path = ROOMS / f"{name}.json"
        room = load_room(path)
        geometry = str(path)
        if entrance == "replay":
            room = replay_room(room, V.load_experiment(Path(data_dir) / "data" / f"{name}.txt"))
            geometry = None
        sims, summaries = [], []
        for seed in seeds:
            out = _seed_dir(runs_dir, name, seed, seeds)
            s = run_sfm(room, out, overrides=overrides, preset=preset, t_end=t_end,
                        trajectory_rate=trajectory_rate, geometry=geometry,
                        model_options=_seed_options(seed))
            summaries.append(s)
            if s["error"] is None:
                sim = V.measure(V.load_run(out), V.corridor_setup(room.walkable),
                                fd_frames=fd_frames)
                sims.append(sim)
                by_seed.setdefault(seed, ([], []))
                by_seed[seed][0].append(sim["fd_density"])
                by_seed[seed][1].append(sim["fd_speed"])
        bad = [s for s in summaries if s["error"] is not None or s.get("status") != "finished"]
        first = bad[0] if bad else summaries[0]
        row: dict[str, Any] = {"run": name, "status": first.get("status"),
                               "error": first["error"],
                               "wall_s": float(sum(s["wall_s"] for s in summaries)),
                               "n_initial": first.get("n_initial"),
                               "n_evacuated": first.get("n_evacuated"),
                               "realisations": len(seeds)}
        for key, get in (("J_exit", lambda m: m["flow"]["exit"]),
                         ("J_y0", lambda m: m["flow"]["y0"]),
                         ("density", lambda m: m["density"]), ("speed", lambda m: m["speed"])):
            row[f"{key}_exp"] = get(exp)
            row[f"{key}_sim"] = _mean(get(m) for m in sims)
            row[f"{key}_err"] = _rel(row[f"{key}_sim"], row[f"{key}_exp"])
            if len(seeds) > 1:
                row[f"{key}_sims"] = [float(get(m)) for m in sims]
        exp_fd[0].append(exp["fd_density"])
        exp_fd[1].append(exp["fd_speed"])
        by_run[name] = (np.concatenate([np.ravel(m["fd_density"]) for m in sims] or [[]]),
                        np.concatenate([np.ravel(m["fd_speed"]) for m in sims] or [[]]),
                        np.ravel(exp["fd_density"]), np.ravel(exp["fd_speed"]))
        rows.append(row)
        log(f"  {name}: {row['status']}, {row['wall_s']:.1f} s wall"
            + (f" ({row['error']})" if row["error"] else ""))

    def pooled(fd):
        if not fd[0]:
            return V.bin_fd([], [], FD_DENSITIES, FD_HALF_WIDTH)
        return V.bin_fd(np.concatenate(fd[0]), np.concatenate(fd[1]), FD_DENSITIES,
                        FD_HALF_WIDTH)

    fd = []
    sim_fd = tuple([a for part in by_seed.values() for a in part[i]] for i in (0, 1))
    per_seed = [pooled(by_seed[seed]) for seed in seeds if seed in by_seed]
    for k, (s_bin, e_bin) in enumerate(zip(pooled(sim_fd), pooled(exp_fd))):
        rho = s_bin["density"]
        fd.append({"density": rho, "speed_sim": s_bin["speed"], "n_sim": s_bin["n"],
                   "speed_exp": e_bin["speed"], "n_exp": e_bin["n"],
                   "speed_weidmann": V.weidmann_speed(rho)})
        if len(seeds) > 1:  # each realisation's own pooled FD
            fd[-1]["speed_sims"] = [b[k]["speed"] for b in per_seed]
    for b, paired in zip(fd, paired_fd(by_run)):
        b.update(paired)
    return {"rows": rows, "fd": fd, "fd_frames": fd_frames, "seeds": list(seeds)}


def paired_fd(by_run: dict[str, tuple], centres=FD_DENSITIES,
              half_width: float = FD_HALF_WIDTH, least: int = FD_PAIR_MIN
              ) -> list[dict[str, Any]]:
    """The fundamental diagram compared run by run. ``by_run``: each run's samples
    (simulated density [1/m^2], speed [m/s], experimental density, speed).

    The pooled bin mixes the runs in the proportions each spends at that density, and a
    simulation's proportions are not the experiment's: a run that passes through 2 /m^2
    quickly in one realisation and lingers there in another moves the pooled speed though
    its own speed there is the same (the corner fit's point #19, replayed inflow, four
    realisations: 0.73-0.85 m/s pooled at 2 /m^2). Here each run's simulated and
    experimental speed in the bin are compared over the runs that both have at least
    ``least`` samples there, each weighted by the experiment's samples: ``speed_sim_paired``
    and ``speed_exp_paired`` [m/s], ``paired_runs`` (their names) and ``runs`` (each run's
    counts and speeds)."""
    bins = {name: (V.bin_fd(ds, vs, centres, half_width), V.bin_fd(de, ve, centres, half_width))
            for name, (ds, vs, de, ve) in by_run.items()}
    out = []
    for k in range(len(centres)):
        per = {name: {"n_sim": s[k]["n"], "speed_sim": s[k]["speed"], "n_exp": e[k]["n"],
                      "speed_exp": e[k]["speed"]} for name, (s, e) in bins.items()}
        out.append({**paired_means(per, least), "runs": per})
    return out


def paired_means(per: Mapping[str, Mapping[str, float]], least: int = FD_PAIR_MIN
                 ) -> dict[str, Any]:
    """One density bin of :func:`paired_fd` from each run's counts and speeds there
    (``per[run]``: ``n_sim``, ``speed_sim``, ``n_exp``, ``speed_exp``): the simulated and
    experimental speeds [m/s] over the runs with at least ``least`` samples in both, each
    weighted by the experiment's samples (nan if none), and those runs' names."""
    paired = [n for n, r in per.items() if r["n_sim"] >= least and r["n_exp"] >= least]
    w = sum(per[n]["n_exp"] for n in paired)
    return {"speed_sim_paired": sum(per[n]["n_exp"] * per[n]["speed_sim"]
                                    for n in paired) / w if w else math.nan,
            "speed_exp_paired": sum(per[n]["n_exp"] * per[n]["speed_exp"]
                                    for n in paired) / w if w else math.nan,
            "paired_runs": paired}


def bottleneck_part(runs_dir: Path, *, overrides=None, preset=None, t_end: float = 600.0,
                    trajectory_rate: float = TRAJECTORY_RATE_HZ,
                    widths: Iterable[float] = BOTTLENECK_WIDTHS,
                    seeds: Iterable[int | None] = (None,), log=print,
                    opening: str = "long") -> list[dict[str, Any]]:
    """The bottleneck series: per width b [m], the specific flow J/b [1/(m s)] at the middle
    of the opening, PedPy's Voronoi density [1/m^2] in front of it (mean over the flow's
    steady state), the published band of J/b at that width, and who was left inside at the
    end (``stuck``); the means over the realisations ``seeds``. ``opening``: ``long`` (the
    2.8 m long openings of :func:`bottleneck_room`, against every published series) or
    ``short`` (the doors in a thin wall of :func:`wall_door_room`, against the published
    doors and short openings, ``published_band(b, "short")``)."""
    rows = []
    seeds = tuple(seeds)
    make = {"long": bottleneck_room, "short": wall_door_room}[opening]
    band_of = "short" if opening == "short" else None
    for b in widths:
        room = make(b)
        setup = bottleneck_setup(room, b)
        flows, dens, summaries = [], [], []
        for seed in seeds:
            out = _seed_dir(runs_dir, f"b{b:g}", seed, seeds)
            s = run_sfm(room, out, overrides=overrides, preset=preset, t_end=t_end,
                        trajectory_rate=trajectory_rate, model_options=_seed_options(seed))
            summaries.append(s)
            if s["error"] is None:
                m = V.measure(V.load_run(out), setup)
                flows.append(m["flow"]["middle"])
                dens.append(m["density"])
        bad = [s for s in summaries if s["error"] is not None or s.get("status") != "finished"]
        s = bad[0] if bad else summaries[0]
        flow = _mean(flows)
        lo, hi, n_pub = V.published_band(b, band_of)
        stuck = max((int(x.get("n_initial") or 0) - int(x.get("n_evacuated") or 0)
                     for x in summaries if x["error"] is None), default=-1)
        row = {"width_m": b, "J": flow, "J_per_b": flow / b, "status": s.get("status"),
               "error": s["error"], "wall_s": float(sum(x["wall_s"] for x in summaries)),
               "err": _rel(flow / b, V.SPECIFIC_BOTTLENECK_FLOW_PER_MS),
               "band": [lo, hi], "band_points": n_pub,
               "in_band": bool(lo <= flow / b <= hi) if math.isfinite(flow) else False,
               "front_density": _mean(dens), "stuck": stuck}
        if len(seeds) > 1:
            row["J_per_b_sims"] = [f / b for f in flows]
            row["front_density_sims"] = [float(d) for d in dens]
        rows.append(row)
        log(f"  {'door in a wall' if opening == 'short' else 'bottleneck'} b = {b:g} m: "
            f"{row['status']}, {row['wall_s']:.1f} s wall"
            + (f" ({row['error']})" if row["error"] else ""))
    return rows


def plot_bottleneck(rows: list[Mapping[str, Any]], path: Path, title: str = "",
                    doors: list[Mapping[str, Any]] | None = None) -> None:
    """``path`` (PNG): the series' J/b and front density against the published points (the
    doors and short openings filled, the long openings open); ``doors``: the doors in a
    thin wall too, against the short openings' band."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.2))
    markers = "osD^v<>ph"
    for k, ser in enumerate(V.published_bottleneck_flows()):
        pts = ser["points"]
        short = ser.get("opening") == "short"
        a1.plot(pts[:, 0], pts[:, 1] / pts[:, 0], markers[k % len(markers)],
                mfc="0.6" if short else "none", color="0.45", ms=5,
                label=f"{ser['label']} ({ser.get('opening', '?')})")
    lo, hi = V.PRESSING_FRONT_DENSITY_PER_M2
    a2.axhspan(lo, hi, color="tab:green", alpha=0.12,
               label="pressing crowds in front of entrances (Adrian et al. 2020)")
    series = [("2.8 m long openings", rows, "tab:red", "tab:green")]
    if doors:
        series.append((f"doors in a {WALL_THICKNESS:g} m wall", doors, "tab:blue", "tab:blue"))
    for label, ser, color, band_color in series:
        b = np.array([r["width_m"] for r in ser])
        band = np.array([r["band"] for r in ser], float)
        a1.fill_between(b, band[:, 0], band[:, 1], color=band_color, alpha=0.12,
                        label=f"published band ({label})")
        a1.plot(b, np.array([r["J_per_b"] for r in ser], float), "-o", color=color, lw=2,
                label=f"pedmesh SFM, {label}")
        a2.plot(b, np.array([r["front_density"] for r in ser], float), "-o", color=color, lw=2,
                label=f"pedmesh SFM, {label}")
    a1.set_xlabel("width b [m]")
    a1.set_ylabel("specific flow J/b [1/(m s)]")
    a1.set_xlim(0.3, 2.8)
    a1.set_ylim(1.0, 3.0)
    a1.legend(fontsize=6, ncol=2)
    a1.grid(alpha=0.3)
    a2.set_xlabel("width b [m]")
    a2.set_ylabel(f"Voronoi density in front [1/m$^2$] ({FRONT_DEPTH:g} m deep)")
    a2.set_ylim(0, 10)
    a2.legend(fontsize=7)
    a2.grid(alpha=0.3)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def free_part(runs_dir: Path, *, overrides=None, preset=None, t_end: float = 600.0,
              trajectory_rate: float = TRAJECTORY_RATE_HZ,
              seeds: Iterable[int | None] = (None,), log=print) -> dict[str, Any]:
    """Mean speed [m/s] of free walkers (one run: three lone walkers have no realisations
    that differ, so only the first of ``seeds`` is used)."""
    out = runs_dir / "free"
    s = run_sfm(free_room(), out, overrides=overrides, preset=preset, t_end=t_end,
                trajectory_rate=trajectory_rate,
                model_options=_seed_options(tuple(seeds)[0]))
    speed, n = math.nan, 0
    if s["error"] is None:
        speed, n = V.mean_speed_in_area(V.load_run(out), FREE_AREA)
    log(f"  free walking: {s.get('status')}, {s['wall_s']:.1f} s wall"
        + (f" ({s['error']})" if s["error"] else ""))
    return {"speed": speed, "samples": n, "status": s.get("status"), "error": s["error"],
            "wall_s": s["wall_s"], "err": _rel(speed, V.FREE_SPEED_MS)}


# --------------------------------------------------------------------------- errors
def errors_of(results: Mapping[str, Any]) -> dict[str, float]:
    """The relative errors (sim / reference - 1) of a :func:`run_validation` result as a
    flat dict of floats, plus ``rms`` (root mean square of the finite ones), ``count`` and
    ``failed`` (runs that did not finish: their errors are nan)."""
    err: dict[str, float] = {}
    failed = 0
    corridor = results.get("corridor")
    if corridor:
        for row in corridor["rows"]:
            failed += row["error"] is not None
            for key in ("J_exit", "J_y0", "density", "speed"):
                err[f"corridor/{row['run']}/{key}"] = row[f"{key}_err"]
        for b in corridor["fd"]:
            if b["n_exp"]:
                err[f"fd/rho={b['density']:g}"] = _rel(b["speed_sim"], b["speed_exp"])
    for row in results.get("bottleneck") or []:
        failed += row["error"] is not None
        err[f"bottleneck/b={row['width_m']:g}"] = row["err"]
    for row in results.get("walldoor") or []:
        failed += row["error"] is not None
        err[f"walldoor/b={row['width_m']:g}"] = row["err"]
    free = results.get("free")
    if free:
        failed += free["error"] is not None
        err["free/speed"] = free["err"]
    finite = np.array([v for v in err.values() if math.isfinite(v)])
    err["rms"] = float(np.sqrt(np.mean(finite ** 2))) if len(finite) else math.nan
    err["count"] = float(len(finite))
    err["failed"] = float(failed)
    return err


def run_validation(overrides: Mapping[str, Any] | None = None, preset: str | None = None, *,
                   parts: Iterable[str] = ("corridor",), data_dir: str | Path | None = None,
                   out_dir: str | Path | None = None, t_end: float = 600.0,
                   trajectory_rate: float = TRAJECTORY_RATE_HZ, fd_frames: str = "all",
                   entrance: str = "door", seeds: Iterable[int | None] = (None,),
                   widths: Iterable[float] = BOTTLENECK_WIDTHS,
                   door_widths: Iterable[float] = WALL_DOOR_WIDTHS,
                   log=print) -> dict[str, Any]:
    """Run the ``parts`` (``corridor``, ``bottleneck``, ``walldoor``, ``free``) with parameter
    ``overrides`` on top of ``preset``; every number, the errors (:func:`errors_of`) and
    the wall time [s]. The runs go to ``out_dir/runs`` (a temporary directory if None).
    ``seeds``: the realisations of every corridor and bottleneck run (None: the
    unjittered lattice and entrance spots); the values are their means, the FD their
    pooled samples. ``widths``, ``door_widths``: the widths [m] of the bottleneck series
    and of the doors in a wall."""
    parts = tuple(parts)
    seeds = tuple(seeds)
    if not seeds:
        raise ValueError("seeds must name at least one realisation")
    unknown = set(parts) - set(PARTS)
    if unknown:
        raise ValueError(f"unknown parts {sorted(unknown)} (parts: {', '.join(PARTS)})")
    data_dir = Path(data_dir) if data_dir is not None else default_data_dir()
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="pedmesh-validation-") as tmp:
        runs = Path(out_dir) / "runs" if out_dir is not None else Path(tmp)
        kw = {"overrides": dict(overrides or {}), "preset": preset, "t_end": t_end,
              "trajectory_rate": trajectory_rate, "seeds": seeds, "log": log}
        results: dict[str, Any] = {
            "preset": preset, "overrides": dict(overrides or {}), "data_dir": str(data_dir),
            "t_end_s": t_end, "trajectory_rate_hz": trajectory_rate, "parts": list(parts),
            "entrance": entrance, "seeds": list(seeds)}
        if "corridor" in parts:
            results["corridor"] = corridor_part(data_dir, runs / "corridor",
                                                fd_frames=fd_frames, entrance=entrance, **kw)
        if "bottleneck" in parts:
            results["bottleneck"] = bottleneck_part(runs / "bottleneck", widths=widths, **kw)
        if "walldoor" in parts:
            results["walldoor"] = bottleneck_part(runs / "walldoor", widths=door_widths,
                                                  opening="short", **kw)
        if "free" in parts:
            results["free"] = free_part(runs / "free", **kw)
    results["errors"] = errors_of(results)
    results["wall_s"] = time.perf_counter() - t0
    return results


def validation_errors(overrides: Mapping[str, Any] | None = None, preset: str | None = None,
                      **kw) -> dict[str, float]:
    """The objective of a parameter fit: the relative errors of :func:`run_validation`
    (same arguments; quiet unless ``log`` is given) as a flat dict of floats."""
    kw.setdefault("log", lambda *a, **k: None)
    return run_validation(overrides, preset, **kw)["errors"]


# --------------------------------------------------------------------------- report
def _f(v: float, fmt: str = ".2f") -> str:
    return "-" if v is None or not math.isfinite(v) else format(v, fmt)


def _pct(v: float) -> str:
    return "-" if v is None or not math.isfinite(v) else f"{100 * v:+.0f}%"


def tables(results: Mapping[str, Any]) -> list[tuple[str, list[str], list[list[str]]]]:
    """The result tables: (title, header, rows of strings)."""
    out = []
    corridor = results.get("corridor")
    if corridor:
        head = ["run", "J exit sim", "J exit exp", "err", "J y0 sim", "J y0 exp", "err",
                "rho sim", "rho exp", "v sim", "v exp", "wall [s]"]
        many = len(corridor.get("seeds", [None])) > 1
        rows = [[r["run"], _f(r["J_exit_sim"]), _f(r["J_exit_exp"]), _pct(r["J_exit_err"]),
                 _f(r["J_y0_sim"]), _f(r["J_y0_exp"]), _pct(r["J_y0_err"]),
                 _f(r["density_sim"]), _f(r["density_exp"]), _f(r["speed_sim"]),
                 _f(r["speed_exp"]), _f(r["wall_s"], ".1f")] for r in corridor["rows"]]
        if many:
            head.insert(4, "err per realisation")
            for row, r in zip(rows, corridor["rows"]):
                row.insert(4, " ".join(_pct(_rel(v, r["J_exit_exp"]))
                                       for v in r["J_exit_sims"]))
        seeds_txt = (f"; mean of realisations {', '.join(map(str, corridor['seeds']))}"
                     if many else "")
        out.append((("Corridor: flow J [1/s], steady-state Voronoi density [1/m^2] and "
                     f"speed [m/s] in (0,-2)-(1.8,0){seeds_txt}"), head, rows))
        head = ["rho [1/m^2]", "v sim", "n sim", "v exp", "n exp", "err", "v Weidmann"]
        rows = [[f"{b['density']:g} +- {FD_HALF_WIDTH:g}", _f(b["speed_sim"]), str(b["n_sim"]),
                 _f(b["speed_exp"]), str(b["n_exp"]), _pct(_rel(b["speed_sim"], b["speed_exp"])),
                 _f(b["speed_weidmann"])]
                for b in corridor["fd"]]
        if many:
            head.insert(6, "err per realisation")
            for row, b in zip(rows, corridor["fd"]):
                row.insert(6, " ".join(_pct(_rel(v, b["speed_exp"])) for v in b["speed_sims"]))
        out.append((f"Pooled Voronoi speed [m/s] by density ({corridor['fd_frames']} frames"
                    f"{seeds_txt})", head, rows))
        if all("speed_sim_paired" in b for b in corridor["fd"]):
            head = ["rho [1/m^2]", "v sim", "v exp", "err", "runs"]
            rows = [[f"{b['density']:g} +- {FD_HALF_WIDTH:g}", _f(b["speed_sim_paired"]),
                     _f(b["speed_exp_paired"]),
                     _pct(_rel(b["speed_sim_paired"], b["speed_exp_paired"])),
                     ", ".join(f"{n}: {_f(r['speed_sim'])} / {_f(r['speed_exp'])}"
                               for n, r in b["runs"].items() if n in b["paired_runs"])]
                    for b in corridor["fd"]]
            out.append(("The same run by run: each run's speed in the bin, simulation / "
                        "experiment, over the runs with at least "
                        f"{FD_PAIR_MIN} samples in both, weighted by the experiment's "
                        "samples (free of how long each run stays in the bin)", head, rows))
    for key, title in (
            ("bottleneck", "Bottleneck series (2.8 m long openings): specific flow against the "
                           "published band (every series' points within 12 % of the width)"),
            ("walldoor", f"Doors in a {WALL_THICKNESS:g} m wall: specific flow against the "
                         "published band of doors and short openings (their points within "
                         "12 % of the width)")):
        series = results.get(key)
        if not series:
            continue
        head = ["b [m]", "J [1/s]", "J/b sim [1/(m s)]", "published J/b", "in band",
                "rho front [1/m^2]", "stuck", "wall [s]"]
        rows = [[f"{r['width_m']:g}", _f(r["J"]), _f(r["J_per_b"]),
                 f"{_f(r['band'][0])}-{_f(r['band'][1])} ({r['band_points']})",
                 "yes" if r["in_band"] else "no", _f(r["front_density"]), str(r["stuck"]),
                 _f(r["wall_s"], ".1f")]
                for r in series]
        if any("J_per_b_sims" in r for r in series):
            head.insert(3, "J/b per realisation")
            for row, r in zip(rows, series):
                row.insert(3, " ".join(_f(v) for v in r.get("J_per_b_sims", [])))
        out.append((f"{title}, Voronoi density in front of the opening, and who was left "
                    "inside", head, rows))
    free = results.get("free")
    if free:
        out.append(("Free walking", ["v sim [m/s]", "v ref [m/s]", "err", "samples", "wall [s]"],
                    [[_f(free["speed"]), _f(V.FREE_SPEED_MS), _pct(free["err"]),
                      str(free["samples"]), _f(free["wall_s"], ".1f")]]))
    return out


def _text_table(head, rows) -> str:
    w = [max(len(str(x)) for x in col) for col in zip(head, *rows)]
    lines = ["  ".join(str(x).rjust(n) for x, n in zip(r, w)) for r in [head, *rows]]
    lines.insert(1, "  ".join("-" * n for n in w))
    return "\n".join(lines)


def _md_table(head, rows) -> str:
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def write_report(results: Mapping[str, Any], out_dir: Path) -> None:
    """``validation.json`` and ``validation.md`` in ``out_dir``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "validation.json").write_text(json.dumps(json_safe(results), indent=1) + "\n")
    md = [(f"# SFM validation (preset {results['preset'] or 'default'}, overrides "
           f"{results['overrides'] or 'none'})"), ""]
    for title, head, rows in tables(results):
        md += [f"## {title}", "", _md_table(head, rows), ""]
    e = results["errors"]
    md += [(f"RMS of {e['count']:.0f} relative errors: {e['rms']:.3f}; failed runs: "
            f"{e['failed']:.0f}; wall time {results['wall_s']:.0f} s."), ""]
    (out_dir / "validation.md").write_text("\n".join(md))
    if results.get("bottleneck"):
        plot_bottleneck(results["bottleneck"], out_dir / "bottleneck.png",
                        f"preset {results['preset'] or 'default'}, overrides "
                        f"{results['overrides'] or 'none'}", doors=results.get("walldoor"))


def main(argv: list[str] | None = None) -> int:
    from pedmesh.parameters import parse_overrides as parse_param_overrides

    ap = argparse.ArgumentParser(prog="python -m pedmesh.fitting.validate",
                                 description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, default=None, metavar="DIR",
                    help="experiments directory with data/*.txt (default: $PEDMESH_EXPERIMENTS "
                         "or <repo>/../shared/experiments)")
    ap.add_argument("--preset", default=None, help="parameter preset (pedmesh presets)")
    ap.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                    help="parameter override (repeatable)")
    ap.add_argument("--out", type=Path, default=Path("runs") / "validation", metavar="DIR")
    ap.add_argument("--bottleneck", action="store_true", help="also the bottleneck widths")
    ap.add_argument("--walldoor", action="store_true",
                    help="also the doors in a thin wall (the short-opening series)")
    ap.add_argument("--free", action="store_true", help="also free walking")
    ap.add_argument("--only-extra", action="store_true",
                    help="skip the corridor runs (with --bottleneck, --walldoor, --free)")
    ap.add_argument("--t-end", type=float, default=600.0, metavar="T",
                    help="simulated time limit per run [s] (default 600)")
    ap.add_argument("--trajectory-rate", type=float, default=10.0, metavar="FPS")
    ap.add_argument("--fd-frames", choices=("steady", "all"), default="all",
                    help="fundamental-diagram samples from every frame (default: the "
                         "experiments reach 3 /m^2 only outside their steady state) or from "
                         "the steady state only")
    ap.add_argument("--entrance", choices=ENTRANCES, default="door",
                    help="the corridor runs' entrance: 'door' (default: the waiting crowd "
                         "and the entrance door of geometries/experiments/) or 'replay' "
                         "(the experiment's measured inflow at y = 7.5 m)")
    ap.add_argument("--seeds", default=None, metavar="S1,S2,...",
                    help="realisations of every corridor and bottleneck run (seeds of the "
                         "start lattice and entrance spots), reported as their mean and "
                         "spread (default: the one unjittered run)")
    args = ap.parse_args(argv)
    seeds: tuple = (None,)
    if args.seeds:
        try:
            seeds = tuple(int(v) for v in args.seeds.split(","))
        except ValueError:
            ap.error(f"--seeds takes integers separated by commas, got {args.seeds!r}")
    parts = [] if args.only_extra else ["corridor"]
    parts += [p for p, on in (("bottleneck", args.bottleneck), ("walldoor", args.walldoor),
                              ("free", args.free)) if on]
    if not parts:
        ap.error("nothing to run (--only-extra needs --bottleneck, --walldoor or --free)")
    warnings.filterwarnings("ignore", module="pedpy")
    results = run_validation(parse_param_overrides(args.param), args.preset, parts=parts,
                             data_dir=args.data, out_dir=args.out, t_end=args.t_end,
                             trajectory_rate=args.trajectory_rate, fd_frames=args.fd_frames,
                             entrance=args.entrance, seeds=seeds)
    print(f"\nSFM validation: preset {args.preset or 'default'}, overrides "
          f"{results['overrides'] or 'none'}")
    for title, head, rows in tables(results):
        print(f"\n{title}\n{_text_table(head, rows)}")
    e = results["errors"]
    print(f"\nRMS of {e['count']:.0f} relative errors {e['rms']:.3f}, failed runs "
          f"{e['failed']:.0f}; total wall time {results['wall_s']:.1f} s")
    write_report(results, args.out)
    print(f"results in {args.out}/validation.json and validation.md")
    return 0


if __name__ == "__main__":
    sys.exit(main())
