"""``pedmesh compare``: run several models on one room and compare them."""

from __future__ import annotations

import argparse
from pathlib import Path

from .cmd_mesh import add_mesh_args, mesh_options
from .cmd_presets import add_preset_arg
from .cmd_run import add_max_people_arg

HELP = "run several models on one room and write comparison plots and tables"
DESCRIPTION = """\
Run each model (or reuse its finished run in the output directory), then write
evacuation.png, outflow.png, fundamental.png, density.png, comparison.csv and
comparison.md into the output directory. The first model is the reference that the
distances are measured against: the mean |N_out(t) - N_ref(t)|/N of the evacuation curves,
the T90 difference, the relative distance of the outflow curves and the L1 distance of the
density fields at a few times. On a building, stairs.csv and a table in comparison.md give
each model's use of each stair (people, first and last on, peak flow and density).

Models are comma-separated, each optionally with parameters: NAME[:PARAM=VALUE...].

examples:
  pedmesh compare geometries/example2.json --models sfm,mac1,rdue,pw:c0=0.5,pw:c0=1
  pedmesh compare geometries/l_shaped.json --models sfm,mac2-local --out runs/l-compare
"""


def add_args(p: argparse.ArgumentParser) -> None:
    from ..parameters import DEFAULT_T_END_S

    p.add_argument("geometry", metavar="GEOMETRY", help="room file (.json, .geojson or .dxf)")
    p.add_argument("--models", required=True, metavar="LIST",
                   help="comma-separated models, e.g. sfm,mac1,rdue,pw:c0=0.5")
    p.add_argument("--t-end", type=float, default=DEFAULT_T_END_S, metavar="T",
                   help=f"stop each run at this simulated time in s "
                        f"(default: {DEFAULT_T_END_S:g})")
    add_preset_arg(p)
    add_mesh_args(p)
    p.add_argument("--times", default=None, metavar="T1,T2,...",
                   help="times [s] of the density comparison (default: 25/50/75 %% of the "
                        "reference's T90)")
    p.add_argument("--out", metavar="DIR", default=None,
                   help="output directory (default: runs/<geometry>-compare)")
    p.add_argument("--rerun", action="store_true", help="do not reuse finished runs")
    add_max_people_arg(p)
    p.add_argument("-q", "--quiet", action="store_true", help="no progress output")


def run(args: argparse.Namespace) -> int:
    import sys

    from ..compare import parse_model_specs, run_comparison
    from ..errors import ParameterError
    from ..run import RunInterrupted
    from .._signals import stop_on_signals
    from .cmd_mesh import mesh_from_args

    specs = parse_model_specs(args.models)
    times = None
    if args.times is not None:
        import math

        try:
            times = [float(x) for x in args.times.split(",") if x.strip()]
        except ValueError:
            raise ParameterError(f"--times expects numbers, got '{args.times}'") from None
        if not times or not all(math.isfinite(t) and t >= 0 for t in times):
            raise ParameterError(f"--times expects finite times >= 0 [s], separated by "
                                 f"commas, got '{args.times}'")
    from ..run.driver import check_crowd

    room, mesh = mesh_from_args(args, buildings=True,
                                check=lambda r: check_crowd(r, args.max_people))
    out = Path(args.out) if args.out else Path("runs") / f"{Path(args.geometry).stem}-compare"
    try:
        with stop_on_signals():  # Ctrl-C / SIGTERM: the running model stops after its step
            res = run_comparison(room, mesh, specs, out, t_end=args.t_end, quiet=args.quiet,
                                 geometry=str(args.geometry), density_times=times,
                                 mesh_options=mesh_options(args),
                                 reuse=not args.rerun, preset=args.preset,
                                 max_people=args.max_people)
    except RunInterrupted as exc:
        print(f"pedmesh: {exc}; finished models are kept and reused next time", file=sys.stderr)
        return 130
    if not args.quiet:
        from ..io.run_folder import COMPARISON_MD

        print((out / COMPARISON_MD).read_text())
    print(f"results in {out}")
    return 0
