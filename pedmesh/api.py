"""The Python API for scripts and notebooks: :func:`simulate` runs a model on a room and
returns its results; :func:`build` gives the model ready to step.

>>> import pedmesh
>>> result = pedmesh.simulate("geometries/example2.json", model="eos")  # doctest: +SKIP
>>> result.times                                                     # doctest: +SKIP
{'T50': 84.1, 'T90': 105.6, 'T100': 123.1}
>>> t, n_out = result.evacuation                                     # doctest: +SKIP

Without ``out_dir`` nothing is written: the curves, frames and trajectories stay in memory.
With ``out_dir`` the run writes its folder as ``pedmesh run`` does and the result reads it.
Either way the result is a :class:`~pedmesh.run.results.RunResult` with the same
attributes: ``summary``, ``times``, ``evacuation``, ``outflow``, ``exit_times``,
``density`` frames and ``density_at(t)``, ``pedestrians``, ``trajectories``, ...

The stepping form builds the model and leaves the loop to you::

    run = pedmesh.build("geometries/example2.json", model="sfm", preset="paper")
    while not run.done and run.t < 60.0:
        run.step()
    print(run.t, run.evacuated, run.remaining)   # [s], [ped], [ped]
    run.sim.positions                            # (the SFM's state: positions [m], ...)

``run`` is the model's :class:`~pedmesh.models.protocol.RunModel`: ``t``, ``evacuated``,
``remaining``, ``done``, ``step()``, ``exit_counts()``, ``summary()``, and the model's own
state (``run.sim`` for the social force model, ``run.state.Q`` and ``run.cell_fields()``
for the continuum models).
"""

from __future__ import annotations

from numbers import Real
from os import PathLike
from pathlib import Path
from typing import Any, Mapping

from .errors import ParameterError
from .parameters import DEFAULT_T_END_S

__all__ = ["simulate", "build"]


def _check_arguments(*, mesh=None, params=None, mesh_options=None, t_end=None,
                     out_dir=None, quiet=True) -> None:
    """One-line :class:`~pedmesh.errors.ParameterError` for an argument of :func:`simulate`
    or :func:`build` of the wrong kind, naming it, before anything is built."""
    from .mesh import SurfaceMesh, TriMesh

    if mesh is not None and not isinstance(mesh, (TriMesh, SurfaceMesh)):
        hint = (f"; a mesh file ('{mesh}') is not read: give mesh_options (e.g. "
                "{'max_area': 0.5}) and pedmesh meshes the room" if isinstance(mesh, (str, Path))
                else "")
        raise ParameterError("mesh must be a TriMesh (pedmesh.mesh.triangulate) or a "
                             "building's SurfaceMesh (pedmesh.mesh.triangulate_building), "
                             f"got {type(mesh).__name__}{hint}")
    if params is not None:
        if not isinstance(params, Mapping):
            raise ParameterError("params must be a mapping of parameter names to values, "
                                 f"e.g. {{'A': 2000.0}}; got {type(params).__name__} "
                                 f"{params!r:.60}")
        bad = [k for k in params if not isinstance(k, str)]
        if bad:
            raise ParameterError(f"params: parameter names are text, got {bad[0]!r}")
    if mesh_options is not None:
        from .mesh.site import check_mesh_options

        check_mesh_options(mesh_options)
    if t_end is not None and (isinstance(t_end, bool) or not isinstance(t_end, Real)):
        raise ParameterError(f"t_end must be a number of seconds, got {type(t_end).__name__} "
                             f"{t_end!r:.40}")
    if out_dir is not None and not isinstance(out_dir, (str, PathLike)):
        raise ParameterError(f"out_dir must be a folder's path (str or pathlib.Path), got "
                             f"{type(out_dir).__name__} {out_dir!r:.40}")
    if out_dir is not None and "\x00" in str(out_dir):
        raise ParameterError(f"out_dir must not hold a NUL character, got {str(out_dir)!r:.60}")
    if quiet not in (True, False):
        raise ParameterError(f"quiet must be True or False, got {quiet!r:.40}")


def _room_and_mesh(room, mesh, mesh_options: Mapping[str, Any] | None,
                   max_people: int | None = None):
    from .errors import RoomFileError
    from .geometry.site import check_site
    from .mesh.site import mesh_site
    from .io import load_room
    from .run.driver import check_crowd

    geometry = None
    if isinstance(room, (str, PathLike)):
        geometry = str(room)
        if not Path(room).exists():
            raise RoomFileError(f"{room}: no such room file")
        room = load_room(room)
    check_site(room)
    check_crowd(room, max_people)  # (before the mesh and the crowd are made)
    if mesh is None:
        mesh = mesh_site(room, **dict(mesh_options or {}))
    elif mesh_options:
        raise ParameterError("give either a mesh or mesh_options, not both")
    return room, mesh, geometry


def build(room, model: str = "sfm", *, preset: str | None = None,
          params: Mapping[str, Any] | None = None, mesh=None,
          mesh_options: Mapping[str, Any] | None = None, max_people: int | None = None,
          **options: Any):
    """Model ``model`` on ``room`` (a :class:`~pedmesh.geometry.Room`, a
    :class:`~pedmesh.geometry.Building` or a room file), built with the parameters of
    ``preset`` (default: the room file's, else ``validated``) and ``params`` on top, ready
    to :meth:`step`. ``mesh``: a :class:`~pedmesh.mesh.TriMesh` of the room, or a
    building's :class:`~pedmesh.mesh.surface.SurfaceMesh` (default: triangulated with
    ``mesh_options``, see :func:`pedmesh.mesh.triangulate` and
    :func:`pedmesh.mesh.triangulate_building`). ``max_people``: the largest crowd taken
    (default 1,000,000, :data:`pedmesh.run.driver.MAX_PEOPLE`). ``options``: the model
    options its registry entry lists (e.g. ``seed`` for the social force model)."""
    from .run.driver import build_model

    _check_arguments(mesh=mesh, params=params, mesh_options=mesh_options)
    room, mesh, _ = _room_and_mesh(room, mesh, mesh_options, max_people)
    return build_model(room, mesh, model, preset=preset, overrides=params,
                       max_people=max_people, **options)


def simulate(room, model: str = "sfm", *, preset: str | None = None,
             params: Mapping[str, Any] | None = None, out_dir: str | Path | None = None,
             t_end: float = DEFAULT_T_END_S, mesh=None,
             mesh_options: Mapping[str, Any] | None = None,
             quiet: bool = True, max_people: int | None = None,
             max_steps: int | None = None, **options: Any):
    """Run ``model`` on ``room`` until everyone has left or ``t_end`` [s] and return the
    result (see the module docstring). ``params``: parameter values by name (see ``pedmesh
    presets`` and the parameter tables of the docs); ``out_dir``: write the run folder
    there (None: keep everything in memory); ``quiet``: no progress bar; ``max_people``:
    the largest crowd taken (default 1,000,000, :data:`pedmesh.run.driver.MAX_PEOPLE`; a
    larger one is refused before anything is allocated); ``max_steps``: the most time
    steps taken (default 10,000,000, :data:`pedmesh.run.driver.MAX_STEPS`). Errors are
    :class:`~pedmesh.errors.PedmeshError` with one line naming the problem. Ctrl-C stops
    the run after its current step and raises :class:`~pedmesh.run.driver.RunInterrupted`
    (a ``KeyboardInterrupt``) whose ``result`` is the result up to then."""
    from .run.driver import RunInterrupted, execute, plan_run
    from .run.memory import MemoryWriter
    from .run.output import RunWriter
    from .run.results import RunResult

    _check_arguments(mesh=mesh, params=params, mesh_options=mesh_options, t_end=t_end,
                     out_dir=out_dir, quiet=quiet)
    room, mesh, geometry = _room_and_mesh(room, mesh, mesh_options, max_people)
    plan = plan_run(room, mesh, model, overrides=params, t_end=t_end, geometry=geometry,
                    mesh_options=dict(mesh_options or {}), model_options=options,
                    preset=preset, max_people=max_people, max_steps=max_steps)
    if out_dir is None:
        writer = MemoryWriter(plan.header, exit_names=mesh.exit_names)
        try:
            execute(plan, writer, quiet=quiet, where="the exception's .result")
        except RunInterrupted as exc:  # (Ctrl-C) the partial result goes with it
            exc.result = writer.result()
            raise
        return writer.result()
    writer = RunWriter(Path(out_dir), plan.header, exit_names=mesh.exit_names)
    try:
        execute(plan, writer, quiet=quiet, where=str(out_dir))
    except RunInterrupted as exc:
        exc.result = RunResult.load(out_dir)
        raise
    return RunResult.load(out_dir)
