"""Derived continuum models benchmark (mac1 and the mac2 family).

1. Build time and non-zeros of mac1's sparse operators on Example 2 at several mesh sizes.
2. Cost of one time step of every continuum model on Example 2's default mesh.
3. Example 2 run to the end with every derived model, for both exit conditions (empty space
   beyond the door, ``vacuum``, and ``transmissive``): T50/T90/T100, steps, wall time; and
   the social force model in the same run for the wall-time goal (mac1 to 99 % evacuated
   in <= 3x the SFM's wall time).

    python benchmarks/nonlocal.py [--skip-runs]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from _common import run_to_end

from pedmesh import load_room
from pedmesh.macro.kernels import SFMFriction, SFMRepulsion
from pedmesh.macro.nonlocal_ops import build_pair_operators
from pedmesh.run.models import MODELS

ROOT = Path(__file__).resolve().parents[1]
DERIVED = ["mac1", "mac2-local", "mac2-local-friction", "mac2-nonlocal", "mac2-nonlocal-friction"]


def operator_sizes(room):
    rows = []
    for a in (2.0, 0.5, 0.125):
        mesh = room.mesh(max_area=a)
        t0 = time.perf_counter()
        ops = build_pair_operators(mesh, SFMRepulsion(), SFMFriction())
        rows.append((mesh.n_triangles, mesh.h, time.perf_counter() - t0, ops.n_pairs,
                     ops.Wx.nnz, ops.Kxx.nnz, ops.Ix.nnz))
    return rows


def step_costs(room, mesh, models):
    out = []
    for name in models:
        run = MODELS[name](room, mesh, {})
        for _ in range(5):
            run.step()
        t0 = time.perf_counter()
        n = 10
        for _ in range(n):
            run.step()
        out.append((name, (time.perf_counter() - t0) / n, run.controller.dt_last))
    return out


def full_run(room, mesh, name, overrides):
    run = MODELS[name](room, mesh, overrides)
    wall, t99 = run_to_end(run)
    return run.summary(), wall, t99


def main(skip_runs: bool = False) -> None:
    room = load_room(ROOT / "geometries" / "example2.json")
    print("mac1 operators on Example 2")
    print("| cells | h [m] | build [s] | pairs | nnz W | nnz K | nnz wall images |")
    print("|---:|---:|---:|---:|---:|---:|---:|")
    for n, h, t, p, nw, nk, ni in operator_sizes(room):
        print(f"| {n} | {h:.2f} | {t:.1f} | {p} | {nw} | {nk} | {ni} |")
    mesh = room.mesh()
    print("\nCost of one step on Example 2's default mesh (first seconds)")
    print("| model | ms/step | dt [s] |")
    print("|---|---:|---:|")
    for name, t, dt in step_costs(room, mesh, ["pw", "rdue"] + DERIVED):
        print(f"| {name} | {1e3 * t:.1f} | {dt:.4f} |")
    if skip_runs:
        return
    print("\nExample 2 to the end (fewer than 0.5 pedestrians inside)")
    print("| model | exit | T50 [s] | T90 [s] | T100 [s] | steps | wall [s] | wall to 99 % [s] |")
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    from pedmesh.micro import Simulation

    t0 = time.perf_counter()
    sim = Simulation(mesh)
    sim.run(1000.0)
    sfm_wall = time.perf_counter() - t0
    from pedmesh.run import evacuation_times

    t50, t90, t100 = evacuation_times(sim.exit_time, 2400)
    print(f"| sfm | - | {t50:.1f} | {t90:.1f} | {t100:.1f} | {sim.steps} | {sfm_wall:.1f} | - |")
    fmt = lambda v: "-" if v is None else f"{v:.1f}"  # noqa: E731
    mac1_99 = None
    for name in DERIVED:
        for kind in ("vacuum", "transmissive"):
            s, wall, t99 = full_run(room, mesh, name, {"exit": kind})
            if name == "mac1" and kind == "vacuum":
                mac1_99 = t99
            print(f"| {name} | {kind} | {fmt(s['t_evac_50'])} | {fmt(s['t_evac_90'])} | "
                  f"{fmt(s['t_evac_100'])} | {s['steps']} | {wall:.1f} | {fmt(t99)} |", flush=True)
    if mac1_99 is not None:
        ratio = mac1_99 / sfm_wall
        print(f"\nmac1 to 99 % / SFM wall time: {ratio:.2f} (goal <= 3: {'met' if ratio <= 3 else 'NOT met'})")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--skip-runs", action="store_true")
    main(ap.parse_args().skip_runs)
