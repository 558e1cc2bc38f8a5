"""``pedmesh run``: simulate a crowd in a room with one model and write the results."""

from __future__ import annotations

import argparse
from pathlib import Path

from .cmd_mesh import add_mesh_args, mesh_options
from .cmd_presets import add_preset_arg

def _files() -> str:
    """The output files (pedmesh.run.output.OUTPUT_FILES) as an aligned list."""
    import textwrap

    from ..run.output import OUTPUT_FILES

    rows = []
    for name, what in OUTPUT_FILES.items():
        lines = textwrap.wrap(what, 90 - 23)
        rows.append(f"  {name:<20} {lines[0]}")
        rows += [" " * 23 + line for line in lines[1:]]
    return "\n".join(rows)


HELP = "simulate an evacuation with a model (sfm, ...) and write the results"
_DESCRIPTION = """\
Simulate the crowd of a room's start areas until everyone has left (or --t-end) and write
into the output directory, as the run goes:

{files}

The run owns its output directory: a directory holding an earlier pedmesh run is cleared
first (its files only), a non-empty directory that is not a pedmesh run is refused, and so
is a directory another run is writing into. An interrupted run (Ctrl-C, kill) keeps
everything written up to then; its summary says 'interrupted', a failed one 'failed' with
the error. Parameters are set with --param NAME=VALUE (repeatable); the summary lists them.

examples:
  pedmesh run geometries/example2.json --model sfm --out runs/ex2-sfm
  pedmesh run geometries/example3.json --model sfm --param dt=0.005 --param A=1500
  pedmesh run geometries/corridor_bottleneck.json --model rdue --preset weidmann
"""


def DESCRIPTION() -> str:
    """The description, with the output files (a callable, so that the parser does not
    import the run driver and the models: filled in when the help is shown)."""
    return _DESCRIPTION.replace("{files}", _files())


def add_max_people_arg(p: argparse.ArgumentParser) -> None:
    """``--max-people N``: the largest crowd a run takes (pedmesh.run.driver.MAX_PEOPLE)."""

    def help_text() -> str:
        from ..run.driver import MAX_PEOPLE

        return (f"refuse a crowd of more than N people, estimated from the start areas "
                f"before anything is allocated (default: {MAX_PEOPLE:,})")

    p.add_argument("--max-people", type=int, default=None, metavar="N", help=help_text)


def _model_help() -> str:
    from ..models import model_names

    return f"model to run (default: sfm; available: {', '.join(model_names())})"


def _max_steps_help() -> str:
    from ..run.driver import MAX_STEPS

    return (f"refuse a run of more than N time steps (t_end / dt), before it starts "
            f"(default: {MAX_STEPS:,})")


def add_args(p: argparse.ArgumentParser) -> None:
    from ..parameters import DEFAULT_T_END_S

    p.add_argument("geometry", metavar="GEOMETRY", help="room file (.json, .geojson or .dxf)")
    p.add_argument("--model", default="sfm", help=_model_help)
    p.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                   help="set a model or numerics parameter (repeatable)")
    p.add_argument("--t-end", type=float, default=DEFAULT_T_END_S, metavar="T",
                   help=f"stop at this simulated time in s if people remain "
                        f"(default: {DEFAULT_T_END_S:g})")
    add_preset_arg(p)
    add_mesh_args(p)
    p.add_argument("--out", metavar="DIR", default=None,
                   help="output directory (default: runs/<geometry>-<model>)")
    p.add_argument("--trajectory-rate", type=float, default=10.0, metavar="FPS",
                   help="(particle models) frames per second of the trajectory files "
                        "(default: 10)")
    p.add_argument("--seed", type=int, default=None, metavar="N",
                   help="(particle models) another realisation: the start positions jittered "
                        "and the start areas' distributions drawn with seed N (default: the "
                        "lattice as the room file gives it)")
    p.add_argument("--static-routes", action="store_true",
                   help="(particle models) keep the initial routes instead of re-solving "
                        "them from the density")
    add_max_people_arg(p)
    p.add_argument("--max-steps", type=int, default=None, metavar="N", help=_max_steps_help)
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")


#: a kernel of each kind of model whose numba cache says whether the kernels were compiled
#: (the module's __pycache__ holds its index, NAME.FUNCTION-LINE.pyXY.nbi)
_KERNELS = {"sfm": ("models/sfm", "kernels.rk3_step-"),
            "continuum": ("models/continuum", "fv_kernels.")}


def kernels_compiled(particle: bool) -> bool:
    """Whether the numerical kernels of a particle (or continuum) model are in numba's
    cache already (else the first run compiles them, once per install)."""
    import pedmesh

    import os

    sub, prefix = _KERNELS["sfm" if particle else "continuum"]
    src = Path(pedmesh.__file__).parent / sub
    cache = src / "__pycache__"
    if os.environ.get("NUMBA_CACHE_DIR"):  # (numba's cache elsewhere, in its own layout)
        from numba.core.caching import UserProvidedCacheLocator

        cache = Path(os.environ["NUMBA_CACHE_DIR"]) / \
            UserProvidedCacheLocator.get_suitable_cache_subpath(str(src / "kernels.py"))
    return cache.is_dir() and any(p.name.startswith(prefix) and p.suffix == ".nbi"
                                  for p in cache.iterdir())


def compile_notice(particle: bool) -> str | None:
    """The line said before a first run compiles the kernels (None if cached)."""
    if kernels_compiled(particle):
        return None
    return ("pedmesh: compiling the numerical kernels (once per install: a few minutes on 2 "
            "cores; later runs start in seconds)")


def run(args: argparse.Namespace) -> int:
    import sys

    from ..models import get_model
    from ..parameters import parse_overrides
    from ..run import RunInterrupted, run_model
    from .._signals import stop_on_signals
    from .cmd_mesh import mesh_from_args

    entry = get_model(args.model)  # fail fast on an unknown model
    name = entry.name
    from ..run.driver import check_crowd

    overrides = parse_overrides(args.param)
    # (before meshing, which compiles the meshers' own kernels on a fresh install)
    notice = compile_notice(entry.scale == "particles")
    if notice and not args.quiet:
        print(notice, file=sys.stderr, flush=True)
    room, mesh = mesh_from_args(args, buildings=True,
                                check=lambda r: check_crowd(r, args.max_people))
    out = Path(args.out) if args.out else Path("runs") / f"{Path(args.geometry).stem}-{name}"
    from ..errors import ParameterError

    model_options: dict = {}
    if args.static_routes:
        if "static_routes" not in entry.options:
            raise ParameterError(f"--static-routes does not apply to model '{name}'")
        model_options["static_routes"] = True
    if args.seed is not None:
        if "seed" not in entry.options:
            raise ParameterError(f"--seed does not apply to model '{name}' (a continuum "
                                 "model has one answer)")
        model_options["seed"] = args.seed
    if args.trajectory_rate != 10.0:
        if "trajectory_rate" not in entry.options:
            raise ParameterError(f"--trajectory-rate does not apply to model '{name}'")
        model_options["trajectory_rate"] = args.trajectory_rate
    try:
        with stop_on_signals():  # Ctrl-C / SIGTERM: stop after the current step
            s = run_model(room, mesh, name, overrides=overrides, t_end=args.t_end, out_dir=out,
                          quiet=args.quiet, geometry=str(args.geometry),
                          mesh_options=mesh_options(args),
                          model_options=model_options, preset=args.preset,
                          max_people=args.max_people, max_steps=args.max_steps)
    except RunInterrupted as exc:
        print(f"pedmesh: {exc}", file=sys.stderr)
        return 130

    def fmt(v):
        return "not reached" if v is None else f"{v:.1f} s"

    print(f"{name} on '{room.name}': {s['n_evacuated']:.0f} of {s['n_initial']:.0f} out "
          f"({s['status']}), T50 {fmt(s['t_evac_50'])}, T90 {fmt(s['t_evac_90'])}, "
          f"T100 {fmt(s['t_evac_100'])}; {s['steps']} steps in {s['wall_time_s']:.1f} s")
    print(f"results in {out}")
    return 0
