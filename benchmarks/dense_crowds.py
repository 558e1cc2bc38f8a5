"""Dense crowds: the evidence behind the social force model's terms for pressing crowds.

Runs a list of model variants ("probes") on the cases that tell them apart, one
realisation each (seed 1), and writes the table of ``docs/validation/dense_crowds.md``:

* the narrow-entrance corridor runs uo-070 and uo-100 and the corridor-fed exit of uo-095
  with the entrance as a door (``geometries/experiments/``: a waiting crowd presses
  through it): exit flow J against the experiment;
* uo-095 and uo-145 fed with the experiment's own inflow (``--entrance replay``);
* the bottleneck of :mod:`pedmesh.fitting.validate` at b = 0.5, 1.0 and 1.8 m: specific
  flow J/b against the published band and the Voronoi density in front of the opening;
* how people pass the entrance door of uo-070 and uo-100 and the exit of uo-095, in the
  experiment and in the shipped preset: the median speed of those crossing y = 7.5 m
  (0.5 m past the entrance) or y = -3.9 m (0.1 m before the exit), and the 10-90 % range
  of where across the corridor they cross.

Usage::

    python benchmarks/dense_crowds.py [--probes NAME,...] [--jobs 2] [--out FILE]

Every number is measured by the functions of :mod:`pedmesh.fitting.validate` and
:mod:`pedmesh.validation` (PedPy); nothing here is fitted.
"""

from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import argparse
import concurrent.futures as cf
import math
import multiprocessing
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

#: the shipped table fit's speed table with its jam point moved from 5.6 to 10 /m^2
JAM10 = "0:1 0.3:0.944 0.6:0.802 1.5:0.582 2.7:0.298 10:0"
#: the shipped table fit's preset, whatever validated.json holds now
TABLE_FIT = {"speed_law": "table", "density_self": 0, "U_f": 1.34, "tau": 0.3062, "A": 962.0,
             "speed_table": "0:1 0.3:0.944 0.6:0.802 1.5:0.582 2.7:0.298 5.6:0"}
#: name -> (what it is, preset, overrides)
PROBES: dict[str, tuple[str, str, dict]] = {
    "table": ("the table fit (the validated preset before the dense-crowd terms)",
              "weidmann", dict(TABLE_FIT)),
    "jam10": ("its speed table's jam point at 10 instead of 5.6 /m^2", "weidmann",
              {**TABLE_FIT, "speed_table": JAM10}),
    "vision": ("Helbing's field of vision, lambda 0.2", "weidmann",
               {**TABLE_FIT, "vision": 0.2}),
    "space": ("space requirement: shrink 0.08 m, t_space 0.2 s", "weidmann",
              {**TABLE_FIT, "shrink": 0.08, "t_space": 0.2}),
    "space+jam10": ("space requirement and jam point 10 /m^2", "weidmann",
                    {**TABLE_FIT, "shrink": 0.08, "t_space": 0.2, "speed_table": JAM10}),
    "space+crowd": ("space requirement and crowding (stretch 2.5, queue width 1.2 m)",
                    "weidmann", {**TABLE_FIT, "shrink": 0.08, "t_space": 0.2,
                                 "crowd_stretch": 2.5}),
    "space+crowd1.8": ("the same with queue width 1.8 m", "weidmann",
                       {**TABLE_FIT, "shrink": 0.08, "t_space": 0.2, "crowd_stretch": 2.5,
                        "queue_width": 1.8}),
    "validated": ("the validated preset as shipped", "validated", {}),
}
DOOR_RUNS = ("uo-070-180-180", "uo-100-180-180", "uo-180-180-095")
REPLAY_RUNS = ("uo-180-180-095", "uo-145-180-180")
WIDTHS = (0.5, 1.0, 1.8)
#: [m] where the passage is measured: just past the entrance, just before uo-095's exit
PASS_LINE = {"uo-070-180-180": 7.5, "uo-100-180-180": 7.5, "uo-180-180-095": -3.9}


def _cases() -> list[tuple[str, str]]:
    return ([("door", r) for r in DOOR_RUNS] + [("replay", r) for r in REPLAY_RUNS]
            + [("bottleneck", f"{b:g}") for b in WIDTHS])


def passage(traj, y: float) -> tuple[float, float, float]:
    """Median speed [m/s] of the people crossing the line y [m] (walking towards -y; over
    +-3 frames) and the 10 % and 90 % quantiles of x [m] where they cross."""
    df = traj.data
    rate = float(traj.frame_rate)
    speeds, xs = [], []
    for _, g in df.groupby("id"):
        g = g.sort_values("frame")
        yy, xx, ff = g["y"].to_numpy(), g["x"].to_numpy(), g["frame"].to_numpy()
        k = np.flatnonzero((yy[:-1] >= y) & (yy[1:] < y))
        if not len(k):
            continue
        k = int(k[0])
        lo, hi = max(k - 3, 0), min(k + 4, len(yy) - 1)
        speeds.append(math.hypot(xx[hi] - xx[lo], yy[hi] - yy[lo]) / ((ff[hi] - ff[lo]) / rate))
        xs.append(xx[k])
    if not speeds:
        return math.nan, math.nan, math.nan
    return (float(np.median(speeds)), float(np.percentile(xs, 10)),
            float(np.percentile(xs, 90)))


def run_case(probe: str, kind: str, name: str) -> dict:
    """One probe on one case: flow (and density in front, passage for door runs)."""
    warnings.filterwarnings("ignore")
    from pedmesh.fitting import validate as VB
    from pedmesh import load_room
    from pedmesh import validation as V

    _, preset, ov = PROBES[probe]
    with tempfile.TemporaryDirectory(prefix="pedmesh-dense-") as tmp:
        out = Path(tmp)
        if kind == "bottleneck":
            b = float(name)
            room = VB.bottleneck_room(b)
            s = VB.run_sfm(room, out, overrides=ov, preset=preset, model_options={"seed": 1})
            if s["error"]:
                return {"error": s["error"]}
            m = V.measure(V.load_run(out), VB.bottleneck_setup(room, b))
            return {"J_per_b": m["flow"]["middle"] / b, "front": m["density"],
                    "stuck": int(s.get("n_initial", 0)) - int(s.get("n_evacuated", 0))}
        path = VB.ROOMS / f"{name}.json"
        room = load_room(path)
        data = VB.default_data_dir() / "data" / f"{name}.txt"
        if kind == "replay":
            room = VB.replay_room(room, V.load_experiment(data))
        s = VB.run_sfm(room, out, overrides=ov, preset=preset, model_options={"seed": 1})
        if s["error"]:
            return {"error": s["error"]}
        traj = V.load_run(out)
        m = V.measure(traj, V.corridor_setup(room.walkable))
        res = {"J": m["flow"]["exit"], "density": m["density"]}
        if kind == "door":
            res["passage"] = passage(traj, PASS_LINE[name])
        return res


def experiment_side() -> dict:
    """The experiment's exit flows and passages (the same measurement)."""
    warnings.filterwarnings("ignore")
    from pedmesh.fitting import validate as VB
    from pedmesh import validation as V

    out = {}
    for name in sorted(set(DOOR_RUNS) | set(REPLAY_RUNS)):
        traj = V.load_experiment(VB.default_data_dir() / "data" / f"{name}.txt")
        setup = V.corridor_setup(exit_width_m=V.experiment_exit_width(name))
        out[name] = {"J": V.measure(traj, setup)["flow"]["exit"]}
        if name in PASS_LINE:
            out[name]["passage"] = passage(traj, PASS_LINE[name])
    return out


def _pc(sim: float, ref: float) -> str:
    return f"{100 * (sim / ref - 1):+.0f}%" if math.isfinite(sim) else "-"


def report(results: dict, exp: dict, probes: list[str], wall_s: float) -> str:
    from pedmesh import validation as V

    def short(r):  # uo-070-180-180 -> uo-070, uo-180-180-095 -> uo-095
        return "uo-" + (r[-3:] if r.endswith("095") else r[3:6])

    head = (["probe"] + [f"{short(r)} door" for r in DOOR_RUNS]
            + [f"{short(r)} replay" for r in REPLAY_RUNS]
            + [f"J/b {b:g} m (band)" for b in WIDTHS] + [f"front {b:g} m" for b in WIDTHS])
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for p in probes:
        row = [f"{p}: {PROBES[p][0]}"]
        for kind, runs in (("door", DOOR_RUNS), ("replay", REPLAY_RUNS)):
            for r in runs:
                res = results[p][(kind, r)]
                row.append("failed" if "error" in res else
                           f"{res['J']:.2f} ({_pc(res['J'], exp[r]['J'])})")
        for b in WIDTHS:
            res = results[p][("bottleneck", f"{b:g}")]
            lo, hi, _ = V.published_band(b)
            if "error" in res:
                row.append("failed")
                continue
            mark = "in" if lo <= res["J_per_b"] <= hi else "out"
            row.append(f"{res['J_per_b']:.2f} ({mark})" + (f", {res['stuck']} stuck"
                                                           if res["stuck"] else ""))
        for b in WIDTHS:
            res = results[p][("bottleneck", f"{b:g}")]
            row.append("-" if "error" in res else f"{res['front']:.1f}")
        lines.append("| " + " | ".join(row) + " |")
    md = ["Exit flow J [1/s] (error against the experiment), bottleneck specific flow J/b "
          "[1/(m s)] (inside or outside the published band at that width), Voronoi density "
          "[1/m^2] in front of the opening; one realisation (seed 1) each.", "",
          *lines, "",
          "How people pass: median speed [m/s] of those crossing y = 7.5 m (0.5 m past the "
          "entrance door) or y = -3.9 m (0.1 m before uo-095's exit), and where across the "
          "corridor they cross (10-90 % of x [m]; the door spans x = 0.4-1.4 m in uo-100, "
          "0.55-1.25 m in uo-070, 0.425-1.375 m in uo-095).", "",
          "| run | experiment | " + " | ".join(probes) + " |",
          "|---|---|" + "---|" * len(probes)]
    for r in DOOR_RUNS:
        def fmt(pas):
            return f"{pas[0]:.2f} m/s, x {pas[1]:.2f}-{pas[2]:.2f}"
        row = [r, fmt(exp[r]["passage"])]
        for p in probes:
            res = results[p][("door", r)]
            row.append("-" if "error" in res else fmt(res["passage"]))
        md.append("| " + " | ".join(row) + " |")
    md += ["", f"Written by `python benchmarks/dense_crowds.py` ({wall_s / 60:.1f} min)."]
    return "\n".join(md) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--probes", default=",".join(PROBES),
                    help=f"comma-separated probes (default all: {', '.join(PROBES)})")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "validation" /
                    "dense_crowds_probes.md")
    args = ap.parse_args(argv)
    probes = [p.strip() for p in args.probes.split(",") if p.strip()]
    bad = [p for p in probes if p not in PROBES]
    if bad:
        ap.error(f"unknown probe {bad[0]!r} (probes: {', '.join(PROBES)})")
    warnings.filterwarnings("ignore")
    t0 = time.perf_counter()
    exp = experiment_side()
    results: dict = {p: {} for p in probes}
    ctx = multiprocessing.get_context("spawn")
    with cf.ProcessPoolExecutor(max_workers=max(1, args.jobs), mp_context=ctx) as pool:
        futs = {pool.submit(run_case, p, k, n): (p, k, n) for p in probes for k, n in _cases()}
        for fut in cf.as_completed(futs):
            p, k, n = futs[fut]
            results[p][(k, n)] = fut.result()
            print(f"  {p} {k} {n}: {results[p][(k, n)]}", flush=True)
    md = report(results, exp, probes, time.perf_counter() - t0)
    args.out.write_text(md)
    print(md)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
