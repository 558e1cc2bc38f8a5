"""Narrow doors and doors in a thin wall: the evidence behind issue 44's door physics.

Runs model variants ("probes") on the cases that tell them apart and writes the tables of
``docs/validation/door_probes.md`` (and the figures as JSON):

* **narrow entrances**: the corridor rooms of ``geometries/experiments/`` with the entrance
  0.5 and 0.6 m wide and 61 and 66 people (the participant counts of the Juelich runs
  uo-050 and uo-060, Zhang et al. 2011, whose trajectories are not in ../shared; the
  waiting area 6 m wide at the shared rooms' 1.66 /m^2): J/b at the corridor's exit by
  PedPy, two realisations;
* **the size of the waiting crowd**: the 2.8 m long bottleneck of 0.5 m with 61 and with
  300 people in front (``pedmesh.fitting.validate.bottleneck_room``): their J/b ratio;
* **short against long**: a door 0.5 and 1.0 m wide in a 0.2 m wall
  (``wall_door_room``) and the 2.8 m long opening of the same width, the same 150
  people: J/b;
* **what holds the door's first row back**: the forces on the people within 0.35 m in
  front of the uo-050 entrance along the walking direction, averaged over t in [15, 60] s
  (N): their own driving force, the walls (social and contact) and the others.

The probes start from the ``validated`` preset as it was fitted before issue 44 (its
parameters written out below, so that the table does not move with the preset) and add
one change at a time; the last probe is the shipped preset::

    python benchmarks/door_physics.py [--probes NAME,...] [--json FILE] [--md FILE]

The probes not named keep their rows from the JSON file.

Every probe is one process per case (``NUMBA_NUM_THREADS=1``); nothing here is fitted.
"""

from __future__ import annotations

import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import argparse
import json
import math
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))

#: the validated preset as fitted before issue 44 (pedmesh/data/validated.json of
#: 2026-11-26), on top of the weidmann preset
BEFORE = {"speed_law": "table", "density_self": 0, "U_f": 1.34, "tau": 0.3062, "A": 962.0,
          "speed_table": "0:1 0.3:0.944 0.6:0.802 1.5:0.582 2.7:0.298 5.6:0",
          "t_space": 0.15, "crowd_width": 2.3, "shrink": 0.063, "crowd_stretch": 3.312,
          "queue_width": 1.737, "crowd_knee": 3.138,
          # (the weidmann preset has converged routes since issue 44; before, no preset had)
          "route_kernel": None, "route_resolution": None}
ROUTE = {"route_kernel": 2.0, "route_resolution": 0.1}
#: name -> (what it is, preset, overrides)
PROBES: dict[str, tuple[str, str, dict]] = {
    "before": ("the validated preset before issue 44 (routes on the run's default mesh)",
               "weidmann", dict(BEFORE)),
    "route": ("+ converged routes (route_kernel 2 m on its own route mesh, 0.1 m at "
              "doors)", "weidmann", {**BEFORE, **ROUTE}),
    "clearance": ("+ the route's clearance from walls (route_clearance 0.5 m)", "weidmann",
                  {**BEFORE, **ROUTE, "route_clearance": 0.5}),
    "cone": ("+ the desired speed from the crowd ahead (density_cone 2)", "weidmann",
             {**BEFORE, **ROUTE, "route_clearance": 0.5, "density_cone": 2.0}),
    "walls": ("+ walls that push only on contact (wall_repulsion 0)", "weidmann",
              {**BEFORE, **ROUTE, "route_clearance": 0.5, "density_cone": 2.0,
               "wall_repulsion": 0.0}),
    "validated": ("the shipped validated preset (refitted: docs/validation/fit.md)",
                  "validated", {}),
}
DENSITY_0 = 1.66  # [1/m^2] the shared uo rooms' waiting crowds (111 in 6 x 11.17 m)


def narrow_room(width: float, people: int):
    """The uo-070 room with its entrance ``width`` [m] wide and a waiting area 6 m wide
    holding ``people`` at DENSITY_0; (room, path of its file)."""
    from pedmesh.io import load_room

    d = json.loads((ROOT / "geometries" / "experiments" / "uo-070-180-180.json").read_text())
    c = 0.9  # the entrance's middle
    depth = people / DENSITY_0 / 6.0 + 0.7
    out = [list(p) for p in d["outline"]]
    out[3], out[4] = [c + width / 2, 8.1], [c + width / 2, 8.0]
    out[-3], out[-2] = [c - width / 2, 8.0], [c - width / 2, 8.1]
    out[0], out[1] = [-2.1, 8.1 + depth], [3.9, 8.1 + depth]
    d["outline"] = out
    d["start_areas"][0]["count"] = people
    d["start_areas"][0]["polygon"] = [[-1.75, 8.45], [3.55, 8.45], [3.55, 7.75 + depth],
                                      [-1.75, 7.75 + depth]]
    d["name"] = f"entrance-{round(width * 100):03d}"
    d["description"] = (f"the uo rooms with a {width:g} m entrance and {people} people "
                        "(benchmarks/door_physics.py)")
    path = Path(tempfile.mkdtemp()) / f"{d['name']}.json"
    path.write_text(json.dumps(d))
    return load_room(path), path


def narrow(preset, overrides, width, people, seed) -> float:
    """J/b [1/(m s)] at the corridor's exit of a narrow entrance (PedPy's flow)."""
    import pedmesh.validation as V
    from pedmesh.fitting.validate import run_sfm

    room, path = narrow_room(width, people)
    out = Path(tempfile.mkdtemp())
    s = run_sfm(room, out, overrides=overrides, preset=preset, geometry=str(path),
                model_options={"seed": seed})
    if s["error"] is not None:
        return math.nan
    return V.measure(V.load_run(out), V.corridor_setup(room.walkable))["flow"]["exit"] / width


def opening(preset, overrides, kind, width, people, seed=1) -> float:
    """J/b [1/(m s)] through a long opening or a door in a wall (quantile flow of the exit
    times: the room behind the wall is free flow)."""
    import pedmesh
    import pedmesh.validation as V
    from pedmesh.fitting.validate import bottleneck_room, wall_door_room

    room = (bottleneck_room if kind == "long" else wall_door_room)(width, people=people)
    res = pedmesh.simulate(room, "sfm", preset=preset, params=overrides, seed=seed,
                           t_end=600.0)
    return V.quantile_flow(res.exit_times) / width


def door_forces(preset, overrides, width=0.5, people=61, seed=1) -> dict[str, float]:
    """The mean forces [N] along the walking direction (towards the door: positive) on the
    people within 0.35 m in front of the entrance and across its width, t in [15, 60] s:
    their driving force, the walls' (social and contact) and the others'."""
    import pedmesh
    from pedmesh.models.sfm import kernels as K

    room, _ = narrow_room(width, people)
    run = pedmesh.build(room, "sfm", preset=preset, params=overrides, seed=seed)
    sim = run.sim
    p = sim.params
    w = sim.walls
    acc = {"drive": [], "walls": [], "others": []}
    while sim.t < 60.0 and not run.done:
        sim.step()
        if sim.t < 15.0 or sim.steps % 10:
            continue
        n = sim.n
        x, v = sim.x[:n], sim.v[:n]
        sel = np.flatnonzero((x[:, 1] > 8.1) & (x[:, 1] < 8.45) & (np.abs(x[:, 0] - 0.9)
                                                                     < 0.5 * width))
        if not len(sel):
            continue
        soc = sim._rs[:n] if p.shrink > 0 else sim.rad[:n]
        Fw = np.zeros((n, 2))
        K.wall_accel(x, v, n, w.piece, w.next_seg, w.x0, w.y0, w.inv_cell, w.nx, w.ny,
                     w.cell_ptr, w.cell_seg, sim.rc_w, sim.rad[:n], p.A * p.wall_repulsion,
                     p.B, p.k, p.kappa, p.m, Fw, soc)
        drive = (sim._ue[:n, None] * sim._e[:n] - v) / p.tau
        total = sim._F[:n]  # the last stage's acceleration: drive + walls + others
        others = total - drive - Fw
        for name, a in (("drive", drive), ("walls", Fw), ("others", others)):
            acc[name].extend((-p.m * a[sel, 1]).tolist())  # (the door lies towards -y)
    return {k: float(np.mean(v)) if v else math.nan for k, v in acc.items()}


def run_probe(name: str) -> dict:
    what, preset, ov = PROBES[name]
    t0 = time.perf_counter()
    out = {"probe": name, "what": what, "preset": preset, "overrides": ov}
    for b, n in ((0.5, 61), (0.6, 66)):
        out[f"narrow_{b:g}"] = [narrow(preset, ov, b, n, s) for s in (1, 2)]
    out["long_0.5_61"] = opening(preset, ov, "long", 0.5, 61)
    out["long_0.5_300"] = opening(preset, ov, "long", 0.5, 300)
    for b in (0.5, 1.0):
        out[f"long_{b:g}"] = opening(preset, ov, "long", b, 150)
        out[f"wall_{b:g}"] = opening(preset, ov, "wall", b, 150)
    out["forces"] = door_forces(preset, ov)
    out["wall_s"] = time.perf_counter() - t0
    return out


def markdown(rows: list[dict]) -> str:
    import pedmesh.validation as V

    lo5, hi5, _ = V.published_band(0.5, "short")
    lo6, hi6, _ = V.published_band(0.6, "short")
    f = lambda v: "-" if v is None or not math.isfinite(v) else f"{v:.2f}"  # noqa: E731
    lines = ["# Door physics probes", "",
             "Written by `python benchmarks/door_physics.py` (its docstring says how each "
             "number is measured); every J/b in 1/(m s). The published doors and short "
             f"openings give {lo5:.2f}-{hi5:.2f} at 0.5 m and {lo6:.2f}-{hi6:.2f} at 0.6 m "
             "(`pedmesh.validation.published_band(b, \"short\")`).", "",
             "| probe | entrance 0.5 m, 61 people (seeds 1, 2) | 0.6 m, 66 people | "
             "0.5 m opening: 61 / 300 people (ratio) | 0.5 m: wall door / long opening | "
             "1.0 m: wall door / long | first row at the door: own drive / walls / others "
             "[N] |", "|---|---|---|---|---|---|---|"]
    for r in rows:
        fo = r["forces"]
        ratio = r["long_0.5_300"] / r["long_0.5_61"] if r["long_0.5_61"] else math.nan
        lines.append(
            f"| `{r['probe']}`: {r['what']} | {f(np.mean(r['narrow_0.5']))} "
            f"({' '.join(f(v) for v in r['narrow_0.5'])}) | {f(np.mean(r['narrow_0.6']))} | "
            f"{f(r['long_0.5_61'])} / {f(r['long_0.5_300'])} ({f(ratio)}) | "
            f"{f(r['wall_0.5'])} / {f(r['long_0.5'])} | {f(r['wall_1'])} / {f(r['long_1'])} | "
            f"{fo['drive']:+.0f} / {fo['walls']:+.0f} / {fo['others']:+.0f} |")
    lines += ["", "Forces along the walking direction: positive pushes the person towards "
              "the door, negative holds them back.", ""]
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--probes", default=",".join(PROBES))
    ap.add_argument("--json", type=Path, default=ROOT / "docs" / "data" / "door_probes.json")
    ap.add_argument("--md", type=Path, default=ROOT / "docs" / "validation" / "door_probes.md")
    ap.add_argument("--jobs", type=int, default=2)
    args = ap.parse_args(argv)
    names = args.probes.split(",")
    for n in names:
        if n not in PROBES:
            ap.error(f"unknown probe {n!r} (probes: {', '.join(PROBES)})")
    warnings.filterwarnings("ignore")
    import concurrent.futures as cf
    import multiprocessing

    from _common import write_json

    ctx = multiprocessing.get_context("spawn")
    with cf.ProcessPoolExecutor(max_workers=max(1, args.jobs), mp_context=ctx) as pool:
        rows = list(pool.map(run_probe, names))
    for r in rows:
        print(r["probe"], {k: v for k, v in r.items() if k not in ("what", "overrides")},
              flush=True)
    # the probes not run now keep their rows from the file (each probe's parameters are
    # written out above, so only the shipped preset's row moves with the preset)
    new = {r["probe"]: r for r in rows}
    if args.json.is_file():
        old = {r["probe"]: r for r in json.loads(args.json.read_text())["results"]["rows"]}
        new = {**old, **new}
    rows = [new[n] for n in PROBES if n in new]
    write_json(args.json, {"rows": rows})
    args.md.parent.mkdir(parents=True, exist_ok=True)
    args.md.write_text(markdown(rows))
    print(f"wrote {args.md}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
