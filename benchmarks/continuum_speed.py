"""What a continuum run costs against the social force model it stands in for.

Part 1 (always): every model on one room (default Example 2, the paper's parameters) as a
user runs it -- ``pedmesh run ROOM --model M -q`` in a new process, so start-up, imports,
numba cache loads and meshing count -- with the repeats interleaved (sfm, eos, ..., sfm,
eos, ...). Printed per model: cells, steps, mean dt, wall time (median and best),
wall / SFM (median over median, and best over best), T50 and T90, and the errors against
the SFM of the same run: T50 and T90 in %, and mean |N_out(t) - N_sfm(t)| / N over the
SFM's evacuation (t up to its T100).

Part 2 (``--sweep``): the work-precision diagram. Each continuum model in one process at
several settings (cell size, reconstruction order, route interval), wall time against the
error in T50/T90 and in the evacuation curve, measured against the same model on a mesh
two times finer than the default (four times with ``--fine-reference``) with the route
solved every step: a reference, not the SFM, since this part is about numerics.
``--plot FILE`` draws it.

    python benchmarks/continuum_speed.py                      # part 1, 2 repeats
    python benchmarks/continuum_speed.py --sweep --plot docs/images/work_precision.png

The machine is shared and noisy: judge by the ratios, not the seconds.
"""

from __future__ import annotations

import argparse
import csv
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

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
    return time.perf_counter() - t0


def part1(args) -> None:
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


#: part 2: settings per model (max_area [m^2], exit_size [m] or None, order, route_interval [s])
SWEEP = [(0.5, None, 3, 0.0), (0.5, None, 3, 0.5), (1.0, None, 3, 0.5), (2.0, None, 3, 0.5),
         (2.0, None, 2, 0.5), (4.0, None, 3, 0.5), (2.0, 0.5, 3, 0.5)]


def _inprocess(room, name, max_area, exit_size, order, route_interval, t_max=900.0):
    from pedmesh.run.models import get_model

    t0 = time.perf_counter()
    mesh = room.mesh(max_area=max_area, exit_size=exit_size)
    _, factory = get_model(name)
    run = factory(room, mesh, {"order": order, "route_interval": route_interval})
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
    for name in args.sweep_models.split(","):
        _inprocess(room, name, 4.0, None, 3, 0.5, t_max=1.0)  # numba caches loaded
        ref = _inprocess(room, name, 0.125 if args.fine_reference else 0.25, None, 3, 0.0)
        print(f"\n{name}: reference {ref['cells']} cells, T50 {ref['t50']:.2f} s, "
              f"T90 {ref['t90']:.2f} s, {ref['wall']:.0f} s")
        print(f"{'max_area':>8} {'exit_size':>9} {'order':>5} {'route dt':>8} {'cells':>6} "
              f"{'steps':>6} {'wall':>6} {'dT50 %':>7} {'dT90 %':>7} {'curve':>7}")
        for ma, es, order, ri in SWEEP:
            r = _inprocess(room, name, ma, es, order, ri)
            d50 = 100 * (r["t50"] / ref["t50"] - 1)
            d90 = 100 * (r["t90"] / ref["t90"] - 1)
            err = curve_error(ref["curve"], r["curve"], ref["n"], ref["curve"][0][-1])
            print(f"{ma:>8} {str(es):>9} {order:>5} {ri:>8} {r['cells']:>6} {r['steps']:>6} "
                  f"{r['wall']:>6.1f} {d50:>+7.2f} {d90:>+7.2f} {err:>7.4f}", flush=True)
            rows.append(dict(model=name, max_area=ma, exit_size=es, order=order,
                             route_interval=ri, wall=r["wall"], d50=d50, d90=d90, curve=err))
    return rows


def plot(rows: list[dict], path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5))
    for name in dict.fromkeys(r["model"] for r in rows):
        rs = [r for r in rows if r["model"] == name]
        err = [max(abs(r["d50"]), abs(r["d90"])) for r in rs]
        (line,) = ax.plot([r["wall"] for r in rs], err, "o", label=name)
        for r, e in zip(rs, err):
            ax.annotate(f"{r['max_area']:g}/{r['order']}/{r['route_interval']:g}"
                        + ("" if r["exit_size"] is None else f"/e{r['exit_size']:g}"),
                        (r["wall"], e), fontsize=6, color=line.get_color())
    ax.set_xscale("log")
    ax.set_yscale("symlog", linthresh=0.05)
    ax.set_xlabel("wall time [s] (one process, mesh included)")
    ax.set_ylabel("max(|error T50|, |error T90|) [%]\nagainst a finer mesh")
    ax.set_title("work-precision: max_area [m^2] / order / route interval [s]", fontsize=9)
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
    args = p.parse_args()
    if args.sweep:
        rows = part2(args)
        if args.plot:
            plot(rows, args.plot)
    else:
        part1(args)


if __name__ == "__main__":
    main()
