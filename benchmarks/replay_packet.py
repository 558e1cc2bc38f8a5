"""Why the replayed corridor runs pass more at their exit than was let in (issue 44).

With ``--entrance replay`` (``pedmesh.fitting.validate``) each of the experiment's people
enters at y = 7.5 m when they crossed that line, so the simulation is fed exactly the
experiment's inflow; what it does with it between y = 7.5 m and the exit (y = -4 m) is
the model's. This script measures, for the experiment and for the simulation:

1. the quantile flow J [1/s] (:func:`pedmesh.validation.quantile_flow`, the validation's
   measure) at lines across the corridor from y = 7 to -4 m: a flow that grows along the
   corridor means the packet of people is compressed on the way (the late ones catch up
   with the early ones), one that falls means it spreads;
2. the mean speed [m/s] between y = 6 and -4 m of the people in each sixth of the entry
   order (PedPy's individual speed, the validation's): who walks faster or slower than in
   the experiment.

Each run with the preset as shipped and with each ``--variant`` (parameter overrides), one
realisation each (``--seed``):

    python benchmarks/replay_packet.py [--runs uo-100-180-180,uo-070-180-180]
                                       [--variant density_cone=0] [--seed 1]

About 15 s per run on one core.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from pedmesh import load_room
from pedmesh import validation as V
from pedmesh.fitting import validate as B

#: [m] the lines across the corridor where the flow is measured (y = 7.5 m is the replay's)
LINES_Y = (7.0, 4.0, 2.0, 0.0, -2.0, -4.0)
#: [m] the stretch over which each person's mean speed is taken
SPEED_Y = (-4.0, 6.0)
#: [m] a line across the whole corridor at height y (x from X_SPAN[0] to X_SPAN[1])
X_SPAN = (-1.0, 3.0)
SEXTILES = 6


def flows(traj) -> list[float]:
    """The quantile flow J [1/s] across each line of LINES_Y."""
    out = []
    for y in LINES_Y:
        times = V.passage_times(traj, ((X_SPAN[0], y), (X_SPAN[1], y)))
        out.append(float(V.quantile_flow(times, *V.FLOW_QUANTILES)))
    return out


def speeds_by_entry(traj) -> list[float]:
    """The mean individual speed [m/s] over y in SPEED_Y of the people of each sixth of
    the entry order (first frame seen), people in the order they appeared."""
    import pedpy

    df = traj.data
    speed = pedpy.compute_individual_speed(
        traj_data=traj, frame_step=max(1, round(V.SPEED_HALF_WINDOW_S * traj.frame_rate)),
        speed_calculation=pedpy.SpeedCalculation.BORDER_SINGLE_SIDED)
    m = speed.merge(df[[pedpy.ID_COL, pedpy.FRAME_COL, pedpy.Y_COL]],
                    on=[pedpy.ID_COL, pedpy.FRAME_COL])
    m = m[(m[pedpy.Y_COL] > SPEED_Y[0]) & (m[pedpy.Y_COL] < SPEED_Y[1])]
    per = m.groupby(pedpy.ID_COL)[pedpy.SPEED_COL].mean()
    order = df.groupby(pedpy.ID_COL)[pedpy.FRAME_COL].min().sort_values().index
    v = per.reindex([i for i in order if i in per.index]).to_numpy(float)
    return [float(part.mean()) for part in np.array_split(v, SEXTILES)]


def row(label: str, traj) -> str:
    j = flows(traj)
    s = speeds_by_entry(traj)
    return (f"   {label:<24} J " + " ".join(f"{x:.2f}" for x in j)
            + " | speed by entry sixth " + " ".join(f"{x:.2f}" for x in s))


def parse_variant(text: str) -> dict:
    out = {}
    for item in filter(None, text.split(",")):
        key, _, value = item.partition("=")
        out[key.strip()] = float(value)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", default="uo-100-180-180,uo-070-180-180,uo-180-180-095")
    ap.add_argument("--variant", action="append", default=[],
                    help="overrides NAME=VALUE[,NAME=VALUE] (repeatable)")
    ap.add_argument("--preset", default="validated")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--data", type=Path, default=None, help="the experiments directory")
    args = ap.parse_args(argv)
    data_dir = args.data or B.default_data_dir()
    print(f"J [1/s] at y = {', '.join(f'{y:g}' for y in LINES_Y)} m; mean speed [m/s] over "
          f"y in ({SPEED_Y[0]:g}, {SPEED_Y[1]:g}) m of each sixth of the entry order; "
          f"preset {args.preset}, seed {args.seed}")
    with tempfile.TemporaryDirectory(prefix="pedmesh-packet-") as tmp:
        for name in filter(None, args.runs.split(",")):
            exp = V.load_experiment(Path(data_dir) / "data" / f"{name}.txt")
            room = B.replay_room(load_room(B.ROOMS / f"{name}.json"), exp)
            print(f"{name}:")
            print(row("experiment", exp))
            for k, variant in enumerate(["", *args.variant]):
                out = Path(tmp) / f"{name}-{k}"
                s = B.run_sfm(room, out, preset=args.preset, overrides=parse_variant(variant),
                              model_options={"seed": args.seed})
                if s["error"] is not None:
                    print(f"   {variant or 'as shipped'}: {s['error']}")
                    continue
                print(row(variant or "as shipped", V.load_run(out)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
