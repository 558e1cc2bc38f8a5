"""Ensembles and parameter studies on Dask (:func:`pedmesh.ensemble`): many runs of one
room, from a laptop to a cluster, with the same call.

A social force run is one sample: its start positions are random (see
:func:`pedmesh.models.sfm.placement.seeded_positions`), so an evacuation time means something
only with its spread. :func:`ensemble` runs ``members`` runs that differ by seed at every
point of a parameter grid (``sweep``) and collects them:

* ``DIR/members/<id>/``: ordinary run folders (see :mod:`pedmesh.run.output`), ``<id>`` =
  ``<point>-<member>`` (e.g. ``002-0007``);
* ``DIR/ensemble.csv``: a row per member (member, seed, swept values, status, counts,
  T50/T90/T100 [s], wall time [s], worker address, error), rewritten as members finish;
* ``DIR/ensemble.json``: per sweep point the 5/50/95 percentiles, mean and standard
  deviation of T50, T90 and T100 over its finished members;
* ``DIR/evacuation_bands.png``: the median evacuation curve and its 5-95 % band per point.

Member ``i`` gets the same seed at every sweep point (common random numbers), so the
points are compared on the same start positions. The work goes to a ``dask.distributed``
cluster: by default a ``LocalCluster`` of worker processes with one thread each on this
machine; ``scheduler="tcp://HOST:PORT"`` (or a ``client``) sends it to an existing
cluster, whose workers must see ``DIR`` and the room file at the same paths (a shared file
system, as on HPC clusters).

Members are atomic and idempotent. A member runs in a temporary folder next to its own,
``members/<id>.tmp-<pid>-<ns>/``, renamed to ``members/<id>/`` only once its run has ended
with its final summary (``finished``, ``stopped at t_end``, or ``failed`` with the error),
so ``members/<id>/`` never holds a cut-off run. A member's folder that holds a finished
run is never cleared or run over: a task that Dask computes again (after a worker died)
finds it and returns its summary. A killed attempt's temporary folder is removed when
nobody holds its lock. The rows of ``ensemble.csv`` (status, counts, times, wall time,
worker, error) are read from each member's own ``summary.json``, also after Ctrl-C.

An ensemble owns ``DIR`` as a run owns its folder: it refuses a non-empty folder that is
not a pedmesh ensemble, holds ``DIR/.lock`` while it runs (a second ensemble into the same
folder is an error), and leaves other files alone. Running the same call again skips
finished members, recognised by the settings their run recorded; a member folder recorded
with other settings is an error (nothing is reused silently), and a failed or interrupted
member is run again. A member that raises is recorded as ``failed`` with its error and the
others go on; an interrupted ensemble keeps every finished member.
"""

from __future__ import annotations

import errno
import functools
import itertools
import json
import math
import os
import re
import shutil
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from ._version import __version__
from .errors import ParameterError, PedmeshError
from .run.results import FINISHED_STATUSES
from .mesh.site import check_mesh_size, mesh_site
from .mesh.triangulate import FEATURE_AREA, MAX_AREA, MIN_ANGLE
from .parameters import DEFAULT_T_END_S

__all__ = ["ensemble", "EnsembleError", "member_seeds", "parse_sweep", "run_member"]

#: columns of ensemble.csv before the swept parameters' columns are inserted after "seed"
_COLUMNS = ["member", "point", "seed", "status", "n_initial", "n_evacuated", "t_evac_50",
            "t_evac_90", "t_evac_100", "wall_time_s", "worker", "error"]
_TIMES = ("t_evac_50", "t_evac_90", "t_evac_100")
#: the values of a member's row that come from its summary.json
_FROM_SUMMARY = ("n_initial", "n_evacuated", *_TIMES, "wall_time_s")
#: a member's temporary folder (``<id>.tmp-<pid>-<ns>``) or a replaced run on its way out
#: (``<id>.old-<pid>-<ns>``), next to its own folder in ``members/``
_SCRATCH = re.compile(r"[0-9]+-[0-9]+\.(tmp|old)-[0-9]+-[0-9]+")


class EnsembleError(PedmeshError):
    """An ensemble cannot start (bad options, or member folders made with other settings)."""


def member_seeds(seed: int, members: int) -> list[int]:
    """The seeds of ``members`` members drawn from the ensemble seed ``seed``: independent
    streams (numpy's SeedSequence spawning), the same for the same ``seed``."""
    children = np.random.SeedSequence(int(seed)).spawn(int(members))
    return [int(c.generate_state(1, np.uint32)[0]) for c in children]


def parse_sweep(items: Sequence[str]) -> dict[str, list[Any]]:
    """``["width=0.8,1.2", "dt=0.01"]`` -> ``{"width": [0.8, 1.2], "dt": [0.01]}`` (values
    parsed as ``--param`` values are; a declared parameter's within its physical range)."""
    from .parameters import PARAMETERS, parse_overrides

    out: dict[str, list[Any]] = {}
    for item in items:
        if "=" not in item:
            raise ParameterError(f"--sweep expects NAME=V1,V2,..., got '{item}'")
        name, values = item.split("=", 1)
        name = name.strip()
        vals = [v.strip() for v in values.split(",")]
        if not name or not any(vals):
            raise ParameterError(f"--sweep expects NAME=V1,V2,..., got '{item}'")
        if not all(vals):  # (an empty value is a typo: refused, not dropped)
            raise ParameterError(f"--sweep {name}: value {vals.index('') + 1} of {len(vals)} "
                                 f"is empty in '{item}'")
        if name in out:
            raise ParameterError(f"parameter '{name}' is swept twice")
        out[name] = [parse_overrides([f"{name}={v}"])[name] for v in vals]
        if name in PARAMETERS:  # (refused here, not in every member on the cluster)
            for v in out[name]:
                PARAMETERS[name].check(v)
    return out


@dataclass
class _Member:
    member: str
    point: int
    seed: int
    values: dict
    out_dir: Path
    overrides: dict
    settings: dict = field(default_factory=dict)


# ------------------------------------------------------------------ on the workers
_ROOMS: dict = {}


def _room_and_mesh(geometry: str, mesh_options: Mapping[str, Any],
                   max_cells: float | None = None):
    """The room and its mesh, built once per worker process and room file contents
    (``max_cells``: the mesher's size limit, None for its default)."""
    from .io import load_room
    from .run.output import file_sha256

    key = (geometry, file_sha256(geometry), tuple(sorted(mesh_options.items())))
    if key not in _ROOMS:
        room = load_room(geometry)
        _ROOMS.clear()  # one room at a time is enough for an ensemble
        _ROOMS[key] = (room, mesh_site(room, **dict(mesh_options), max_cells=max_cells))
    return _ROOMS[key]


def _worker_address() -> str:
    try:
        from distributed import get_worker

        return get_worker().address
    except (ImportError, ValueError):
        return "local"


def _scratch_name(final: Path, kind: str) -> Path:
    return final.with_name(f"{final.name}.{kind}-{os.getpid()}-{time.time_ns()}")


def _summary_row(folder: Path, summary: Mapping[str, Any]) -> dict[str, Any]:
    """The values of a member's row that its run's ``summary`` (in ``folder``) gives:
    status (a killed run reads as ``interrupted``), counts, times, wall time, error, and
    the worker if the summary names it."""
    from .run.output import run_status

    row: dict[str, Any] = {"status": run_status(folder, summary),
                           **{k: summary.get(k) for k in _FROM_SUMMARY},
                           "error": summary.get("error") or ""}
    ens = summary.get("ensemble")
    if isinstance(ens, Mapping) and ens.get("worker"):
        row["worker"] = ens["worker"]
    return row


def _finished_run(final: Path, settings: Mapping[str, Any]) -> dict | None:
    """The summary of the finished run in ``final`` if it holds one (EnsembleError if it
    was made with other settings), else None."""
    from .run.output import _read_summary, run_status
    from .run.results import RunResult

    s = _read_summary(final) if final.is_dir() else None
    if s is None or run_status(final, s) not in FINISHED_STATUSES:
        return None
    diff = RunResult(final, s).settings_differences(dict(settings))
    if diff:
        raise EnsembleError(f"{final} was made with other settings ({diff[0][0]}); use "
                            "another --out or delete it")
    return s


def _clear_member(folder: Path) -> None:
    """Remove ``folder``, a member's folder that holds a run which did not finish (failed,
    interrupted or cut off), so that a new run can take its place. It is renamed away
    first, so ``folder`` never holds half of it. EnsembleError if it holds anything but a
    pedmesh run's files, or a run that is still writing."""
    from .run.output import LOCK, _is_run_file, _lock_is_held, _read_summary, run_status

    if folder.is_symlink() or not folder.is_dir():
        raise EnsembleError(f"{folder}: not a pedmesh run folder; move it away or choose "
                            "another --out")
    s = _read_summary(folder)
    if (s is not None and run_status(folder, s) == "running") or (
            s is None and _lock_is_held(folder)):
        raise EnsembleError(f"{folder}: another pedmesh run is writing into this folder; "
                            "wait for it or choose another --out")
    names = sorted(e.name for e in folder.iterdir())
    if s is None and names not in ([], [LOCK]) and "summary.json" not in names:
        raise EnsembleError(f"{folder}: not a pedmesh run folder; move it away or choose "
                            "another --out")
    foreign = [n for n in names if not _is_run_file(n)]
    if foreign:
        raise EnsembleError(f"{folder / foreign[0]}: not a file of pedmesh's in a member's "
                            "folder that must run again; move it away")
    old = _scratch_name(folder, "old")
    os.rename(folder, old)
    shutil.rmtree(old, ignore_errors=True)


def _install(tmp: Path, final: Path) -> dict:
    """Rename the ended run in ``tmp`` to ``final`` and return its summary. If ``final``
    already holds a finished run (another attempt of the same member won), that one stays,
    ``tmp`` goes, and its summary is returned; an unfinished run there is replaced."""
    from .run.output import _read_summary, run_status

    for _ in range(10):
        if not os.path.lexists(final):
            try:
                os.rename(tmp, final)  # atomic; fails if another attempt got there first
            except OSError as exc:
                if exc.errno not in (errno.EEXIST, errno.ENOTEMPTY):
                    raise
                continue
            return _read_summary(final) or {}
        have = _read_summary(final) if final.is_dir() else None
        if have is not None and run_status(final, have) in FINISHED_STATUSES:
            shutil.rmtree(tmp, ignore_errors=True)
            return have
        try:
            _clear_member(final)
        except FileNotFoundError:  # another attempt moved it meanwhile
            continue
    raise EnsembleError(f"{final}: could not put the member's run in place")


def _run_in_temp(task: Mapping[str, Any], final: Path, worker: str) -> dict:
    """Run the member of ``task`` in a temporary folder next to ``final`` and rename it to
    ``final`` once the run has ended with its final summary (see :func:`_install`);
    returns that summary. An interrupted or killed attempt never reaches ``final``."""
    from .run.driver import RunInterrupted, execute, plan_run
    from .run.output import RunWriter, _read_summary

    room, mesh = _room_and_mesh(task["geometry"], task["mesh_options"], task.get("max_cells"))
    plan = plan_run(room, mesh, task["model"], overrides=dict(task["overrides"]),
                    t_end=task["t_end"], geometry=task["geometry"],
                    mesh_options=dict(task["mesh_options"]),
                    model_options=dict(task["model_options"]), preset=task["preset"],
                    max_people=task.get("max_people"))
    header = {**plan.header, "ensemble": {"member": task["member"], "point": task["point"],
                                          "seed": task["seed"], "worker": worker}}
    final.parent.mkdir(parents=True, exist_ok=True)
    tmp = _scratch_name(final, "tmp")
    try:
        writer = RunWriter(tmp, header, exit_names=mesh.exit_names)
        error = None
        try:
            execute(plan, writer, quiet=True, where=str(final))
        except RunInterrupted:
            raise
        except Exception as exc:  # a failed run: its summary says failed, with the error
            error = exc
        s = _read_summary(tmp)
        if s is None or s.get("status") not in (*FINISHED_STATUSES, "failed"):
            raise error or EnsembleError(f"member {task['member']}: its run wrote no final "
                                         "summary")
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return _install(tmp, final)


def run_member(task: Mapping[str, Any]) -> dict[str, Any]:
    """Run one member (on a worker) and return its row; never raises for a failed run.

    Idempotent: if the member's folder already holds its finished run (Dask computes a
    task again when the worker that held its result died), nothing is run and the row of
    that run is returned. Otherwise the run goes to a temporary folder that becomes the
    member's folder when the run has ended (:func:`_run_in_temp`). The row's status,
    counts, times, wall time and error are those of the member's ``summary.json``.

    The member's compiled kernels run on one thread: the workers already keep the cores
    busy, and threads that wait for each other on a busy machine are far slower than one
    (see :data:`pedmesh.models.continuum.solver.PARALLEL_MIN_CELLS`)."""
    import numba

    from .run.driver import RunInterrupted, run_settings

    numba.set_num_threads(1)

    t0 = time.perf_counter()
    worker = _worker_address()
    row: dict[str, Any] = {"member": task["member"], "point": task["point"],
                           "seed": task["seed"], **task["values"], "worker": worker}
    final = Path(task["out_dir"])
    try:
        settings = run_settings(task["model"], overrides=dict(task["overrides"]),
                                t_end=task["t_end"], geometry=task["geometry"],
                                mesh_options=dict(task["mesh_options"]),
                                model_options=dict(task["model_options"]),
                                preset=task["preset"])
        summary = _finished_run(final, settings)
        if summary is None:
            summary = _run_in_temp(task, final, worker)
        row.update(_summary_row(final, summary))
    except RunInterrupted as exc:
        row.update(status="interrupted", wall_time_s=time.perf_counter() - t0,
                   error=f"interrupted at t = {exc.t:.2f} s; its output was discarded")
    except BaseException as exc:  # recorded, so that the other members go on
        if isinstance(exc, KeyboardInterrupt):
            raise
        msg = str(exc) if isinstance(exc, PedmeshError) else f"{type(exc).__name__}: {exc}"
        row.update(status="failed", error=msg, wall_time_s=time.perf_counter() - t0)
    return row


# ------------------------------------------------------------------ on the client
def _plan(geometry: str, model: str, members: int, out: Path, *, overrides: dict,
          sweep: dict[str, list], seed: int, t_end: float, mesh_options: dict,
          preset: str | None, seeded: bool) -> list[_Member]:
    from .run.driver import run_settings

    keys = list(sweep)
    points = list(itertools.product(*(sweep[k] for k in keys))) if keys else [()]
    seeds = member_seeds(seed, members)
    plan = []
    for p, values in enumerate(points):
        vals = dict(zip(keys, values))
        for i in range(members):
            mid = f"{p:03d}-{i:04d}"
            ov = {**overrides, **vals}
            opts = {"seed": seeds[i]} if seeded else {}
            m = _Member(mid, p, seeds[i], vals, out / "members" / mid, ov)
            m.settings = run_settings(model, overrides=ov, t_end=t_end, geometry=geometry,
                                      mesh_options=mesh_options, model_options=opts,
                                      preset=preset)
            plan.append(m)
    return plan


def _existing(m: _Member) -> tuple[dict | None, bool]:
    """(summary, clear) of member ``m``: the summary of its finished run if its folder
    holds one made with the same settings; else None, and whether its folder holds an
    unfinished run to clear before the member runs again. EnsembleError if its folder
    holds something else, or a run made with other settings."""
    from .run.output import LOCK, _read_summary, run_status
    from .run.results import RunResult

    d = m.out_dir
    if not os.path.lexists(d):
        return None, False
    if d.is_symlink() or not d.is_dir():
        raise EnsembleError(f"{d}: not a pedmesh run folder; move it away or choose another "
                            "--out")
    names = [e.name for e in d.iterdir()]
    if not names:
        return None, True
    s = _read_summary(d)
    if s is None:
        if names == [LOCK] or "summary.json" in names:  # a run cut off at its start
            return None, True
        raise EnsembleError(f"{d}: not a pedmesh run folder; move it away or choose another "
                            "--out")
    diff = RunResult(d, s).settings_differences(m.settings)
    if diff:
        what = ", ".join(f"{k} ({there!r} there, {now!r} now)" for k, there, now in diff[:3])
        raise EnsembleError(f"member {m.member}: {d} was made with other settings: {what}; "
                            "use another --out or delete it")
    if run_status(d, s) in FINISHED_STATUSES:
        return s, False
    return None, True


def _stats(values: Sequence[float]) -> dict[str, float | None]:
    v = np.asarray([x for x in values if x is not None and np.isfinite(x)], float)
    if len(v) == 0:
        return {"p5": None, "p50": None, "p95": None, "mean": None, "std": None, "n": 0}
    p5, p50, p95 = np.percentile(v, [5, 50, 95])
    return {"p5": float(p5), "p50": float(p50), "p95": float(p95), "mean": float(v.mean()),
            "std": float(v.std(ddof=1)) if len(v) > 1 else None, "n": int(len(v))}


def _write_csv(path: Path, frame) -> None:
    from .run.output import _atomic_write

    _atomic_write(path, frame.to_csv(index=False))


def _summaries(out: Path, frame, sweep: dict, meta: dict) -> dict:
    points = []
    for p, grp in frame.groupby("point", sort=True):
        done = grp[grp["status"].isin(FINISHED_STATUSES)]
        entry = {"point": int(p), "values": {k: grp.iloc[0][k] for k in sweep},
                 "members": int(len(grp)), "finished": int(len(done)),
                 "failed": int((grp["status"] == "failed").sum())}
        for k in _TIMES:
            entry[k] = _stats(list(done[k]))
        points.append(entry)
    data = {**meta, "points": points}
    from .run.output import _atomic_write, _clean

    _atomic_write(out / "ensemble.json", json.dumps(_clean(data), indent=2) + "\n")
    return data


def _bands(out: Path, frame, sweep: dict) -> Path | None:
    """evacuation_bands.png: median evacuation curve and 5-95 % band per sweep point."""
    from .plotting import _plt
    from .run.results import RunResult

    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 4.5))
    drawn = False
    for p, grp in frame.groupby("point", sort=True):
        curves = []
        for mid, status in zip(grp["member"], grp["status"]):
            if status not in FINISHED_STATUSES:
                continue
            try:
                curves.append(RunResult.load(out / "members" / mid).evacuation)
            except (PedmeshError, OSError, ValueError):
                continue
        if not curves:
            continue
        t_max = max(float(t[-1]) for t, _ in curves)
        grid = np.linspace(0.0, t_max, 600)
        n = np.array([np.interp(grid, t, e) for t, e in curves])
        lo, med, hi = np.percentile(n, [5, 50, 95], axis=0)
        vals = {k: grp.iloc[0][k] for k in sweep}
        label = ", ".join(f"{k}={v:g}" if isinstance(v, (int, float)) else f"{k}={v}"
                          for k, v in vals.items()) or "all members"
        line, = ax.plot(grid, med, label=f"{label} ({len(curves)} runs)")
        ax.fill_between(grid, lo, hi, color=line.get_color(), alpha=0.25, lw=0)
        drawn = True
    if not drawn:
        plt.close(fig)
        return None
    ax.set_xlabel("t [s]")
    ax.set_ylabel("pedestrians out")
    ax.set_title("evacuation: median and 5-95 % band over the members")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path = out / "evacuation_bands.png"
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def ensemble(geometry: str | Path, model: str = "sfm", members: int = 10,
             out: str | Path = "ensemble", *, overrides: Mapping[str, Any] | None = None,
             sweep: Mapping[str, Sequence[Any]] | None = None, seed: int = 0,
             client=None, scheduler: str | None = None, workers: int | None = None,
             t_end: float = DEFAULT_T_END_S, max_area: float = MAX_AREA,
             min_angle: float = MIN_ANGLE, feature_area: float | None = FEATURE_AREA,
             exit_size: float | None = None,
             max_cells: float | None = None,
             preset: str | None = None, quiet: bool = False, max_people: int | None = None):
    """Run an ensemble (see module docstring) and return its members as a pandas
    DataFrame (the rows of ensemble.csv).

    ``client``: a ``dask.distributed.Client`` of your own (left open); otherwise
    ``scheduler`` (an address such as ``tcp://10.0.0.5:8786``) or a new ``LocalCluster``
    with ``workers`` worker processes (default: the number of cores), closed at the end.
    """
    import pandas  # noqa: F401  (the ensemble extra: without it, fail before any work)

    from .models import get_model

    geometry = str(geometry)
    if not Path(geometry).is_file():
        raise EnsembleError(f"{geometry}: no such file")
    entry = get_model(model)
    name = entry.name
    _check_options(entry, members, seed, workers, t_end)
    seeded = entry.random
    sweep, overrides = _checked_sweep(sweep, overrides)
    _check_names(entry, overrides, sweep)
    if client is None:
        _check_scheduler(scheduler)
    mesh_options = {"max_area": max_area, "min_angle": min_angle, "feature_area": feature_area,
                    "exit_size": exit_size}
    preset = _check_room(geometry, preset, mesh_options, max_cells, max_people)
    out = Path(out)
    plan = _plan(geometry, name, members, out, overrides=overrides, sweep=sweep, seed=seed,
                 t_end=t_end, mesh_options=mesh_options, preset=preset, seeded=seeded)
    lock = _claim_ensemble_dir(out)
    try:
        _remove_scratch(out / "members")
        rows, todo = _resume(plan, out)
        frame = functools.partial(_frame, rows, plan,
                                  _COLUMNS[:3] + list(sweep) + _COLUMNS[3:])
        _write_csv(out / "ensemble.csv", frame())
        meta = {"pedmesh_version": __version__, "geometry": geometry, "model": name,
                "members": members, "seed": seed, "overrides": overrides, "sweep": sweep,
                "t_end": t_end, "mesh": mesh_options, "preset": preset}
        if not quiet and len(todo) < len(plan):
            print(f"pedmesh: {len(plan) - len(todo)} of {len(plan)} members already finished "
                  "(skipped)", file=sys.stderr)
        if todo:
            _compute(todo, rows, plan, name, geometry, t_end, mesh_options, preset, seeded,
                     out, frame, client=client, scheduler=scheduler, workers=workers,
                     quiet=quiet, max_cells=max_cells, max_people=max_people)
        _from_folders(rows, plan)
        return _finish(out, frame(), sweep, meta)
    finally:
        try:
            _remove_scratch(out / "members")
        finally:
            lock.close()


def _check_options(entry, members, seed, workers, t_end) -> None:
    """EnsembleError unless ``members`` is a positive integer, ``seed`` a non-negative one,
    ``workers`` None or a positive integer, ``t_end`` a positive number of seconds, and
    ``members`` 1 for a model (registry ``entry``) without random input."""
    if isinstance(members, bool) or not isinstance(members, (int, np.integer)) or members < 1:
        raise EnsembleError(f"members must be a positive integer, got {members!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise EnsembleError(f"seed must be a non-negative integer, got {seed!r}")
    if workers is not None and (not isinstance(workers, (int, np.integer)) or workers < 1):
        raise EnsembleError(f"workers must be a positive integer, got {workers!r}")
    if not (math.isfinite(t_end) and t_end > 0):
        raise EnsembleError(f"t_end must be a positive number of seconds, got {t_end!r}")
    if not entry.random and members > 1:
        raise EnsembleError(f"model '{entry.name}' has no random input: its members would all "
                            "be the same; use members=1 (with a sweep)")


def _checked_sweep(sweep: Mapping[str, Sequence[Any]] | None,
                   overrides: Mapping[str, Any] | None) -> tuple[dict[str, list], dict]:
    """The sweep and the fixed overrides as plain dicts; EnsembleError if a swept parameter
    has no values or is also set."""
    if sweep is not None and not isinstance(sweep, Mapping):
        raise EnsembleError(f"sweep must map parameter names to lists of values, e.g. "
                            f"{{'U_f': [1.2, 1.34]}}; got {type(sweep).__name__} {sweep!r:.40}")
    if overrides is not None and not isinstance(overrides, Mapping):
        raise EnsembleError(f"overrides must map parameter names to values, got "
                            f"{type(overrides).__name__} {overrides!r:.40}")
    for k, v in (sweep or {}).items():
        if isinstance(v, (str, bytes)) or not isinstance(v, (Sequence, np.ndarray)):
            raise EnsembleError(f"sweep of '{k}' must be a list of values, got {v!r:.40}")
    sweep = {k: list(v) for k, v in (sweep or {}).items()}
    for k, v in sweep.items():
        if not v:
            raise EnsembleError(f"sweep of '{k}' has no values")
    overrides = dict(overrides or {})
    both = sorted(set(overrides) & set(sweep))
    if both:
        raise EnsembleError(f"parameter '{both[0]}' is both set and swept")
    return sweep, overrides


def _check_names(entry, overrides: Mapping[str, Any], sweep: Mapping[str, Any]) -> None:
    """EnsembleError naming the first set or swept parameter that model ``entry`` does not
    declare (checked here, before any cluster starts, not in every member)."""
    known = entry.parameter_names
    for what, names in (("swept", sweep), ("set", overrides)):
        unknown = sorted(set(names) - known)
        if unknown:
            raise EnsembleError(f"unknown parameter '{unknown[0]}' ({what}) for model "
                                f"'{entry.name}' (known: {', '.join(sorted(known))})")


def _check_scheduler(scheduler: str | None) -> None:
    """EnsembleError unless ``scheduler`` is None or a Dask address with a host and a port
    (``tcp://HOST:PORT``); checked before anything is written or started."""
    if scheduler is None:
        return
    what = f"scheduler address '{scheduler}'"
    if not isinstance(scheduler, str) or not scheduler.strip():
        raise EnsembleError(f"{what} is empty; give tcp://HOST:PORT")
    try:
        from distributed.comm.addressing import get_address_host_port, parse_address
    except ImportError:
        return  # reported with the install hint when the cluster is needed
    try:
        parse_address(scheduler)
        host, port = get_address_host_port(scheduler)
    except (ValueError, TypeError) as exc:
        raise EnsembleError(f"{what} is not valid ({exc}); give tcp://HOST:PORT") from None
    if not host or not 0 < int(port) < 65536:
        raise EnsembleError(f"{what} is not valid (a host and a port 1-65535 are needed); "
                            "give tcp://HOST:PORT")
    if scheduler.startswith("tcp://") or "://" not in scheduler:
        _probe_scheduler(scheduler, host, int(port))


def _probe_scheduler(scheduler: str, host: str, port: int, timeout: float = 5.0) -> None:
    """EnsembleError at once if nothing listens at ``host:port`` (Dask's own client would
    retry a refused connection until its timeout and then report only that)."""
    import socket

    try:
        with socket.create_connection((host, port), timeout=timeout):
            pass
    except ConnectionRefusedError:
        raise EnsembleError(f"cannot reach the Dask scheduler at {scheduler}: the connection "
                            "was refused (no scheduler listens there; start one with "
                            "'dask scheduler', or leave out --scheduler to use this "
                            "machine)") from None
    except socket.timeout:
        raise EnsembleError(f"cannot reach the Dask scheduler at {scheduler}: no answer "
                            f"within {timeout:g} s (a firewall, or the wrong host)") from None
    except OSError as exc:
        raise EnsembleError(f"cannot reach the Dask scheduler at {scheduler}: "
                            f"{exc.strerror or exc}") from None


def _is_ensemble_dir(d: Path) -> bool:
    """Whether ``d`` holds a pedmesh ensemble: its ensemble.csv (pedmesh's columns) or
    ensemble.json, or nothing but a ``members`` folder."""
    from .run.output import LOCK

    try:
        with open(d / "ensemble.csv", encoding="utf-8") as f:
            if f.readline().startswith(",".join(_COLUMNS[:3]) + ","):
                return True
    except (OSError, ValueError):
        pass
    try:
        data = json.loads((d / "ensemble.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        data = None
    if isinstance(data, dict) and ("pedmesh_version" in data
                                   or {"model", "members", "points"} <= set(data)):
        return True
    names = {e.name for e in d.iterdir()} - {LOCK}
    return names == {"members"} and (d / "members").is_dir()


def _claim_ensemble_dir(out: Path):
    """Make ``out`` this ensemble's (as :func:`pedmesh.run.output.claim_run_dir` does for a
    run): refuse a non-empty folder that is not a pedmesh ensemble, before writing
    anything, and one another ensemble is writing into; returns the held lock file."""
    from .run.output import LOCK, fcntl

    if os.path.lexists(out) and not out.is_dir():
        raise EnsembleError(f"{out}: exists and is not a directory; choose another --out")
    if out.is_dir() and any(e.name != LOCK for e in out.iterdir()) \
            and not _is_ensemble_dir(out):
        raise EnsembleError(f"{out}: not empty and not a pedmesh ensemble directory; choose "
                            "another --out (pedmesh does not write into other files)")
    out.mkdir(parents=True, exist_ok=True)
    lock = open(out / LOCK, "a+")
    if fcntl is not None:
        try:
            fcntl.flock(lock.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            lock.close()
            raise EnsembleError(f"{out}: another pedmesh ensemble is writing into this "
                                "directory; wait for it or choose another --out") from None
    return lock


def _remove_scratch(members: Path) -> None:
    """Remove the temporary folders of members' attempts that were killed (their lock
    free): a running attempt holds its lock, a killed one no longer does."""
    from .run.output import _lock_is_held

    if not members.is_dir():
        return
    for e in members.iterdir():
        if _SCRATCH.fullmatch(e.name) and e.is_dir() and not e.is_symlink() \
                and _lock_is_held(e) is False:
            shutil.rmtree(e, ignore_errors=True)


def _check_room(geometry: str, preset: str | None, mesh_options: Mapping[str, Any],
                max_cells: float | None, max_people: int | None = None) -> str | None:
    """Load the room once on the client, so that a bad room file or an oversized mesh fails
    here and not in every member, and return the preset in use (``preset``, else the room
    file's, else the default)."""
    from .io import load_room
    from .presets import resolve_preset

    from .run.driver import check_crowd

    room = load_room(geometry)
    check_crowd(room, max_people)  # (the crowd limit, --max-people)
    preset = resolve_preset(preset, room)
    check_mesh_size(room, dict(mesh_options), max_cells)
    return preset


def _resume(plan: list[_Member], out: Path) -> tuple[dict[str, dict], list[_Member]]:
    """The first rows of ensemble.csv (members already finished in ``out``, with the
    values of their summaries, the others ``pending``) and the members still to run. The
    folders of members that must run again and hold an unfinished run are cleared, once
    every member's folder has been checked."""
    import pandas as pd

    rows: dict[str, dict] = {}
    todo: list[_Member] = []
    previous: dict[str, dict] = {}
    try:  # the workers of members an earlier pedmesh did not name in their summaries
        old = pd.read_csv(out / "ensemble.csv", dtype=str, keep_default_na=False)
        if {"member", "worker"} <= set(old.columns):
            previous = {str(r["member"]): r for r in old.to_dict("records")}
    except (ValueError, OSError, pd.errors.ParserError):
        previous = {}
    clear = []
    for m in plan:
        done, stale = _existing(m)
        base = {"member": m.member, "point": m.point, "seed": m.seed, **m.values}
        if done is None:
            todo.append(m)
            rows[m.member] = {**base, "status": "pending", "error": ""}
            if stale:
                clear.append(m.out_dir)
        else:
            prev = previous.get(m.member, {})
            rows[m.member] = {**base, "worker": prev.get("worker", ""),
                              **_summary_row(m.out_dir, done)}
    for d in clear:
        _clear_member(d)
    return rows, todo


def _from_folders(rows: dict[str, dict], plan: list[_Member],
                  members: Sequence[_Member] | None = None, *,
                  missing: str | None = None) -> None:
    """Update the rows of ``members`` (default: all of ``plan``) from their folders'
    summaries, so that ensemble.csv says what each member's summary.json says; a member
    without a summary keeps its row, or gets status ``missing`` if that is given and its
    row is still ``submitted`` or ``pending``."""
    from .run.output import _read_summary

    for m in plan if members is None else members:
        s = _read_summary(m.out_dir) if m.out_dir.is_dir() else None
        if s is not None:
            rows[m.member].update(_summary_row(m.out_dir, s))
        elif missing and rows[m.member].get("status") in ("submitted", "pending"):
            rows[m.member].update(status=missing)


def _finish(out: Path, result, sweep: dict, meta: dict):
    """Write the final ensemble.csv, ensemble.json and evacuation_bands.png of the members'
    DataFrame ``result`` to ``out``, and return ``result``."""
    _write_csv(out / "ensemble.csv", result)
    _summaries(out, result, sweep, meta)
    _bands(out, result, sweep)
    return result


def _frame(rows: Mapping[str, dict], plan: list[_Member], columns: list[str]):
    """The current rows of the members in ``plan`` as a DataFrame with ``columns`` (None
    where a row has no value yet)."""
    import pandas as pd

    f = pd.DataFrame([rows[m.member] for m in plan])
    for c in columns:
        if c not in f:
            f[c] = None
    return f[columns]


def _compute(todo, rows, plan, model, geometry, t_end, mesh_options, preset, seeded, out,
             frame, *, client, scheduler, workers, quiet, max_cells=None,
             max_people=None) -> None:
    """Submit the members in ``todo`` and record their rows as they finish, each from the
    member's own summary. A collected result is released at once, so that Dask does not
    compute it again when the worker holding it dies. On Ctrl-C the members not collected
    take their rows from their folders (``interrupted`` where there is none), once before
    and once after the cluster is closed."""
    try:
        from distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise EnsembleError("ensembles need Dask: pip install 'pedmesh[ensemble]'") from None
    from tqdm import tqdm

    own_client = own_cluster = None
    if client is None:
        if scheduler:
            try:
                client = own_client = Client(scheduler, timeout="20s")
            except (OSError, TimeoutError, ValueError) as exc:
                raise EnsembleError(f"cannot reach the Dask scheduler at {scheduler}: "
                                    f"{exc}") from None
        else:
            n = int(workers or os.cpu_count() or 1)
            own_cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                       host="127.0.0.1", dashboard_address="127.0.0.1:0")
            client = own_client = Client(own_cluster)
    interrupted: KeyboardInterrupt | None = None
    pending: dict = {}
    bar = None
    try:
        if not quiet:
            link = getattr(client, "dashboard_link", None)
            n_workers = len(client.scheduler_info().get("workers", {}))
            print(f"pedmesh: {len(todo)} members on {n_workers} Dask worker(s)"
                  + (f"; dashboard {link}" if link else ""), file=sys.stderr)
        tasks = [{"member": m.member, "point": m.point, "seed": m.seed, "values": m.values,
                  "geometry": str(Path(geometry).resolve()), "model": model,
                  "overrides": m.overrides, "t_end": t_end, "out_dir": str(m.out_dir.resolve()),
                  "mesh_options": mesh_options, "preset": preset, "max_cells": max_cells,
                  "max_people": max_people,
                  "model_options": {"seed": m.seed} if seeded else {}} for m in todo]
        for m, t in zip(todo, tasks):
            fut = client.submit(run_member, t, key=f"pedmesh-{m.member}-{time.time_ns()}",
                                pure=False)
            pending[fut] = m
            rows[m.member]["status"] = "submitted"
        bar = tqdm(total=len(pending), unit="run", disable=quiet, file=sys.stderr,
                   desc="ensemble", dynamic_ncols=True)
        for fut in as_completed(list(pending)):
            m = pending.pop(fut)
            try:
                row = fut.result()
            except Exception as exc:  # the worker died under it (too often)
                row = {"status": "failed", "error": f"{type(exc).__name__}: {exc}"}
            fut.release()
            rows[m.member].update({k: v for k, v in row.items() if k != "member"})
            _from_folders(rows, plan, [m])
            _write_csv(out / "ensemble.csv", frame())
            bar.update(1)
            failed = sum(r.get("status") == "failed" for r in rows.values())
            if failed:
                bar.set_postfix_str(f"{failed} failed", refresh=False)
    except KeyboardInterrupt as exc:
        interrupted = exc
        if pending:
            client.cancel(list(pending))
        _from_folders(rows, plan, todo, missing="interrupted")
        _write_csv(out / "ensemble.csv", frame())
    finally:
        if bar is not None:
            bar.close()
        if own_client is not None:
            own_client.close()
        if own_cluster is not None:
            own_cluster.close()
    if interrupted is not None:  # members that ended while the cluster shut down
        _from_folders(rows, plan, todo, missing="interrupted")
        _write_csv(out / "ensemble.csv", frame())
        raise interrupted
