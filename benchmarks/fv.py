"""Finite-volume core benchmark.

1. Cost of one residual evaluation (reconstruction + limiter + fluxes + flux limiter +
   sources) per cell at about 10k, 40k and 160k cells, for Payne-Whitham (3 variables) and
   RDUE (1 variable), median of repeats (and the best, which shows how much of the median
   is other load on a shared machine); goal <= 0.5 microseconds per cell per stage.
2. The paper's Example 2 with ``rdue`` and with ``pw`` (c0 = 0.5 and 1 m/s) on the default
   mesh, for both exit conditions: wall time, steps, T50/T90/T100 and the wall time to
   99 % evacuated.

    python benchmarks/fv.py [--skip-runs]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from _common import run_to_end

from pedmesh import Exit, Room, load_room
from pedmesh.models.continuum import macro_model
from pedmesh.models.continuum.adapter import MacroRun
from pedmesh.models.continuum.solver import FVOptions, FVSolver
from pedmesh.mesh import triangulate

ROOT = Path(__file__).resolve().parents[1]


def residual_cost(repeats: int = 21):
    rows = []
    for target in (10_000, 40_000, 160_000):
        room = Room([(0, 0), (100, 0), (100, 50), (0, 50)],
                    exits=[Exit("e", [(100, 20), (100, 30)])])
        # quality meshing (min angle 30 deg) makes about 1.58x as many triangles as area/max_area
        mesh = triangulate(room, max_area=1.58 * 5000.0 / target)
        for name in ("pw", "rdue"):
            model = macro_model(name)
            s = FVSolver(mesh, model, FVOptions())
            x = mesh.centroids[:, 0]
            Q = model.initial_state(1.0 + 0.5 * np.sin(x / 7.0)
                                    * np.cos(mesh.centroids[:, 1] / 5.0))
            if name == "pw":
                Q[:, 1] = 0.3 * Q[:, 0]
            s.update_route(Q)
            s.residual(Q, 0.0, 0.01)
            ts = []
            for _ in range(repeats):
                t0 = time.perf_counter()
                s.residual(Q, 0.0, 0.01)
                ts.append(time.perf_counter() - t0)
            t = float(np.median(ts))
            t0 = time.perf_counter()
            s.update_route(Q)
            t_route = time.perf_counter() - t0
            rows.append((mesh.n_triangles, name, t, t / mesh.n_triangles,
                         min(ts) / mesh.n_triangles, t_route))
    return rows


def example2_runs():
    room = load_room(ROOT / "geometries" / "example2.json")
    mesh = triangulate(room)
    out = []
    cases = [("rdue", {}, "demand"), ("rdue", {"exit": "transmissive"}, "transmissive")]
    for c0 in (0.5, 1.0):
        for kind in ("vacuum", "transmissive"):
            cases.append(("pw", {"c0": c0, "exit": kind}, kind))
    for name, over, kind in cases:
        run = MacroRun(room, mesh, over, model=name)
        wall, t99 = run_to_end(run)
        s = run.summary()
        label = name + (f" c0={over['c0']:g}" if "c0" in over else "")
        out.append((label, kind, wall, t99, s))
    return out


def main(skip_runs: bool = False) -> None:
    print("Residual cost (one stage: reconstruction, limiters, fluxes, sources)")
    print("| cells | model | residual [ms] | us per cell | best of repeats [us per cell] | "
          "route re-solve [ms] |")
    print("|---:|---|---:|---:|---:|---:|")
    worst = 0.0
    for n, name, t, per, best, tr in residual_cost():
        worst = max(worst, per)
        print(f"| {n} | {name} | {1e3 * t:.2f} | {1e6 * per:.3f} | {1e6 * best:.3f} | "
              f"{1e3 * tr:.1f} |")
    print(f"goal <= 0.5 us per cell (median) at every size: "
          f"{'met' if worst <= 0.5e-6 else 'NOT met'} (largest {1e6 * worst:.3f})")
    if skip_runs:
        return
    print("\nExample 2 on the default mesh (until fewer than 0.5 pedestrians remain)")
    print("| model | exit | T50 [s] | T90 [s] | T100 [s] | steps | wall [s] | wall to 99 % [s] |")
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    for label, kind, wall, t99, s in example2_runs():
        fmt = lambda v: "-" if v is None else f"{v:.1f}"  # noqa: E731
        print(f"| {label} | {kind} | {fmt(s['t_evac_50'])} | {fmt(s['t_evac_90'])} | "
              f"{fmt(s['t_evac_100'])} | {s['steps']} | {wall:.1f} | {fmt(t99)} |")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--skip-runs", action="store_true")
    main(ap.parse_args().skip_runs)
