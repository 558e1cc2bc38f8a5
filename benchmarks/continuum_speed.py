"""What a continuum run costs against the social force model it stands in for.

Part 1 (always): every model on one room (default Example 2, the paper's parameters) as a
user runs it -- ``pedmesh run ROOM --model M -q`` in a new process, so start-up, imports,
numba cache loads and meshing count -- with the repeats interleaved (sfm, eos, ..., sfm,
eos, ...) and the disk synced between runs (untimed), so that no run pays for the write-back
of the previous one's output. Printed per model: cells, steps, mean dt, wall time (median and best),
wall / SFM (median over median, and best over best), T50 and T90, and the errors against
the SFM of the same run: T50 and T90 in %, and mean |N_out(t) - N_sfm(t)| / N over the
SFM's evacuation (t up to its T100).

Part 2 (``--sweep``): the work-precision diagram. Each continuum model in one process at
the settings of SWEEP, from the explicit scheme on the uniform 0.5 m^2 mesh as it was (3
stages, every cell) through each change that made it cheaper (active set, semi-implicit
pressure, 2 stages, cfl 0.9, the graded mesh) to variations of the defaults (route
interval, order, coarser meshes): wall time against the error in T50/T90 and in the
evacuation curve, measured against the same model on a uniform mesh two times finer than
the old default (four times with ``--fine-reference``), explicit at cfl 0.5 with the route
solved every step: a reference, not the SFM, since this part is about numerics.
``--plot FILE`` draws it.

    python benchmarks/continuum_speed.py                      # part 1, 2 repeats
    python benchmarks/continuum_speed.py --sweep --plot docs/images/work_precision.png

``--json FILE`` (part 1) also writes the table as JSON, from which the docs render it.

The machine is shared and noisy: judge by the ratios, not the seconds.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from pedmesh.mesh import triangulate

ROOT = Path(__file__).resolve().parents[1]


def _curve(run_dir: Path) -> tuple[np.ndarray, np.ndarray]:
    with open(run_dir / "evacuation.csv") as f:
        rows = list(csv.reader(f))[1:]
    a = np.array(rows, float)
    return a[:, 0], a[:, 1]


def curve_error(ref: tuple, other: tuple, n: float, t_max: float) -> float:
    """mean over t in [0, t_max] of |N_other(t) - N_ref(t)| / N (0.1 s grid)."""
    t = np.arange(0.0, t_max, 0.1)
    a = np.interp(t, *ref)
    b = np.interp(t, *other)
    return float(np.mean(np.abs(a - b)) / n)


def run_cli(room: str, model: str, out: Path, extra: list[str]) -> float:
    cmd = [sys.executable, "-m", "pedmesh", "run", room, "--model", model, "--out", str(out),
           "-q", *extra]
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, cwd=ROOT, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    # the run's output written back to disk now, untimed: otherwise the kernel writes it
    # (200 MB for the SFM on Example 2) during the next run and charges that run for it
    os.sync()
    return wall


def part1(args) -> dict:
    models = args.models.split(",")
    if "sfm" not in models:
        models = ["sfm", *models]
    walls: dict[str, list[float]] = {m: [] for m in models}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(args.repeats):
            for m in models:
                walls[m].append(run_cli(args.room, m, Path(tmp) / f"{m}-{r}", args.extra))
                print(f"  repeat {r + 1}: {m:>24} {walls[m][-1]:7.1f} s", flush=True)
        last = args.repeats - 1
        info = {m: json.loads((Path(tmp) / f"{m}-{last}" / "summary.json").read_text())
                for m in models}
        curves = {m: _curve(Path(tmp) / f"{m}-{last}") for m in models}
    s_ref = info["sfm"]
    med_sfm, best_sfm = statistics.median(walls["sfm"]), min(walls["sfm"])
    n = s_ref["n_initial"]
    t_max = s_ref["t_evac_100"] or max(curves["sfm"][0])
    print(f"\n{args.room}, {args.repeats} interleaved repeats, whole process "
          f"(pedmesh run -q {' '.join(args.extra)})")
    head = (f"{'model':>24} {'cells':>7} {'steps':>6} {'mean dt':>8} {'wall med':>9} "
            f"{'best':>6} {'/SFM med':>8} {'best':>6} {'T50':>7} {'T90':>7} {'dT50':>7} "
            f"{'dT90':>7} {'curve':>7}")
    print(head)
    rows = []
    for m in models:
        s = info[m]
        med, best = statistics.median(walls[m]), min(walls[m])
        d50 = 100 * (s["t_evac_50"] / s_ref["t_evac_50"] - 1)
        d90 = 100 * (s["t_evac_90"] / s_ref["t_evac_90"] - 1)
        err = curve_error(curves["sfm"], curves[m], n, t_max)
        print(f"{m:>24} {s['mesh']['triangles']:>7} {s['steps']:>6} {s['dt']:>8.4f} "
              f"{med:>9.1f} {best:>6.1f} {med / med_sfm:>8.3f} {best / best_sfm:>6.3f} "
              f"{s['t_evac_50']:>7.2f} {s['t_evac_90']:>7.2f} {d50:>+6.2f}% {d90:>+6.2f}% "
              f"{err:>7.4f}")
        rows.append(dict(model=m, cells=s["mesh"]["triangles"], steps=s["steps"], dt=s["dt"],
                         wall_median=med, wall_best=best, ratio_median=med / med_sfm,
                         ratio_best=best / best_sfm, t50=s["t_evac_50"], t90=s["t_evac_90"],
                         d50=d50, d90=d90, curve=err))
    return dict(room=args.room, repeats=args.repeats, extra=args.extra, rows=rows)


UNIFORM = {"max_area": 0.5, "feature_area": None}
EXPLICIT = {"implicit_pressure": 0, "stages": 3, "active_set": 0, "cfl": 0.7}
#: part 2: (label, mesh options, run overrides); each row adds one change to the one before
#: (the first is the scheme as it was before the semi-implicit step), then variations of
#: the defaults. Overrides a model does not have (implicit_pressure for rdue and mac1)
#: are dropped.
SWEEP = [
    ("explicit, 3 stages, uniform 0.5", UNIFORM, EXPLICIT),
    ("+ active set", UNIFORM, {**EXPLICIT, "active_set": 1}),
    ("+ semi-implicit", UNIFORM, {"stages": 3, "cfl": 0.7}),
    ("+ 2 stages", UNIFORM, {"cfl": 0.7}),
    ("+ cfl 0.9 (defaults, uniform 0.5)", UNIFORM, {}),
    ("defaults (graded mesh)", {}, {}),
    ("defaults, route every 0.5 s", {}, {"route_interval": 0.5}),
    ("defaults, route every step", {}, {"route_interval": 0.0}),
    ("defaults, order 2", {}, {"order": 2}),
    ("graded 0.5 -> 4 m^2", {"feature_area": 0.5, "max_area": 4.0}, {}),
    ("uniform 2 m^2", {"max_area": 2.0, "feature_area": None}, {}),
]


def _overrides(name: str, overrides: dict) -> dict:
    from pedmesh.models.continuum import macro_model

    if not getattr(macro_model(name), "supports_implicit_pressure", False):
        overrides = {k: v for k, v in overrides.items() if k != "implicit_pressure"}
    return overrides


def _inprocess(room, name, mesh_options, overrides, t_max=900.0):
    from pedmesh.models import get_model

    t0 = time.perf_counter()
    mesh = triangulate(room, **mesh_options)
    factory = get_model(name).build
    run = factory(room, mesh, _overrides(name, overrides))
    ts, ns = [0.0], [0.0]
    while not run.done and run.t < t_max:
        run.step()
        ts.append(run.t)
        ns.append(run.evacuated)
    wall = time.perf_counter() - t0
    s = run.summary()
    return dict(cells=mesh.n_triangles, steps=s["steps"], wall=wall, t50=s["t_evac_50"],
                t90=s["t_evac_90"], curve=(np.array(ts), np.array(ns)), n=run.n_initial)


def part2(args) -> list[dict]:
    import pedmesh

    room = pedmesh.load_room(ROOT / args.room)
    rows = []
    fine = {"max_area": 0.125 if args.fine_reference else 0.25, "feature_area": None}
    for name in args.sweep_models.split(","):
        _inprocess(room, name, {"max_area": 4.0}, {}, t_max=1.0)  # numba caches loaded
        # the reference: a finer uniform mesh, the explicit scheme at cfl 0.5 on 3 stages,
        # every cell, the route solved every step
        ref = _inprocess(room, name, fine, {**EXPLICIT, "cfl": 0.5, "route_interval": 0.0})
        print(f"\n{name}: reference {ref['cells']} cells, T50 {ref['t50']:.2f} s, "
              f"T90 {ref['t90']:.2f} s, {ref['wall']:.0f} s")
        print(f"{'setting':>36} {'cells':>6} {'steps':>6} {'wall':>6} {'dT50 %':>7} "
              f"{'dT90 %':>7} {'curve':>7}")
        for label, mesh_options, overrides in SWEEP:
            r = _inprocess(room, name, mesh_options, overrides)
            d50 = 100 * (r["t50"] / ref["t50"] - 1)
            d90 = 100 * (r["t90"] / ref["t90"] - 1)
            err = curve_error(ref["curve"], r["curve"], ref["n"], ref["curve"][0][-1])
            print(f"{label:>36} {r['cells']:>6} {r['steps']:>6} {r['wall']:>6.1f} "
                  f"{d50:>+7.2f} {d90:>+7.2f} {err:>7.4f}", flush=True)
            rows.append(dict(model=name, label=label, cells=r["cells"], steps=r["steps"],
                             wall=r["wall"], d50=d50, d90=d90, curve=err))
    return rows


def plot(rows: list[dict], path: str) -> None:
    """Wall time against the larger T50/T90 error per model; the first settings (the old
    scheme through each change to the defaults) joined by a line, the variations as
    points. The rows also go to ``path`` with a .csv suffix."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    with open(Path(path).with_suffix(".csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    path_len = next(k for k, (lab, _, _) in enumerate(SWEEP) if lab.startswith("defaults (")) + 1
    fig, ax = plt.subplots(figsize=(8, 5))
    for name in dict.fromkeys(r["model"] for r in rows):
        rs = [r for r in rows if r["model"] == name]
        err = [max(abs(float(r["d50"])), abs(float(r["d90"])), 0.01) for r in rs]
        wall = [float(r["wall"]) for r in rs]
        (line,) = ax.plot(wall[:path_len], err[:path_len], "o-", label=name)
        ax.plot(wall[path_len:], err[path_len:], "s", color=line.get_color(), mfc="none")
        for k, (x, e) in enumerate(zip(wall, err)):
            ax.annotate(str(k + 1), (x, e), fontsize=7, color=line.get_color(),
                        xytext=(3, 2), textcoords="offset points")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("wall time [s] (one process, mesh included)")
    ax.set_ylabel("max(|error T50|, |error T90|) [%] (at least 0.01)\n"
                  "against a fine explicit reference")
    ax.set_title("Example 2, line: " + "; ".join(f"{k + 1} {lab}" for k, (lab, _, _)
                                                  in enumerate(SWEEP[:path_len]))
                 + "\nsquares: " + "; ".join(f"{k + 1 + path_len} {lab}" for k, (lab, _, _)
                                              in enumerate(SWEEP[path_len:])), fontsize=6)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    print(f"wrote {path}")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--room", default="geometries/example2.json")
    p.add_argument("--models", default="sfm,eos,rdue,pw,mac1,mac2-local,mac2-nonlocal")
    p.add_argument("--repeats", type=int, default=2)
    p.add_argument("--extra", nargs="*", default=[], help="more pedmesh run options")
    p.add_argument("--sweep", action="store_true", help="part 2 only: work-precision")
    p.add_argument("--sweep-models", default="eos,rdue,pw")
    p.add_argument("--fine-reference", action="store_true",
                   help="part 2: reference on max_area 0.125 m^2 (default 0.25)")
    p.add_argument("--plot", default=None, metavar="FILE")
    p.add_argument("--json", default=None, metavar="FILE", help="part 1: write the table here")
    args = p.parse_args()
    if args.sweep:
        rows = part2(args)
        if args.plot:
            plot(rows, args.plot)
    else:
        results = part1(args)
        if args.json:
            from _common import write_json  # benchmarks/ is the script's directory

            write_json(args.json, results)


if __name__ == "__main__":
    main()
