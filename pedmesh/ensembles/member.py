"""One member of an ensemble and its folder ``members/<id>/``: the run on a worker
(:func:`run_member`) in a temporary folder that is renamed into place once the run has
ended, the row its ``summary.json`` gives, and the checks and clean-up of member folders
that the client does before the members run (see :mod:`pedmesh.ensembles`)."""

from __future__ import annotations

import errno
import os
import re
import shutil
import time
from pathlib import Path
from typing import Any, Mapping

from ..errors import PedmeshError
from ..mesh.site import mesh_site
from ..run.results import FINISHED_STATUSES
from .plan import TIMES, EnsembleError, Member
from ..io import run_folder as F

#: the values of a member's row that come from its summary.json
_FROM_SUMMARY = ("n_initial", "n_evacuated", *TIMES, "wall_time_s")
#: a member's temporary folder (``<id>.tmp-<pid>-<ns>``) or a replaced run on its way out
#: (``<id>.old-<pid>-<ns>``), next to its own folder in ``members/``
_SCRATCH = re.compile(r"[0-9]+-[0-9]+\.(tmp|old)-[0-9]+-[0-9]+")


# ------------------------------------------------------------------ a member's folder
def _scratch_name(final: Path, kind: str) -> Path:
    return final.with_name(f"{final.name}.{kind}-{os.getpid()}-{time.time_ns()}")


def _not_a_run_folder(folder: Path) -> EnsembleError:
    return EnsembleError(f"{folder}: not a pedmesh run folder; move it away or choose "
                         "another --out")


def summary_row(folder: Path, summary: Mapping[str, Any]) -> dict[str, Any]:
    """The values of a member's row that its run's ``summary`` (in ``folder``) gives:
    status (a killed run reads as ``interrupted``), counts, times, wall time, error, and
    the worker if the summary names it."""
    row: dict[str, Any] = {"status": F.run_status(folder, summary),
                           **{k: summary.get(k) for k in _FROM_SUMMARY},
                           "error": summary.get("error") or ""}
    ens = summary.get("ensemble")
    if isinstance(ens, Mapping) and ens.get("worker"):
        row["worker"] = ens["worker"]
    return row


def existing_run(m: Member) -> tuple[dict | None, bool]:
    """(summary, clear) of member ``m``: the summary of its finished run if its folder
    holds one made with the same settings; else None, and whether its folder holds an
    unfinished run to clear before the member runs again. EnsembleError if its folder
    holds something else, or a run made with other settings."""
    from ..run.results import RunResult

    d = m.out_dir
    if not os.path.lexists(d):
        return None, False
    if d.is_symlink() or not d.is_dir():
        raise _not_a_run_folder(d)
    names = [e.name for e in d.iterdir()]
    if not names:
        return None, True
    s = F.good_summary(d)
    if s is None:
        if names == [F.LOCK] or F.SUMMARY in names:  # a run cut off at its start
            return None, True
        raise _not_a_run_folder(d)
    diff = RunResult(d, s).settings_differences(m.settings)
    if diff:
        what = ", ".join(f"{k} ({there!r} there, {now!r} now)" for k, there, now in diff[:3])
        raise EnsembleError(f"member {m.member}: {d} was made with other settings: {what}; "
                            "use another --out or delete it")
    if F.run_status(d, s) in FINISHED_STATUSES:
        return s, False
    return None, True


def clear_member(folder: Path) -> None:
    """Remove ``folder``, a member's folder that holds a run which did not finish (failed,
    interrupted or cut off), so that a new run can take its place. It is renamed away
    first, so ``folder`` never holds half of it. EnsembleError if it holds anything but a
    pedmesh run's files, or a run that is still writing."""
    if folder.is_symlink() or not folder.is_dir():
        raise _not_a_run_folder(folder)
    s = F.good_summary(folder)
    if (s is not None and F.run_status(folder, s) == "running") or (
            s is None and F.lock_is_held(folder)):
        raise EnsembleError(f"{folder}: another pedmesh run is writing into this folder; "
                            "wait for it or choose another --out")
    names = sorted(e.name for e in folder.iterdir())
    if s is None and names not in ([], [F.LOCK]) and F.SUMMARY not in names:
        raise _not_a_run_folder(folder)
    foreign = [n for n in names if not F.is_run_file(n)]
    if foreign:
        raise EnsembleError(f"{folder / foreign[0]}: not a file of pedmesh's in a member's "
                            "folder that must run again; move it away")
    old = _scratch_name(folder, "old")
    os.rename(folder, old)
    shutil.rmtree(old, ignore_errors=True)


def remove_scratch(members: Path) -> None:
    """Remove the temporary folders of members' attempts that were killed (their lock
    free): a running attempt holds its lock, a killed one no longer does."""
    if not members.is_dir():
        return
    for e in members.iterdir():
        if _SCRATCH.fullmatch(e.name) and e.is_dir() and not e.is_symlink() \
                and F.lock_is_held(e) is False:
            shutil.rmtree(e, ignore_errors=True)


# ------------------------------------------------------------------ on the workers
_ROOMS: dict = {}


def _room_and_mesh(geometry: str, mesh_options: Mapping[str, Any],
                   max_cells: float | None = None):
    """The room and its mesh, built once per worker process and room file contents
    (``max_cells``: the mesher's size limit, None for its default)."""
    from ..io import load_room
    from ..run.output import file_sha256

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


def _finished_run(final: Path, settings: Mapping[str, Any]) -> dict | None:
    """The summary of the finished run in ``final`` if it holds one (EnsembleError if it
    was made with other settings), else None."""
    from ..run.results import RunResult

    s = F.good_summary(final) if final.is_dir() else None
    if s is None or F.run_status(final, s) not in FINISHED_STATUSES:
        return None
    diff = RunResult(final, s).settings_differences(dict(settings))
    if diff:
        raise EnsembleError(f"{final} was made with other settings ({diff[0][0]}); use "
                            "another --out or delete it")
    return s


def _install(tmp: Path, final: Path) -> dict:
    """Rename the ended run in ``tmp`` to ``final`` and return its summary. If ``final``
    already holds a finished run (another attempt of the same member won), that one stays,
    ``tmp`` goes, and its summary is returned; an unfinished run there is replaced."""
    for _ in range(10):
        if not os.path.lexists(final):
            try:
                os.rename(tmp, final)  # atomic; fails if another attempt got there first
            except OSError as exc:
                if exc.errno not in (errno.EEXIST, errno.ENOTEMPTY):
                    raise
                continue
            return F.good_summary(final) or {}
        have = F.good_summary(final) if final.is_dir() else None
        if have is not None and F.run_status(final, have) in FINISHED_STATUSES:
            shutil.rmtree(tmp, ignore_errors=True)
            return have
        try:
            clear_member(final)
        except FileNotFoundError:  # another attempt moved it meanwhile
            continue
    raise EnsembleError(f"{final}: could not put the member's run in place")


def _run_in_temp(task: Mapping[str, Any], final: Path, worker: str) -> dict:
    """Run the member of ``task`` in a temporary folder next to ``final`` and rename it to
    ``final`` once the run has ended with its final summary (see :func:`_install`);
    returns that summary. An interrupted or killed attempt never reaches ``final``."""
    from ..run.driver import RunInterrupted, execute, plan_run
    from ..run.output import RunWriter

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
        s = F.good_summary(tmp)
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

    from ..run.driver import RunInterrupted, run_settings

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
        row.update(summary_row(final, summary))
    except RunInterrupted as exc:
        row.update(status="interrupted", wall_time_s=time.perf_counter() - t0,
                   error=f"interrupted at t = {exc.t:.2f} s; its output was discarded")
    except BaseException as exc:  # recorded, so that the other members go on
        if isinstance(exc, KeyboardInterrupt):
            raise
        msg = str(exc) if isinstance(exc, PedmeshError) else f"{type(exc).__name__}: {exc}"
        row.update(status="failed", error=msg, wall_time_s=time.perf_counter() - t0)
    return row
