"""Run any registered model through the shared output contract, with a progress bar."""

from __future__ import annotations

import contextlib
import math
import sys
import time
from pathlib import Path
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from .._version import __version__
from .. import parameters as P
from ..parameters import DEFAULT_T_END_S
from .._signals import request_stop, stop_on_signals, stop_requested
from ..errors import ParameterError, PedmeshError, SimulationError
from ..models import CONTINUUM, DenseFrames, ModelEntry, get_model
from .background import BackgroundWriter, use_background
from ..io.run_folder import json_safe
from .output import RunWriter, file_sha256
from ..models.protocol import RunModel

__all__ = ["run_model", "build_model", "plan_run", "execute", "RunPlan", "run_settings",
           "resolve_parameters", "check_options", "check_room_mesh", "check_crowd",
           "MAX_PEOPLE", "MAX_STEPS", "RunInterrupted", "request_stop", "stop_requested",
           "stop_on_signals"]

#: [ped] the largest crowd a run takes unless told otherwise (``--max-people``,
#: ``max_people=`` in Python): a start area with a typo in its spacing or count would
#: otherwise allocate gigabytes before anything is written
MAX_PEOPLE = 1_000_000
#: the most time steps a run takes unless told otherwise (``--max-steps``, ``max_steps=`` in
#: Python): a t_end or dt off by powers of ten would otherwise start a run that never ends
#: (10 million steps: about 3 h at 1 ms a step; Example 2 takes 12,000)
MAX_STEPS = 10_000_000


class RunInterrupted(PedmeshError, KeyboardInterrupt):
    """A run stopped by Ctrl-C or SIGTERM; the output written so far is kept.

    It is a :class:`KeyboardInterrupt` (what caused it), so a script's ``except
    KeyboardInterrupt`` sees it, and a :class:`~pedmesh.errors.PedmeshError`. ``t`` [s]:
    the time reached; ``out_dir``: where the results are; ``result``: the partial result
    (set by :func:`pedmesh.simulate`: the in-memory result, or the run folder's
    :class:`~pedmesh.run.results.RunResult`; None elsewhere)."""

    def __init__(self, t: float, out_dir: Path | str, result: Any = None) -> None:
        super().__init__(f"interrupted at t = {t:.2f} s; results up to then are in {out_dir}")
        self.t = t
        self.out_dir = out_dir
        self.result = result


def run_settings(model: str, *, overrides: Mapping[str, Any] | None = None, t_end: float,
                 geometry: str | None = None, mesh_options: Mapping[str, Any] | None = None,
                 model_options: Mapping[str, Any] | None = None,
                 preset: str | None = None) -> dict[str, Any]:
    """What a run was asked to do, as recorded in its summary (``settings``) and compared
    by ``pedmesh compare`` before it reuses a run: the room file's SHA-256, the model, the
    parameter preset and overrides, t_end [s], the mesh and model options, and the pedmesh
    version."""
    room_hash = None
    if geometry is not None and Path(geometry).is_file():
        room_hash = file_sha256(geometry)
    return json_safe({
        "room_sha256": room_hash,
        "model": model,
        "preset": preset,
        "overrides": dict(sorted((overrides or {}).items())),
        "t_end": float(t_end),
        "mesh": dict(sorted((mesh_options or {}).items())),
        "model_options": dict(sorted((model_options or {}).items())),
        "pedmesh_version": __version__,
    })


def resolve_parameters(entry: ModelEntry, room, *, preset: str | None = None,
                       overrides: Mapping[str, Any] | None = None) -> tuple[str, dict]:
    """The preset a run of ``entry`` uses (asked for, else the room file's, else the default)
    and its parameters: the preset's values for those the model has, the ``overrides`` on
    top."""
    from ..presets import preset_overrides, resolve_preset

    preset = resolve_preset(preset, room)
    return preset, preset_overrides(preset, entry.parameter_names, dict(overrides or {}),
                                    continuum=entry.scale == CONTINUUM)


def check_crowd(room, max_people: int | None = None) -> float:
    """The number of people the room's start areas hold (estimated from their areas,
    before anyone is placed: :attr:`pedmesh.geometry.StartArea.expected_count`); a one-line
    error if it is above ``max_people`` (None: :data:`MAX_PEOPLE`)."""
    limit = MAX_PEOPLE if max_people is None else max_people
    if isinstance(limit, bool) or not isinstance(limit, (int, np.integer)) or limit < 1:
        raise ParameterError(f"max_people must be a positive whole number, got {limit!r}")
    if room is None:
        return 0.0
    areas = getattr(room, "start_areas", ())
    n = float(sum(a.expected_count for a in areas))
    if n > limit:
        big = max(areas, key=lambda a: a.expected_count)
        most = (f" (start area '{big.name}': {big.expected_count:.3g})" if len(areas) > 1
                else "")
        raise ParameterError(
            f"the start areas hold about {n:.3g} people{most}, more than the limit of "
            f"{int(limit):,}; give --max-people N (max_people=N in Python) to run a crowd "
            f"this large")
    return n


def check_steps(t_end: float, parameters: Mapping[str, Any],
                max_steps: int | None = None) -> float:
    """The number of time steps ``t_end`` [s] takes at the run's fixed time step ``dt`` [s]
    (a continuum's step follows its CFL condition: 0, not checked); a one-line error if it
    is above ``max_steps`` (None: :data:`MAX_STEPS`)."""
    limit = MAX_STEPS if max_steps is None else max_steps
    if isinstance(limit, bool) or not isinstance(limit, (int, np.integer)) or limit < 1:
        raise ParameterError(f"max_steps must be a positive whole number, got {limit!r}")
    dt = parameters.get("dt")
    if isinstance(dt, bool) or not isinstance(dt, (int, float, np.floating)) or not dt > 0:
        return 0.0
    steps = float(t_end) / float(dt)
    if steps > limit:
        raise ParameterError(
            f"t_end {t_end:g} s at dt {dt:g} s is {steps:.3g} time steps, more than the limit "
            f"of {int(limit):,}; lower t_end (--t-end) or raise dt, or give --max-steps N "
            "(max_steps=N in Python) to run this long")
    return steps


def check_way_out(room) -> None:
    """A one-line :class:`~pedmesh.errors.GeometryError` naming a start area (and its
    level) whose people can never leave: a room without exits, a level with no stair to an
    exit (:meth:`pedmesh.geometry.Building.no_way_out`)."""
    from ..errors import GeometryError

    if room is None or not getattr(room, "start_areas", ()):
        return
    stuck = room.no_way_out()
    if stuck:
        level, area, why = stuck[0]
        where = f"level '{level}': " if level is not None else ""
        more = f" (and {len(stuck) - 1} more start area(s))" if len(stuck) > 1 else ""
        raise GeometryError(f"{where}start area '{area}': its people can never leave: "
                            f"{why}{more}")


def check_options(entry: ModelEntry, options: Mapping[str, Any]) -> None:
    """A one-line error for a model option the model does not take."""
    unknown = sorted(set(options) - entry.options)
    if unknown:
        raise ParameterError(f"model '{entry.name}' takes no option '{unknown[0]}'"
                             + (f" (options: {', '.join(sorted(entry.options))})"
                                if entry.options else ""))


def check_room_mesh(room, mesh) -> None:
    """A one-line :class:`~pedmesh.errors.ParameterError` unless ``mesh`` is a mesh of
    ``room``: the room's fingerprint (:func:`pedmesh.mesh.triangle_mesh.room_fingerprint`)
    must be the one kept in the mesh; a mesh made without a room must have the room's
    exits and walkable area."""
    from ..geometry.site import is_building
    from ..mesh import SurfaceMesh

    if room is not None and is_building(room) != isinstance(mesh, SurfaceMesh):
        what = "a building's surface mesh" if isinstance(mesh, SurfaceMesh) else "a room's mesh"
        raise ParameterError(f"the mesh given is {what}, not a mesh of "
                             f"{'building' if is_building(room) else 'room'} '{room.name}'; "
                             "leave out mesh= (pedmesh meshes it), or mesh it with "
                             "pedmesh.mesh.site.mesh_site")
    if room is None or not hasattr(room, "boundary_rings"):
        return
    from ..mesh.triangle_mesh import room_fingerprint

    have = getattr(mesh, "room_fingerprint", None)
    made_of = getattr(getattr(mesh, "room", None), "name", None)
    if have is not None:
        if have != room_fingerprint(room):
            of = f"room '{made_of}'" if made_of is not None else "another room"
            raise ParameterError(f"the mesh was made from {of}, not from room '{room.name}' "
                                 "(their walls, obstacles or exits differ); triangulate "
                                 "this room for it")
        return
    if tuple(getattr(mesh, "exit_names", ())) != tuple(room.exit_names):
        raise ParameterError(f"the mesh's exits {list(mesh.exit_names)} are not those of "
                             f"room '{room.name}' {list(room.exit_names)}; triangulate this "
                             "room for it")
    areas = getattr(mesh, "areas", None)
    if areas is not None and not math.isclose(float(np.sum(areas)), room.area, rel_tol=1e-6):
        raise ParameterError(f"the mesh covers {float(np.sum(areas)):.6g} m^2, room "
                             f"'{room.name}' {room.area:.6g} m^2: not a mesh of this room; "
                             "triangulate this room for it")


def build_model(room, mesh, model: str, *, preset: str | None = None,
                overrides: Mapping[str, Any] | None = None, max_people: int | None = None,
                **options: Any) -> RunModel:
    """The stepping form: model ``model`` built on ``mesh`` with its preset's parameters and
    ``overrides``, ready for ``step()`` (:class:`~pedmesh.models.protocol.RunModel`); nothing
    is written. ``options``: the model options its registry entry lists (e.g. ``seed``).
    ``max_people``: the largest crowd taken (:func:`check_crowd`)."""
    entry = get_model(model)
    check_options(entry, options)
    check_room_mesh(room, mesh)
    check_crowd(room if room is not None else getattr(mesh, "room", None), max_people)
    _, parameters = resolve_parameters(entry, room, preset=preset, overrides=overrides)
    return _build(entry, room, mesh, parameters, options)


def _build(entry: ModelEntry, room, mesh, parameters: Mapping[str, Any],
           options: Mapping[str, Any]) -> RunModel:
    """The model's run object, checked against the run protocol."""
    run = entry.build(room, mesh, parameters, **options)
    if not isinstance(run, RunModel):
        raise TypeError(f"model '{entry.name}' does not implement "
                        "pedmesh.models.protocol.RunModel")
    return run


def run_model(room, mesh, model: str, *, overrides: dict[str, float] | None = None,
              t_end: float = DEFAULT_T_END_S, out_dir: str | Path = "run", quiet: bool = False,
              geometry: str | None = None, mesh_options: dict[str, Any] | None = None,
              model_options: dict[str, Any] | None = None,
              preset: str | None = None, max_people: int | None = None,
              safety: bool = True, max_steps: int | None = None) -> dict[str, Any]:
    """Run ``model`` on ``mesh`` until everyone has left or ``t_end`` [s].

    The run owns ``out_dir`` (see :mod:`pedmesh.run.output`): it refuses a non-empty
    directory that is not a pedmesh run and one another run is writing into, removes an
    earlier run's files, and writes its output as it goes. Returns the final summary.
    Raises :class:`RunInterrupted` on Ctrl-C or :func:`request_stop`,
    :class:`~pedmesh.errors.SimulationError` on a blow-up, and whatever else stopped the
    run (a bad parameter while the model is built, a full disk); in every case the summary
    is written first, with status ``interrupted`` or ``failed`` and the error. A crowd
    above ``max_people`` (:func:`check_crowd`) is refused before anything is written.
    ``safety``: compute the crowd-safety measures at the end (see :class:`RunPlan`).
    More time steps than ``max_steps`` (:func:`check_steps`) are refused the same way.
    """
    out = Path(out_dir)
    plan = plan_run(room, mesh, model, overrides=overrides, t_end=t_end, geometry=geometry,
                    mesh_options=mesh_options, model_options=model_options, preset=preset,
                    max_people=max_people, safety=safety, max_steps=max_steps)
    writer = RunWriter(out, plan.header, exit_names=mesh.exit_names)
    return execute(plan, writer, quiet=quiet, where=str(out))


@dataclass(frozen=True)
class RunPlan:
    """What a run will do, checked before anything is written: the model's entry, its
    parameters and options, the end time [s] and the summary's header."""

    entry: ModelEntry
    room: Any
    mesh: Any
    parameters: dict
    options: dict
    t_end: float
    header: dict
    #: compute the crowd-safety measures at the end (summary.json "safety", safety.vtu);
    #: off for the measurement runs of calibrations and fits, whose folders are scratch
    safety: bool = True


def plan_run(room, mesh, model: str, *, overrides: Mapping[str, Any] | None = None,
             t_end: float = DEFAULT_T_END_S, geometry: str | None = None,
             mesh_options: Mapping[str, Any] | None = None,
             model_options: Mapping[str, Any] | None = None,
             preset: str | None = None, max_people: int | None = None,
             safety: bool = True, max_steps: int | None = None) -> RunPlan:
    """Check a run's request and resolve its parameters (see :func:`run_model`); the crowd's
    size is checked against ``max_people`` (:func:`check_crowd`) before anything big is
    allocated."""
    if stop_requested():  # asked to stop before this run began (e.g. between compared models)
        raise KeyboardInterrupt
    if not (math.isfinite(t_end) and t_end > 0):
        raise ParameterError(f"t_end must be a positive number of seconds, got {t_end!r}")
    site = room if room is not None else getattr(mesh, "room", None)
    check_crowd(site, max_people)
    check_way_out(site)
    entry = get_model(model)
    check_room_mesh(room, mesh)
    overrides = dict(overrides or {})
    # the settings record the preset's name and the overrides
    preset, parameters = resolve_parameters(entry, room, preset=preset, overrides=overrides)
    check_steps(t_end, parameters, max_steps)
    model_options = dict(model_options or {})
    check_options(entry, model_options)
    if site is not None and site.seed is not None and "seed" in entry.options:
        model_options.setdefault("seed", site.seed)  # (the room file's, unless told one)
    header = {
        "model": entry.name,
        "geometry": geometry,
        "room": room.name if room is not None else None,
        "mesh": {"vertices": mesh.n_points, "triangles": mesh.n_triangles,
                 **(mesh_options or {})},
        "t_end": t_end,
        "settings": run_settings(entry.name, overrides=overrides, t_end=t_end,
                                 geometry=geometry, mesh_options=mesh_options,
                                 model_options=model_options, preset=preset),
    }
    return RunPlan(entry, room, mesh, parameters, model_options, float(t_end), header,
                   safety=safety)


def _progress_bar(name: str, n_people: float, quiet: bool):
    """The run's progress bar (:func:`pedmesh.run.progress.progress_bar`)."""
    from .progress import progress_bar

    return progress_bar(name, n_people, quiet)


def execute(plan: RunPlan, writer, *, quiet: bool = False, where: str = "the output") -> dict:
    """Build the planned model and run it to the end, writing through ``writer`` (a
    :class:`~pedmesh.run.output.RunWriter`, or an in-memory one with the same methods);
    returns the final summary. ``where`` names the output in messages. The summary is
    written in every case, with status ``interrupted`` or ``failed`` and the error."""
    t_wall0 = time.perf_counter()
    name = plan.entry.name
    run: RunModel | None = None
    bar = None
    frame = 0
    status, error = "failed", None
    kept = None
    try:
        run = _build(plan.entry, plan.room, plan.mesh, plan.parameters, plan.options)
        params = run.parameters()
        # the units of the declared parameters (pedmesh.parameters), for the reader
        extra: dict[str, Any] = {"parameters": params, "units": {
            k: P.PARAMETERS[k].unit for k in params if k in P.PARAMETERS}}
        if run.warnings:
            extra["warnings"] = list(run.warnings)
            for w in run.warnings:
                print(f"pedmesh: warning: {w}", file=sys.stderr)
        if use_background(plan.parameters.get("threads"), writer):
            writer = BackgroundWriter(writer)  # (the steps on threads, the output beside)
        writer.start(extra)
        bar = _progress_bar(name, run.n_initial, quiet)
        if plan.safety and getattr(writer, "dir", None) is not None:
            kept = _safety_kept()  # (the density frames for the measures, as written)
            loop_writer = _KeepDensity(writer, kept) if kept is not None else writer
        else:
            loop_writer = writer
        with _stepping(run):
            frame = _loop(run, loop_writer, plan.t_end, bar)
        if isinstance(writer, BackgroundWriter):
            writer.drain()  # (a write error is the run's)
        status = "finished" if run.done else "stopped at t_end"
    except KeyboardInterrupt:
        status = "interrupted"
        raise RunInterrupted(run.t if run is not None else 0.0, where) from None
    except SimulationError as exc:
        error = str(exc)
        raise SimulationError(f"{error} (results up to then are in {where})") from None
    except BaseException as exc:
        error = str(exc) if isinstance(exc, PedmeshError) else f"{type(exc).__name__}: {exc}"
        raise
    finally:
        if bar is not None:
            bar.close()
        wall = time.perf_counter() - t_wall0  # (the run's, without the safety measures)
        result: dict[str, Any] = {}
        if run is not None:
            try:
                result = dict(run.summary())
            except Exception as exc:  # the summary of a broken run: keep what we know
                result = {"summary_error": f"{type(exc).__name__}: {exc}"}
            if plan.safety:
                if isinstance(writer, BackgroundWriter):  # (the measures read the output)
                    writer.drain(raise_error=False)  # (an error: the writer's finish says)
                result["safety"] = _safety(plan, writer, result, kept)
        summary = writer.finish(status=status, error=error,
                                t_stop=run.t if run is not None else 0.0, frames=frame,
                                wall_time_s=wall, **result)
    if summary.get("status") == "failed":  # the output could not be closed (full disk)
        raise SimulationError(f"{summary.get('error')} (results up to then are in {where})")
    return summary


def _stepping(run: RunModel):
    """The model's context for its steps, if it has one (``run.stepping()``: a continuum
    model sets numba's threads and BLAS once for the whole loop instead of at every step,
    :meth:`pedmesh.models.continuum.solver.FVController.stepping`), else none."""
    stepping = getattr(run, "stepping", None)
    return stepping() if callable(stepping) else contextlib.nullcontext()


def _safety_kept():
    """A :class:`~pedmesh.run.safety.KeptDensity` for the run's density frames (None if
    the safety measures cannot be imported: they then say so in the summary)."""
    try:
        from .safety import KeptDensity
    except Exception:
        return None
    return KeptDensity()


class _KeepDensity:
    """``writer`` (any writer of the protocol) whose density frames are also kept in
    ``kept`` (:class:`~pedmesh.run.safety.KeptDensity`), so that the safety measures at the
    end need not read them back from their files; every other attribute is the writer's."""

    def __init__(self, writer, kept) -> None:
        self._writer = writer
        self._kept = kept

    def density_frame(self, t: float, mesh, point_data=None, cell_data=None) -> None:
        self._writer.density_frame(t, mesh, point_data=point_data, cell_data=cell_data)
        self._kept.add(t, mesh, cell_data)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._writer, name)


def _safety(plan: RunPlan, writer, result: Mapping[str, Any], kept=None) -> dict:
    """The run's crowd-safety measures (:mod:`pedmesh.run.safety`) from what it wrote (its
    density frames' numbers from ``kept`` where it holds them all), and safety.vtu beside
    them; an error is recorded ({"error": ...}), never raised, so that the measures cannot
    fail a run (not even a Ctrl-C while they are computed)."""
    try:
        from .safety import safety_from_memory, safety_measures

        room = plan.room if plan.room is not None else getattr(plan.mesh, "room", None)
        if room is None:
            room = getattr(plan.mesh, "building", None)
        # a run given its own start positions: its people are not the start areas'
        n0 = None if "positions" in plan.options else result.get("n_initial")
        if getattr(writer, "dir", None) is not None:
            return safety_measures(writer.dir, room, plan.mesh, n_initial=n0,
                                   write_fields=True, kept=kept)
        return safety_from_memory(writer, room, plan.mesh, n_initial=n0)
    except KeyboardInterrupt:
        return {"error": "interrupted while the safety measures were computed"}
    except Exception as exc:
        msg = str(exc) if isinstance(exc, PedmeshError) else f"{type(exc).__name__}: {exc}"
        return {"error": msg}


def _loop(run: RunModel, writer: RunWriter, t_end: float, bar) -> int:
    """Step ``run`` to the end, writing samples and frames; returns the number of frames."""
    next_sample = 0.0
    next_frame = 0.0
    frame = 0
    last_frame_t = last_sample_t = -math.inf
    counts0 = np.zeros(len(writer.exit_names))

    def sample(t: float) -> None:
        nonlocal last_sample_t, counts0
        counts = np.asarray(run.exit_counts(), float)
        span = t - last_sample_t
        flows = (counts - counts0) / span if math.isfinite(span) and span > 0 else 0 * counts
        writer.sample(t, run.evacuated)
        writer.outflow(t, flows)
        counts0 = counts
        last_sample_t = t

    def frame_now(t: float) -> None:
        nonlocal frame, last_frame_t
        run.write_frame(writer, frame)
        frame += 1
        last_frame_t = t

    # a model that interpolates its frames in time (MacroRun.write_frame_at) steps freely
    # and gets each frame at k * output_interval; the others land their steps on them
    dense = isinstance(run, DenseFrames) and bool(run.dense_frames)

    def dense_frames(t: float, final: bool) -> None:
        nonlocal frame, last_frame_t, next_frame
        while next_frame <= t + 1e-9:
            run.write_frame_at(writer, frame, min(next_frame, t))
            frame += 1
            last_frame_t = next_frame
            next_frame = frame * run.output_interval
        if final and t > last_frame_t + 1e-9:
            frame_now(t)

    def record(final: bool = False) -> None:
        nonlocal next_sample, next_frame
        t = run.t
        if t >= next_sample - 1e-9 or (final and t > last_sample_t + 1e-9):
            sample(t)
            k = math.floor((t - next_sample) / run.sample_interval + 1e-9) + 1
            next_sample += run.sample_interval * max(1, k)
        run.record(writer, final=final)
        if dense:
            dense_frames(t, final)
        elif t >= next_frame - 1e-9 or (final and t > last_frame_t + 1e-9):
            frame_now(t)
            k = math.floor((t - next_frame) / run.output_interval + 1e-9) + 1
            next_frame += run.output_interval * max(1, k)

    record()
    last_bar = 0.0

    def show() -> None:  # (whole people out; the simulated time beside them)
        bar.set_postfix_str(f"t={min(run.t, t_end):.1f}/{t_end:g} s", refresh=False)
        bar.advance(run.evacuated, run.t)

    while not run.done and run.t < t_end - 1e-9:
        run.step(t_end if dense else min(next_frame, t_end))
        if run.done or run.t >= t_end - 1e-9:
            break
        record()
        if stop_requested():
            raise KeyboardInterrupt
        if run.t - last_bar >= 0.5:
            show()
            last_bar = run.t
    record(final=True)  # the final state
    show()
    if run.done and bar.n < bar.total:  # (a continuum's last fraction of a person)
        bar.update(bar.total - bar.n)
    return frame
