"""``pedmesh ensemble``: many runs of one room on Dask (seeds and parameter sweeps)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .cmd_mesh import add_mesh_args, mesh_options
from .cmd_presets import add_preset_arg
from .cmd_run import add_max_people_arg

HELP = "run an ensemble or a parameter study on Dask (local cores or a cluster)"
DESCRIPTION = """\
Run --members runs of a room that differ by seed (start positions), at every point of the
grid given by --sweep options (N members at each point), on a Dask cluster: by default a
LocalCluster of --workers processes on this machine, or an existing cluster with
--scheduler tcp://HOST:PORT (started with `dask scheduler` and `dask worker`; the workers
must see the room file and DIR at the same paths).

Writes into DIR as members finish:
  members/<point>-<member>/  ordinary run folders (see pedmesh run --help)
  ensemble.csv               a row per member: seed, swept values, status, counts,
                             t_evac_50/90/100 [s], wall time [s], worker address, error
  ensemble.json              per sweep point: 5/50/95 percentiles, mean and standard
                             deviation of T50, T90, T100
  evacuation_bands.png       median evacuation curve with its 5-95 % band per point

DIR must be empty, new, or an earlier pedmesh ensemble (other files in it are left alone);
a second ensemble into the same DIR is refused while one runs. A member runs in a
temporary folder (members/<id>.tmp-...) that becomes members/<id>/ when its run has ended,
so a member's folder never holds a cut-off run, and a finished member is never run over
(not even when Dask recomputes it after a worker died). ensemble.csv takes each member's
status, counts and times from the member's own summary.json.

Running the same command again skips finished members; a member folder made with other
settings is an error. --param and --sweep names are checked against the model's
parameters before any cluster starts. A failed member is recorded and the others go on;
Ctrl-C keeps every finished member.

examples:
  pedmesh ensemble geometries/l_shaped.json --members 20 --out runs/lshape-ens
  pedmesh ensemble geometries/corridor_bottleneck.json --members 10 \\
      --sweep U_f=0.8,1.0,1.3 --out runs/speed-study
  pedmesh ensemble geometries/example2.json --members 50 --scheduler tcp://10.0.0.5:8786
"""


def add_args(p: argparse.ArgumentParser) -> None:
    from ..parameters import DEFAULT_T_END_S

    p.add_argument("geometry", metavar="GEOMETRY", help="room file (.json, .geojson or .dxf)")
    p.add_argument("--model", default="sfm", help="model to run (default: sfm)")
    p.add_argument("--members", type=int, default=10, metavar="N",
                   help="runs per sweep point, differing by seed (default: 10)")
    p.add_argument("--out", metavar="DIR", default=None,
                   help="output directory (default: runs/<geometry>-ensemble)")
    p.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                   help="set a parameter for every member (repeatable)")
    p.add_argument("--sweep", action="append", default=[], metavar="NAME=V1,V2,...",
                   help="sweep a parameter over values (repeatable: a grid over all)")
    p.add_argument("--seed", type=int, default=0, metavar="S",
                   help="ensemble seed; member seeds are drawn from it (default: 0)")
    p.add_argument("--scheduler", metavar="ADDRESS", default=None,
                   help="address of an existing Dask scheduler, e.g. tcp://HOST:8786")
    p.add_argument("--workers", type=int, default=None, metavar="K",
                   help="worker processes of the local cluster (default: number of cores)")
    p.add_argument("--t-end", type=float, default=DEFAULT_T_END_S, metavar="T",
                   help=f"stop each run at this simulated time in s "
                        f"(default: {DEFAULT_T_END_S:g})")
    add_preset_arg(p)
    add_max_people_arg(p)
    add_mesh_args(p)
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")


def run(args: argparse.Namespace) -> int:
    import signal

    from ..ensembles import ensemble, parse_sweep
    from ..models import get_model
    from ..parameters import parse_overrides
    from ..run.results import FINISHED_STATUSES

    name = get_model(args.model).name
    out = Path(args.out) if args.out else Path("runs") / f"{Path(args.geometry).stem}-ensemble"
    old = signal.signal(signal.SIGTERM, signal.default_int_handler)  # SIGTERM as Ctrl-C
    try:
        df = ensemble(args.geometry, name, args.members, out,
                      overrides=parse_overrides(args.param), sweep=parse_sweep(args.sweep),
                      seed=args.seed, scheduler=args.scheduler, workers=args.workers,
                      t_end=args.t_end, **mesh_options(args), max_cells=args.max_cells,
                      max_people=args.max_people,
                      quiet=args.quiet, preset=args.preset)
    except KeyboardInterrupt:
        print(f"pedmesh: ensemble interrupted; finished members are kept in {out}",
              file=sys.stderr)
        return 130
    finally:
        signal.signal(signal.SIGTERM, old)
    done = df["status"].isin(FINISHED_STATUSES).sum()
    failed = int((df["status"] == "failed").sum())
    print(f"{done} of {len(df)} members finished, {failed} failed; results in {out}")
    if failed:
        first = df[df["status"] == "failed"].iloc[0]
        print(f"first failure: member {first['member']}: {first['error']}", file=sys.stderr)
    return 0 if failed == 0 else 1
