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

The package's modules: :mod:`~pedmesh.ensembles.plan` (seeds, the sweep's grid, the checks
made before anything starts, the claim of ``DIR``), :mod:`~pedmesh.ensembles.member` (one
member's run on a worker and its folder), :mod:`~pedmesh.ensembles.running` (the members
on Dask, resuming) and :mod:`~pedmesh.ensembles.stats` (``ensemble.csv``,
``ensemble.json``, the bands).
"""

from __future__ import annotations

import functools
import sys
from pathlib import Path
from typing import Any, Mapping, Sequence

from .._version import __version__
from ..mesh.triangulate import FEATURE_AREA, MAX_AREA, MIN_ANGLE
from ..parameters import DEFAULT_T_END_S
from .member import remove_scratch, run_member
from .plan import (COLUMNS, EnsembleError, check_names, check_options, check_room,
                   check_scheduler, checked_sweep, claim_ensemble_dir, member_seeds,
                   parse_sweep, plan_members)
from .running import compute, resume, rows_frame, rows_from_folders
from .stats import finish, write_csv
from ..io import run_folder as F

__all__ = ["ensemble", "EnsembleError", "member_seeds", "parse_sweep", "run_member"]

# The public names stay pedmesh.ensembles' own, as before the split into modules: for the
# API documentation (automodule), in tracebacks, and as the name by which Dask pickles
# run_member for its workers (pedmesh.ensembles.run_member, looked up there on unpickling).
for _obj in (EnsembleError, member_seeds, parse_sweep, run_member):
    _obj.__module__ = __name__
del _obj



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

    from ..models import get_model

    geometry = str(geometry)
    if not Path(geometry).is_file():
        raise EnsembleError(f"{geometry}: no such file")
    entry = get_model(model)
    name = entry.name
    check_options(entry, members, seed, workers, t_end)
    seeded = entry.random
    sweep, overrides = checked_sweep(sweep, overrides)
    check_names(entry, overrides, sweep)
    if client is None:
        check_scheduler(scheduler)
    mesh_options = {"max_area": max_area, "min_angle": min_angle, "feature_area": feature_area,
                    "exit_size": exit_size}
    preset = check_room(geometry, preset, mesh_options, max_cells, max_people)
    out = Path(out)
    plan = plan_members(geometry, name, members, out, overrides=overrides, sweep=sweep,
                        seed=seed, t_end=t_end, mesh_options=mesh_options, preset=preset,
                        seeded=seeded)
    lock = claim_ensemble_dir(out)
    try:
        remove_scratch(out / F.ENSEMBLE_MEMBERS)
        rows, todo = resume(plan, out)
        frame = functools.partial(rows_frame, rows, plan,
                                  COLUMNS[:3] + list(sweep) + COLUMNS[3:])
        write_csv(out / F.ENSEMBLE_CSV, frame())
        meta = {"pedmesh_version": __version__, "geometry": geometry, "model": name,
                "members": members, "seed": seed, "overrides": overrides, "sweep": sweep,
                "t_end": t_end, "mesh": mesh_options, "preset": preset}
        if not quiet and len(todo) < len(plan):
            print(f"pedmesh: {len(plan) - len(todo)} of {len(plan)} members already finished "
                  "(skipped)", file=sys.stderr)
        if todo:
            compute(todo, rows, plan, name, geometry, t_end, mesh_options, preset, seeded,
                    out, frame, client=client, scheduler=scheduler, workers=workers,
                     quiet=quiet, max_cells=max_cells, max_people=max_people)
        rows_from_folders(rows, plan)
        return finish(out, frame(), sweep, meta)
    finally:
        try:
            remove_scratch(out / F.ENSEMBLE_MEMBERS)
        finally:
            lock.close()
