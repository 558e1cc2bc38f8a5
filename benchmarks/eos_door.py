"""eos against the social force model under the validated preset, and what the social force
model's people do in front of a door (docs/validation/dense_crowds.md, "eos at the door").

1. ``--times``: T50 and T90 of ``pedmesh run GEOMETRY --model sfm|eos --preset validated``
   on Example 2, the corridor bottleneck and the 10,000-person venue, eos against the SFM,
   with the SFM also from ``--seeds`` jittered start lattices (its spread); ``--param
   NAME=VALUE`` goes to eos (e.g. ``exit_kernel=0``: the law read at the local density).
2. ``--door``: Example 2's exit (x = 100 m, y in [20, 30] m) in the exit-limited phase
   (t in [70, 110] s): in 0.5 m strips in front of it, the social force model's crowd
   density (people per area), the kernel density its people read their speed law at
   (without their own share), its ratio to the crowd's, their desired speed, velocity and
   the pair force along x; and beside it the kernel's mass beyond the exit that eos's
   ``exit_kernel`` takes away (:func:`pedmesh.models.continuum.exit_kernel.exit_kernel_mass`).
   Then the same strips under eos (density, v_x and the flow along x per metre of width,
   from frames every 0.5 s), with ``--param`` going to eos there too (e.g.
   ``exit=transmissive``: the exit's condition).

    python benchmarks/eos_door.py --times --seeds 2      # ~15 min on 2 cores
    python benchmarks/eos_door.py --door                 # ~1 min
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
GEOMETRIES = ("example2", "corridor_bottleneck", "venue_10k")


def _room_and_mesh(name: str):
    from pedmesh.cli.cmd_mesh import mesh_from_args
    from pedmesh.cli.cmd_run import add_args

    ap = argparse.ArgumentParser()
    add_args(ap)
    return mesh_from_args(ap.parse_args([str(ROOT / "geometries" / f"{name}.json")]))


def _run(name: str, model: str, seed: int | None, overrides: dict, tmp: Path) -> dict:
    from pedmesh.run import run_model

    room, mesh = _room_and_mesh(name)
    t0 = time.perf_counter()
    s = run_model(room, mesh, model, overrides=overrides, out_dir=tmp / f"{name}-{model}-{seed}",
                  quiet=True, preset="validated", safety=False,
                  model_options={} if seed is None else {"seed": seed})
    return {"t50": s["t_evac_50"], "t90": s["t_evac_90"], "wall": time.perf_counter() - t0}


def times(seeds: int, overrides: dict) -> None:
    print("| geometry | SFM T50 / T90 [s] (lattice) | SFM seeds 1..n | eos T50 / T90 [s] "
          "| eos - SFM (lattice) | eos - SFM (mean of all SFM runs) |")
    print("|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory(prefix="pedmesh-eos-door-") as tmp:
        for name in GEOMETRIES:
            sfm = [_run(name, "sfm", s, {}, Path(tmp)) for s in [None, *range(1, seeds + 1)]]
            eos = _run(name, "eos", None, overrides, Path(tmp))
            m50 = np.mean([r["t50"] for r in sfm])
            m90 = np.mean([r["t90"] for r in sfm])
            seeded = ", ".join(f"{r['t50']:.1f} / {r['t90']:.1f}" for r in sfm[1:])
            print(f"| {name} | {sfm[0]['t50']:.1f} / {sfm[0]['t90']:.1f} | {seeded} | "
                  f"{eos['t50']:.1f} / {eos['t90']:.1f} | "
                  f"{100 * (eos['t50'] / sfm[0]['t50'] - 1):+.1f} / "
                  f"{100 * (eos['t90'] / sfm[0]['t90'] - 1):+.1f} % | "
                  f"{100 * (eos['t50'] / m50 - 1):+.1f} / {100 * (eos['t90'] / m90 - 1):+.1f} % |",
                  flush=True)


def door() -> None:
    from scipy.spatial import cKDTree

    from pedmesh.models.continuum.exit_kernel import exit_kernel_mass
    from pedmesh.models.sfm import SFMNumerics, Simulation
    from pedmesh.models.sfm.params import SocialForceParams, with_overrides
    from pedmesh.presets import get_preset

    room, mesh = _room_and_mesh("example2")
    names = {f.name for f in dataclasses.fields(SocialForceParams)}
    (p,) = with_overrides(get_preset("validated").overrides(names), SocialForceParams())
    sim = Simulation(mesh, params=p, numerics=SFMNumerics())
    w_self = 1.0 / (math.pi * p.R * p.R)  # (density_self = 0: the law leaves it out)
    edges = np.arange(96.0, 100.01, 0.5)
    nb = len(edges) - 1
    acc = {k: np.zeros(nb) for k in ("n", "rho_k", "ue", "vx", "fx")}
    frames, next_t = 0, 70.0
    while sim.t < 110.0:
        sim.step()
        if sim.t + 1e-9 < next_t:
            continue
        next_t += 0.5
        frames += 1
        n = sim.n
        x, v = sim.x[:n], sim.v[:n]
        i, j = cKDTree(x).query_pairs(1.2, output_type="ndarray").T
        d = x[i] - x[j]
        dist = np.hypot(d[:, 0], d[:, 1])
        f = (p.A * np.exp((sim._rs[i] + sim._rs[j] - dist) / p.B)
             + p.k * np.maximum(sim.rad[i] + sim.rad[j] - dist, 0.0)) * d[:, 0] / dist
        fx = np.zeros(n)
        np.add.at(fx, i, f)
        np.add.at(fx, j, -f)
        b = np.digitize(x[:, 0], edges) - 1
        m = (x[:, 1] >= 20.0) & (x[:, 1] < 30.0) & (b >= 0) & (b < nb)
        for k, val in (("n", np.ones(n)), ("rho_k", sim.rho[:n] - w_self), ("ue", sim._ue[:n]),
                       ("vx", v[:, 0]), ("fx", fx / p.m)):
            np.add.at(acc[k], b[m], val[m])
    mid = 0.5 * (edges[1:] + edges[:-1])
    w = exit_kernel_mass(mesh, np.c_[mid, np.full(nb, 25.0)], np.zeros(nb, int), p.R)
    area = 0.5 * 10.0
    print(f"Example 2, social force model (validated), t in [70, 110] s, {frames} frames, "
          "y in [20, 30] m")
    print("| x [m] | crowd density [/m^2] | kernel density read [/m^2] | read / crowd "
          "| desired speed [m/s] | v_x [m/s] | pair force / m along x [m/s^2] "
          "| 1 - w at the strip's middle (eos exit_kernel) | flow along x [1/(m s)] |")
    print("|---|---|---|---|---|---|---|---|---|")
    for q in range(nb):
        c = max(acc["n"][q], 1.0)
        rho = acc["n"][q] / frames / area
        print(f"| {edges[q]:.1f}-{edges[q + 1]:.1f} | {rho:.2f} | {acc['rho_k'][q] / c:.2f} | "
              f"{acc['rho_k'][q] / c / rho:.2f} | {acc['ue'][q] / c:.2f} | "
              f"{acc['vx'][q] / c:.2f} | {acc['fx'][q] / c:+.2f} | {1 - w[q]:.2f} | "
              f"{rho * acc['vx'][q] / c:.2f} |")


def door_eos(overrides: dict) -> None:
    """The strips of :func:`door` under eos (validated, the run's default mesh)."""
    import pedmesh

    room, mesh = _room_and_mesh("example2")
    res = pedmesh.simulate(room, "eos", preset="validated", mesh=mesh, t_end=300.0,
                           params={"output_interval": 0.5, **overrides})
    c, area = mesh.centroids, mesh.areas
    edges = np.arange(96.0, 100.01, 0.5)
    nb = len(edges) - 1
    b = np.digitize(c[:, 0], edges) - 1
    m = (c[:, 1] >= 20.0) & (c[:, 1] < 30.0) & (b >= 0) & (b < nb)
    mass, mom, cover = np.zeros(nb), np.zeros(nb), np.zeros(nb)
    frames = 0
    for t in np.arange(70.0, 110.01, 0.5):
        _, rho, vel = res.density_at(float(t))
        np.add.at(mass, b[m], (rho * area)[m])
        np.add.at(mom, b[m], (rho * area * vel[:, 0])[m])
        np.add.at(cover, b[m], area[m])
        frames += 1
    extra = ", ".join(f"{k}={v}" for k, v in overrides.items())
    print(f"\neos (validated{', ' + extra if extra else ''}), the same strips, {frames} "
          f"frames; T50 / T90 {res.times['T50']:.1f} / {res.times['T90']:.1f} s")
    print("| x [m] | density [/m^2] | v_x [m/s] | flow along x [1/(m s)] |")
    print("|---|---|---|---|")
    for q in range(nb):
        rho_q = mass[q] / cover[q]
        vx = mom[q] / max(mass[q], 1e-12)
        print(f"| {edges[q]:.1f}-{edges[q + 1]:.1f} | {rho_q:.2f} | {vx:.2f} | "
              f"{rho_q * vx:.2f} |")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--times", action="store_true")
    ap.add_argument("--door", action="store_true")
    ap.add_argument("--seeds", type=int, default=2, help="SFM runs from jittered lattices")
    ap.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                    help="an eos parameter (repeatable)")
    a = ap.parse_args(argv)
    from pedmesh.parameters import parse_overrides

    if not (a.times or a.door):
        ap.error("say --times and/or --door")
    if a.door:
        door()
        door_eos(parse_overrides(a.param))
    if a.times:
        times(a.seeds, parse_overrides(a.param))


if __name__ == "__main__":
    sys.exit(main())
