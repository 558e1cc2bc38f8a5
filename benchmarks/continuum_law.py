"""The continuum models' desired-speed law under a preset: the social force model's own
fundamental diagram, measured.

The social force model evaluates its desired speed U_e at a Gaussian kernel density
without a pedestrian's own share (``density_self=0``), which reads lower than the crowd's
true density (nobody stands within a body diameter of anyone, lanes form, walls cut the
kernel). A continuum model's density is the true one. So that both models share one
fundamental diagram, the continuum models take as their law ``U_e(rho) = U_f g(rho)`` the
speed the social force model actually walks at the density rho, measured here:

* a corridor 40 m long and 10 m wide, its far end (x = 40 m) the exit, filled over
  x in [0, 30] m at the density rho0 (the start lattice jittered by the seed);
* the density [ped/m^2] and mean speed [m/s] of the people in the box x in [12, 22] m,
  y in [2, 8] m (2 m from the walls), over the frames t in [3, 6] s: after the
  acceleration (tau = 0.3 s), before the rarefaction from the crowd's front at x = 30 m
  reaches the box;
* rho0 = 0.25 ... 5.5 /m^2, ``--seeds`` realisations each; the table's points are the
  measured (density, speed / U_f) pairs averaged over the seeds, sorted by density, made
  non-increasing (a later point never above an earlier one), with 0:1 in front and the
  jam point where the line through the last two points reaches g = 0 (capped at
  ``JAM_CAP``).

Writes ``pedmesh/data/fd_<preset>.json`` (the table as ``speed_table`` text, every
measurement, the protocol, the SFM parameters) unless ``--no-write``; the preset
(:mod:`pedmesh.presets`) gives it to the continuum models as their ``speed_table``.

    python benchmarks/continuum_law.py [--preset validated] [--seeds 2] [--no-write]

About 2 minutes on two cores.
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DENSITIES = (0.25, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 4.5, 5.0, 5.5)  # [ped/m^2]
LENGTH, WIDTH, FILLED = 40.0, 10.0, 30.0  # [m]
BOX = (12.0, 2.0, 22.0, 8.0)  # [m] x0, y0, x1, y1
WINDOW = (3.0, 6.0)  # [s]
JAM_CAP = 8.0  # [ped/m^2] the jam point is never put beyond this
FPS = 10.0


def corridor(rho0: float):
    from pedmesh import Exit, Room, StartArea

    rect = lambda x0, y0, x1, y1: [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]  # noqa: E731
    return Room(rect(0, 0, LENGTH, WIDTH), exits=[Exit("end", [(LENGTH, 0), (LENGTH, WIDTH)])],
                start_areas=[StartArea("crowd", rect(0.2, 0.2, FILLED, WIDTH - 0.2),
                                       density=rho0)],
                name=f"fd-rho{rho0:g}")


def box_density_speed(traj_file: Path) -> tuple[float, float, int]:
    """Mean density [ped/m^2] and mean speed [m/s] of the people in :data:`BOX` over the
    frames in :data:`WINDOW` of an SFM run's trajectories (centred differences), and the
    number of speed samples."""
    data = np.loadtxt(traj_file, comments="#")
    pid, frame, x, y = data[:, 0].astype(int), data[:, 1].astype(int), data[:, 2], data[:, 3]
    order = np.lexsort((frame, pid))
    pid, frame, x, y = pid[order], frame[order], x[order], y[order]
    same = (pid[2:] == pid[:-2]) & (frame[2:] - frame[:-2] == 2)
    k = np.flatnonzero(same) + 1  # samples with a neighbour frame on each side
    u = np.hypot(x[k + 1] - x[k - 1], y[k + 1] - y[k - 1]) * FPS / 2.0
    t = frame[k] / FPS
    x0, y0, x1, y1 = BOX
    sel = ((t >= WINDOW[0]) & (t <= WINDOW[1]) & (x[k] >= x0) & (x[k] < x1)
           & (y[k] >= y0) & (y[k] < y1))
    frames = np.unique(frame[k][sel])
    if not len(frames):
        return math.nan, math.nan, 0
    rho = sel.sum() / len(frames) / ((x1 - x0) * (y1 - y0))
    return float(rho), float(u[sel].mean()), int(sel.sum())


def measure(preset: str, seeds: int, overrides: dict | None = None, log=print) -> list[dict]:
    """Every (rho0, seed) run's measured density and speed."""
    from pedmesh.run import run_model

    rows = []
    with tempfile.TemporaryDirectory(prefix="pedmesh-fd-") as tmp:
        for rho0 in DENSITIES:
            room = corridor(rho0)
            mesh = room.mesh(max_area=2.0)
            for seed in range(1, seeds + 1):
                out = Path(tmp) / f"{rho0:g}-{seed}"
                t0 = time.perf_counter()
                run_model(room, mesh, "sfm", overrides=dict(overrides or {}), t_end=WINDOW[1] + 0.2,
                          out_dir=out, quiet=True, preset=preset,
                          model_options={"seed": seed, "trajectory_rate": FPS})
                rho, u, n = box_density_speed(out / "trajectories.txt")
                rows.append({"rho0": rho0, "seed": seed, "density": rho, "speed": u,
                             "samples": n, "wall_s": time.perf_counter() - t0})
                log(f"  rho0 {rho0:4g} seed {seed}: density {rho:.3f} /m^2, speed {u:.3f} m/s "
                    f"({n} samples, {rows[-1]['wall_s']:.1f} s)")
    return rows


def table_of(rows: list[dict], U_f: float) -> list[tuple[float, float]]:
    """The ``table`` law's points (density, g) of the measurements (module docstring)."""
    by = {}
    for r in rows:
        if math.isfinite(r["density"]):
            by.setdefault(r["rho0"], []).append((r["density"], r["speed"]))
    pts = sorted((float(np.mean([d for d, _ in v])), float(np.mean([u for _, u in v])) / U_f)
                 for v in by.values())
    out = [(0.0, 1.0)]
    for rho, g in pts:
        if rho <= out[-1][0] + 1e-3:
            continue
        out.append((round(rho, 3), round(min(g, out[-1][1]), 4)))
    (r1, g1), (r2, g2) = out[-2], out[-1]
    slope = (g2 - g1) / (r2 - r1) if r2 > r1 else 0.0
    jam = r2 - g2 / slope if slope < 0 else JAM_CAP
    out.append((round(min(max(jam, r2 + 0.1), JAM_CAP), 3), 0.0))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--preset", default="validated")
    ap.add_argument("--seeds", type=int, default=2, help="realisations per density (2)")
    ap.add_argument("--no-write", action="store_true", help="print, write nothing")
    args = ap.parse_args(argv)
    from pedmesh import __version__
    from pedmesh.presets import preset_overrides
    from pedmesh.run.models import model_parameters
    from pedmesh.speed import format_speed_table

    sfm = preset_overrides(args.preset, model_parameters("sfm"), {})
    U_f = float(sfm.get("U_f", 1.034))
    print(f"The SFM's fundamental diagram under preset {args.preset} (U_f {U_f:g} m/s), "
          f"{args.seeds} realisation(s) per density")
    t0 = time.perf_counter()
    rows = measure(args.preset, args.seeds)
    table = table_of(rows, U_f)
    text = format_speed_table(table)
    print(f"\ncontinuum speed_table: {text}\n(wall {time.perf_counter() - t0:.0f} s)")
    print(" rho [/m^2]   v [m/s]   g = v/U_f")
    for rho, g in table:
        print(f"  {rho:8.3f}  {g * U_f:8.3f}  {g:8.4f}")
    if args.no_write:
        return 0
    path = ROOT / "pedmesh" / "data" / f"fd_{args.preset}.json"
    record = {
        "speed_table": text, "U_f": U_f,
        "measurements": rows,
        "protocol": {"corridor_m": [LENGTH, WIDTH], "filled_to_x_m": FILLED, "box_m": BOX,
                     "window_s": WINDOW, "densities": DENSITIES, "seeds": args.seeds,
                     "jam_cap": JAM_CAP, "script": "benchmarks/continuum_law.py"},
        "sfm_parameters": {k: v for k, v in sfm.items() if k != "calibration"},
        "date": datetime.date.today().isoformat(), "pedmesh_version": __version__,
    }
    path.write_text(json.dumps(record, indent=1) + "\n")
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
