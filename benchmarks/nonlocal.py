"""Derived continuum models benchmark (mac1 and the mac2 family).

1. Build time and non-zeros of mac1's sparse operators on Example 2 at several mesh sizes.
2. Cost of one time step of every continuum model on Example 2's default mesh.
3. The wall-time goal (mac1 to 99 % evacuated in <= 3x the social force model's wall time,
   same run): the SFM on Example 2, and mac1 on the default mesh (h = 0.56 m) and on a
   coarse one (max_area 2 m^2, h = 1.1 m); every wall time counts meshing and the route or
   operator build. The two mac1 rows show how far the coarse mesh moves T50/T90/T100.
4. Example 2 run to the end with every derived model on the default mesh, for both exit
   conditions (empty space beyond the door, ``vacuum``, and ``transmissive``):
   T50/T90/T100, steps, wall time.

    python benchmarks/nonlocal.py [--skip-runs | --only-goal] [--models mac1,mac2-local]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from _common import run_to_end

from pedmesh import load_room
from pedmesh.models.continuum.physics import SFMFriction, SFMRepulsion
from pedmesh.models.continuum.nonlocal_ops import build_pair_operators
from pedmesh.models import get_model
from pedmesh.mesh import triangulate

ROOT = Path(__file__).resolve().parents[1]
#: max_area [m^2] of the coarse mesh of the wall-time goal (h about 1.1 m, against 0.56 m)
COARSE_AREA = 2.0
DERIVED = ["mac1", "mac2-local", "mac2-local-friction", "mac2-nonlocal", "mac2-nonlocal-friction"]


def operator_sizes(room):
    rows = []
    for a in (2.0, 0.5, 0.125):
        mesh = triangulate(room, max_area=a)
        t0 = time.perf_counter()
        ops = build_pair_operators(mesh, SFMRepulsion(), SFMFriction())
        rows.append((mesh.n_triangles, mesh.h, time.perf_counter() - t0, ops.n_pairs,
                     ops.Wx.nnz, ops.Kxx.nnz, ops.Ix.nnz))
    return rows


def step_costs(room, mesh, models):
    out = []
    for name in models:
        run = get_model(name).build(room, mesh, {})
        for _ in range(5):
            run.step()
        t0 = time.perf_counter()
        n = 10
        for _ in range(n):
            run.step()
        out.append((name, (time.perf_counter() - t0) / n, run.controller.dt_last))
    return out


def full_run(room, mesh, name, overrides):
    run = get_model(name).build(room, mesh, overrides)
    wall, t99 = run_to_end(run)
    return run.summary(), wall, t99


def main(skip_runs: bool = False, only_goal: bool = False, models=None) -> None:
    room = load_room(ROOT / "geometries" / "example2.json")
    print("mac1 operators on Example 2")
    print("| cells | h [m] | build [s] | pairs | nnz W | nnz K | nnz wall images |")
    print("|---:|---:|---:|---:|---:|---:|---:|")
    for n, h, t, p, nw, nk, ni in operator_sizes(room):
        print(f"| {n} | {h:.2f} | {t:.1f} | {p} | {nw} | {nk} | {ni} |")
    mesh = triangulate(room)
    print("\nCost of one step on Example 2's default mesh (first seconds)")
    print("| model | ms/step | dt [s] |")
    print("|---|---:|---:|")
    for name, t, dt in step_costs(room, mesh, ["pw", "rdue"] + DERIVED):
        print(f"| {name} | {1e3 * t:.1f} | {dt:.4f} |")
    if skip_runs:
        return
    goal_runs(room)
    if only_goal:
        return
    print("\nExample 2 to the end, default mesh (fewer than 0.5 pedestrians inside)")
    print("| model | exit | T50 [s] | T90 [s] | T100 [s] | steps | wall [s] | wall to 99 % [s] | "
          "max mass error |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|")
    fmt = lambda v: "-" if v is None else f"{v:.1f}"  # noqa: E731
    for name in models or DERIVED:
        for kind in ("vacuum", "transmissive"):
            s, wall, t99 = full_run(room, mesh, name, {"exit": kind})
            print(f"| {name} | {kind} | {fmt(s['t_evac_50'])} | {fmt(s['t_evac_90'])} | "
                  f"{fmt(s['t_evac_100'])} | {s['steps']} | {wall:.1f} | {fmt(t99)} | "
                  f"{s['mass_error_max']:.1e} |", flush=True)


def goal_runs(room) -> None:
    """The wall-time goal: the SFM on the default mesh against mac1 (exit: empty space) on
    the default mesh and on a coarse one, every wall time from scratch (mesh, routes or
    operators, and the run)."""
    from pedmesh.models.sfm import Simulation
    from pedmesh.run import evacuation_times

    t0 = time.perf_counter()
    sim = Simulation(triangulate(room))
    sim.run(1000.0)
    sfm_wall = time.perf_counter() - t0
    t50, t90, t100 = evacuation_times(sim.exit_time, 2400)
    print("\nExample 2: SFM against mac1 (wall times include meshing and the operator build)")
    print("| model | mesh: cells, h [m] | T50 [s] | T90 [s] | T100 [s] | steps | build [s] | "
          "wall to 99 % [s] | / SFM |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|")
    print(f"| sfm | default | {t50:.1f} | {t90:.1f} | {t100:.1f} | {sim.steps} | - | "
          f"{sfm_wall:.1f} (to the end) | 1 |", flush=True)
    for area in (COARSE_AREA, None):
        t0 = time.perf_counter()
        mesh = triangulate(room) if area is None else triangulate(room, max_area=area)
        run = get_model("mac1").build(room, mesh, {})
        build = time.perf_counter() - t0
        _, t99 = run_to_end(run)
        s = run.summary()
        tot = build + t99
        label = "default" if area is None else f"max_area {area:g} m^2"
        print(f"| mac1 | {label}: {mesh.n_triangles}, {mesh.h:.2f} | {s['t_evac_50']:.1f} | "
              f"{s['t_evac_90']:.1f} | {s['t_evac_100']:.1f} | {s['steps']} | {build:.1f} | "
              f"{tot:.1f} | {tot / sfm_wall:.2f} |", flush=True)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--skip-runs", action="store_true", help="operators and step costs only")
    ap.add_argument("--only-goal", action="store_true",
                    help="skip the runs of every derived model after the wall-time goal")
    ap.add_argument("--models", default=None,
                    help="comma-separated derived models to run to the end (default: all)")
    a = ap.parse_args()
    chosen = None if a.models is None else [m.strip() for m in a.models.split(",") if m.strip()]
    unknown = sorted(set(chosen or []) - set(DERIVED))
    if unknown:
        ap.error(f"unknown model '{unknown[0]}' (choose from: {', '.join(DERIVED)})")
    main(a.skip_runs, a.only_goal, chosen)
