"""The hybrid prototype (:class:`pedmesh.models.hybrid.HybridRun`, issue 47) against the
pure models on the corridor bottleneck.

``geometries/corridor_bottleneck.json`` with the agents within ``--near`` (4) m of the
exit and ``eos`` elsewhere, against the social force model and ``eos`` alone, all under
``--preset`` (validated; the prototype's agents walk on the run's mesh, without the route
mesh of the preset's ``route_resolution``) and the start lattice of seed ``--seed``:
T50 / T90 / T100 [s] from the evacuation curve (people out through either model's exits,
sampled at every meeting, 0.1 s), the most agents at once,
where the people were at the end, the largest error of the count over the run, and the
wall time. The issue's goal is T50/T90/T100 within 2 % of the social force model's (or two
standard deviations of a 10-seed ensemble); this prints where the prototype stands.

    python benchmarks/hybrid.py [--near 4] [--seed 0] [--preset validated] [--json FILE]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import write_json  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
ROOM = ROOT / "geometries" / "corridor_bottleneck.json"
QUANTILES = (0.5, 0.9, 1.0)


def crossing_times(t: np.ndarray, out: np.ndarray, n: float) -> list[float]:
    """The first times [s] the curve ``out`` [ped] at ``t`` reaches each quantile of ``n``
    (1.0: within 0.5 of a person of everyone, as a continuum run counts a room empty)."""
    res = []
    for q in QUANTILES:
        goal = q * n - (0.5 if q == 1.0 else 0.0)
        k = np.flatnonzero(out >= goal - 1e-9)
        res.append(float(t[k[0]]) if len(k) else float("nan"))
    return res


def run_hybrid(mesh, near: float, seed: int, preset: str) -> dict:
    from pedmesh.models.hybrid import HybridRun, zone_cells

    t0 = time.perf_counter()
    run = HybridRun(mesh, zone_cells(mesh, near_exits=near), seed=seed, preset=preset)
    n = run.n_initial
    ts, outs, worst, most = [], [], 0.0, 0
    while not run.finished and run.t < 1000.0:
        run.step()
        c = run.count()
        worst = max(worst, abs(c.total - n))
        most = max(most, c.agents)
        ts.append(run.t)
        outs.append(c.out_continuum + c.out_agents)
    c = run.count()
    return {"times_s": crossing_times(np.array(ts), np.array(outs), n),
            "max_agents": most, "count_error_max": worst, "n": n,
            "end": {"cells": c.cells, "agents": c.agents, "accounts": c.accounts,
                    "out_continuum": c.out_continuum, "out_agents": c.out_agents},
            "wall_s": time.perf_counter() - t0}


def run_pure(room, mesh, model: str, seed: int, preset: str) -> dict:
    import tempfile

    from pedmesh.run import run_model

    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="pedmesh-hybrid-") as tmp:
        s = run_model(room, mesh, model, t_end=1000.0, quiet=True, preset=preset,
                      out_dir=Path(tmp) / model,
                      model_options={"seed": seed} if model == "sfm" else {})
    return {"times_s": [float(s[f"t_evac_{k}"]) for k in (50, 90, 100)],
            "wall_s": time.perf_counter() - t0}


def main(argv: list[str] | None = None) -> int:
    import pedmesh
    from pedmesh.mesh import triangulate

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--near", type=float, default=4.0, help="agents within this of the exit [m]")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--preset", default="validated")
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args(argv)
    room = pedmesh.load_room(ROOM)
    mesh = triangulate(room)
    res = {"room": str(ROOM.relative_to(ROOT)), "near_m": args.near, "seed": args.seed,
           "preset": args.preset,
           "hybrid": run_hybrid(mesh, args.near, args.seed, args.preset),
           "sfm": run_pure(room, mesh, "sfm", args.seed, args.preset),
           "eos": run_pure(room, mesh, "eos", args.seed, args.preset)}
    ref = res["sfm"]["times_s"]
    print(f"{res['room']}: agents within {args.near:g} m of the exit, seed {args.seed}, "
          f"preset {args.preset}")
    print("model    T50 [s]  T90 [s]  T100 [s]   against the SFM          wall [s]")
    for name in ("sfm", "eos", "hybrid"):
        t = res[name]["times_s"]
        err = " ".join(f"{a / b - 1:+6.1%}" for a, b in zip(t, ref))
        print(f"{name:<8} {t[0]:7.1f}  {t[1]:7.1f}  {t[2]:8.1f}   {err}   "
              f"{res[name]['wall_s']:6.1f}")
    h = res["hybrid"]
    print(f"hybrid: at most {h['max_agents']} of {h['n']} people agents at once; the count "
          f"(cells + agents + accounts + out) off by at most {h['count_error_max']:.1e} "
          f"people; at the end {h['end']}")
    if args.json:
        write_json(args.json, res)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
