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

Running the same call again skips finished members, recognised by the settings their
run recorded; a member folder recorded with other settings is an error (nothing is
reused silently), and a failed or interrupted member is run again. A member that raises
is recorded as ``failed`` with its error and the others go on; an interrupted ensemble
keeps every finished member.
"""

from __future__ import annotations

import functools
import itertools
import json
import math
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from .errors import ParameterError, PedmeshError
from .run.results import FINISHED_STATUSES
from .mesh.triangulate import FEATURE_AREA, MAX_AREA, MIN_ANGLE, triangulate
from .parameters import DEFAULT_T_END_S

__all__ = ["ensemble", "EnsembleError", "member_seeds", "parse_sweep"]

#: columns of ensemble.csv before the swept parameters' columns are inserted after "seed"
_COLUMNS = ["member", "point", "seed", "status", "n_initial", "n_evacuated", "t_evac_50",
            "t_evac_90", "t_evac_100", "wall_time_s", "worker", "error"]
_TIMES = ("t_evac_50", "t_evac_90", "t_evac_100")


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
        _ROOMS[key] = (room, triangulate(room, **dict(mesh_options), max_cells=max_cells))
    return _ROOMS[key]


def _worker_address() -> str:
    try:
        from distributed import get_worker

        return get_worker().address
    except (ImportError, ValueError):
        return "local"


def run_member(task: Mapping[str, Any]) -> dict[str, Any]:
    """Run one member (on a worker) and return its row; never raises for a failed run.
    The member's compiled kernels run on one thread: the workers already keep the cores
    busy, and threads that wait for each other on a busy machine are far slower than one
    (see :data:`pedmesh.models.continuum.solver.PARALLEL_MIN_CELLS`)."""
    import numba

    from .run import run_model

    numba.set_num_threads(1)

    t0 = time.perf_counter()
    row: dict[str, Any] = {"member": task["member"], "point": task["point"],
                           "seed": task["seed"], **task["values"],
                           "worker": _worker_address()}
    try:
        room, mesh = _room_and_mesh(task["geometry"], task["mesh_options"],
                                    task.get("max_cells"))
        s = run_model(room, mesh, task["model"], overrides=dict(task["overrides"]),
                      t_end=task["t_end"], out_dir=task["out_dir"], quiet=True,
                      geometry=task["geometry"], mesh_options=dict(task["mesh_options"]),
                      model_options=dict(task["model_options"]), preset=task["preset"])
        row.update({k: s.get(k) for k in ("status", "n_initial", "n_evacuated", *_TIMES)})
        row["wall_time_s"] = s.get("wall_time_s")
        row["error"] = ""
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


def _existing(m: _Member) -> dict | None:
    """The finished run of member ``m`` if its folder holds one made with the same
    settings; None if it must run; EnsembleError if its folder holds something else."""
    from .run.results import RunResult

    d = m.out_dir
    if not d.exists() or not any(d.iterdir()):
        return None
    if not (d / "summary.json").exists():
        if [e.name for e in d.iterdir()] == [".lock"]:
            return None
        raise EnsembleError(f"{d}: not a pedmesh run folder; move it away or choose another "
                            "--out")
    res = RunResult.load(d)
    diff = res.settings_differences(m.settings)
    if diff:
        what = ", ".join(f"{k} ({there!r} there, {now!r} now)" for k, there, now in diff[:3])
        raise EnsembleError(f"member {m.member}: {d} was made with other settings: {what}; "
                            "use another --out or delete it")
    if not res.finished:
        return None
    s = res.summary
    return {"status": res.status, **{k: s.get(k) for k in ("n_initial", "n_evacuated",
                                                             *_TIMES, "wall_time_s")}}


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
             preset: str | None = None, quiet: bool = False):
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
    mesh_options = {"max_area": max_area, "min_angle": min_angle, "feature_area": feature_area,
                    "exit_size": exit_size}
    preset = _check_room(geometry, preset, mesh_options, max_cells)
    out = Path(out)
    plan = _plan(geometry, name, members, out, overrides=overrides, sweep=sweep, seed=seed,
                 t_end=t_end, mesh_options=mesh_options, preset=preset, seeded=seeded)
    rows, todo = _resume(plan, out)
    out.mkdir(parents=True, exist_ok=True)
    frame = functools.partial(_frame, rows, plan, _COLUMNS[:3] + list(sweep) + _COLUMNS[3:])
    _write_csv(out / "ensemble.csv", frame())
    meta = {"geometry": geometry, "model": name, "members": members, "seed": seed,
            "overrides": overrides, "sweep": sweep, "t_end": t_end, "mesh": mesh_options,
            "preset": preset}
    if not quiet and len(todo) < len(plan):
        print(f"pedmesh: {len(plan) - len(todo)} of {len(plan)} members already finished "
              "(skipped)", file=sys.stderr)
    if todo:
        _compute(todo, rows, plan, name, geometry, t_end, mesh_options, preset, seeded, out,
                 frame, client=client, scheduler=scheduler, workers=workers, quiet=quiet,
                 max_cells=max_cells)
    return _finish(out, frame(), sweep, meta)


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
    sweep = {k: list(v) for k, v in (sweep or {}).items()}
    for k, v in sweep.items():
        if not v:
            raise EnsembleError(f"sweep of '{k}' has no values")
    overrides = dict(overrides or {})
    both = sorted(set(overrides) & set(sweep))
    if both:
        raise EnsembleError(f"parameter '{both[0]}' is both set and swept")
    return sweep, overrides


def _check_room(geometry: str, preset: str | None, mesh_options: Mapping[str, Any],
                max_cells: float | None) -> str | None:
    """Load the room once on the client, so that a bad room file or an oversized mesh fails
    here and not in every member, and return the preset in use (``preset``, else the room
    file's, else the default)."""
    from .io import load_room
    from .presets import resolve_preset

    room = load_room(geometry)
    preset = resolve_preset(preset, room)
    _check_mesh_size(room, mesh_options, max_cells)
    return preset


def _resume(plan: list[_Member], out: Path) -> tuple[dict[str, dict], list[_Member]]:
    """The first rows of ensemble.csv (members already finished in ``out`` with their
    results and the worker recorded in an earlier ensemble.csv, the others ``pending``)
    and the members still to run."""
    import pandas as pd

    rows: dict[str, dict] = {}
    todo: list[_Member] = []
    previous = {}
    if (out / "ensemble.csv").exists():
        try:
            old = pd.read_csv(out / "ensemble.csv", dtype={"member": str}, keep_default_na=False)
            previous = {str(r["member"]): r for r in old.to_dict("records")}
        except (ValueError, OSError):
            previous = {}
    for m in plan:
        done = _existing(m)
        base = {"member": m.member, "point": m.point, "seed": m.seed, **m.values}
        if done is None:
            todo.append(m)
            rows[m.member] = {**base, "status": "pending", "error": ""}
        else:
            prev = previous.get(m.member, {})
            rows[m.member] = {**base, **done, "worker": prev.get("worker", ""), "error": ""}
    return rows, todo


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


def _check_mesh_size(room, mesh_options: Mapping[str, Any], max_cells: float | None) -> None:
    """The mesher's size check, on the estimate, before any member is sent out."""
    from .errors import MeshError
    from .mesh.triangulate import MAX_CELLS, check_max_cells, estimate_cells, size_fields

    check_max_cells(max_cells)
    limit = MAX_CELLS if max_cells is None else max_cells
    if not math.isfinite(limit) or not (mesh_options["max_area"] > 0):
        return  # no limit, or a bad max_area that the mesher reports itself
    fields = size_fields(room, feature_area=mesh_options.get("feature_area"),
                         exit_size=mesh_options.get("exit_size") if room.exits else None,
                         max_area=mesh_options["max_area"])
    n = estimate_cells(room, mesh_options["max_area"], fields)
    if n > limit:
        raise MeshError(f"the members' mesh would have about {n:,.0f} triangles, more than "
                        f"the limit of {limit:,.0f}; use a larger max_area, or raise the limit "
                        "(--max-cells N)")


def _compute(todo, rows, plan, model, geometry, t_end, mesh_options, preset, seeded, out,
             frame, *, client, scheduler, workers, quiet, max_cells=None) -> None:
    """Submit the members in ``todo`` and record their rows as they finish."""
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
            except (OSError, TimeoutError) as exc:
                raise EnsembleError(f"cannot reach the Dask scheduler at {scheduler}: "
                                    f"{exc}") from None
        else:
            n = int(workers or os.cpu_count() or 1)
            own_cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                       host="127.0.0.1", dashboard_address="127.0.0.1:0")
            client = own_client = Client(own_cluster)
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
                  "model_options": {"seed": m.seed} if seeded else {}} for m in todo]
        futures = [client.submit(run_member, t, key=f"pedmesh-{m.member}-{time.time_ns()}",
                                 pure=False) for m, t in zip(todo, tasks)]
        for m in todo:
            rows[m.member]["status"] = "submitted"
        bar = tqdm(total=len(futures), unit="run", disable=quiet, file=sys.stderr,
                   desc="ensemble", dynamic_ncols=True)
        try:
            for fut in as_completed(futures):
                try:
                    row = fut.result()
                except Exception as exc:  # the worker died under it
                    row = {"member": _member_of(fut, todo, futures), "status": "failed",
                           "error": f"{type(exc).__name__}: {exc}"}
                rows[row["member"]].update(row)
                _write_csv(out / "ensemble.csv", frame())
                bar.update(1)
                failed = sum(r.get("status") == "failed" for r in rows.values())
                if failed:
                    bar.set_postfix_str(f"{failed} failed", refresh=False)
        except KeyboardInterrupt:
            client.cancel(futures)
            for m in todo:
                if rows[m.member]["status"] == "submitted":
                    rows[m.member]["status"] = "interrupted"
            _write_csv(out / "ensemble.csv", frame())
            raise
        finally:
            bar.close()
    finally:
        if own_client is not None:
            own_client.close()
        if own_cluster is not None:
            own_cluster.close()


def _member_of(fut, todo, futures) -> str:
    return todo[futures.index(fut)].member
