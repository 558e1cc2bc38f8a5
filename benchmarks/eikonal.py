"""Eikonal benchmark: pedmesh's unstructured fast marching vs scikit-fmm, in one run.

On the paper's Example 3 room (100 x 50 m, obstacle, two exits), unit cost, at about 2k,
8k, 30k and 120k vertices: set-up time (once per mesh), median solve time over repeats,
errors against the exact geodesic distance, and scikit-fmm orders 1 and 2 on Cartesian
grids with about the same node count (aligned with the obstacle; exit nodes fixed at 0,
nodes strictly inside the obstacle masked). Also the plain Kimmel-Sethian march
(``corner_radius=0``) and a variable-cost solve (array input, corner rays integrated).

    python benchmarks/eikonal.py [--repeats 9] [--json FILE]

``--json FILE`` also writes the tables as JSON, from which the docs render them.

Targets (issue 3): at about 30k vertices a solve takes <= 8 ms and no more than 2x
scikit-fmm order 1 per node in the same run.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from pedmesh import load_room
from pedmesh.eikonal import EikonalSolver, geodesic_distance
from pedmesh.mesh import triangulate

ROOT = Path(__file__).resolve().parents[1]
AREAS = [2.0, 0.5, 0.125, 0.03125]


def timed(fn, repeats):
    fn()  # warm-up (compilation or cache load)
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        ts.append(time.perf_counter() - t0)
    return out, float(np.median(ts))


def skfmm_run(room, n_nodes, order, repeats):
    import skfmm

    k = max(1, round(5.0 / np.sqrt(5000.0 / n_nodes)))
    dx = 5.0 / k
    x = np.linspace(0, 100, int(round(100 / dx)) + 1)
    y = np.linspace(0, 50, int(round(50 / dx)) + 1)
    X, Y = np.meshgrid(x, y, indexing="ij")
    phi0 = np.ones_like(X)
    on_exit = np.isclose(X, 100) & (((Y >= 10) & (Y <= 20)) | ((Y >= 30) & (Y <= 40)))
    phi0[on_exit] = 0.0
    hole = (X > 70) & (X < 80) & (Y > 15) & (Y < 35)
    phi0 = np.ma.MaskedArray(phi0, hole)
    d, t = timed(lambda: skfmm.distance(phi0, dx=dx, order=order), repeats)
    d = np.ma.getdata(d)[~hole]
    pts = np.column_stack([X[~hole], Y[~hole]])
    err = np.abs(d - geodesic_distance(room, pts))
    return dict(nodes=int((~hole).sum()), t=t, l1=err.mean(), linf=err.max())


def main(repeats: int = 9) -> dict:
    room = load_room(ROOT / "geometries" / "example3.json")
    rows = []
    for a in AREAS:
        mesh = triangulate(room, max_area=a)
        exact = geodesic_distance(room, mesh.points)
        t0 = time.perf_counter()
        solver = EikonalSolver(mesh)
        t_setup = time.perf_counter() - t0
        plain = EikonalSolver(mesh, corner_radius=0.0)
        phi, t = timed(lambda: solver.solve(1.0), repeats)
        phi0, t0_ = timed(lambda: plain.solve(1.0), repeats)
        cost = 1.0 + 0.2 * np.sin(mesh.points[:, 0] / 9.0)
        _, t_var = timed(lambda: solver.solve(cost), repeats)
        err = np.abs(phi - exact)
        err0 = np.abs(phi0 - exact)
        s1 = skfmm_run(room, mesh.n_points, 1, repeats)
        s2 = skfmm_run(room, mesh.n_points, 2, repeats)
        rows.append((mesh.n_points, t_setup, t, t0_, t_var, err, err0, s1, s2))

    print("pedmesh unstructured FMM (default: corner rays within 10 m) on Example 3, unit cost")
    print()
    print("| vertices | set-up [ms] | solve [ms] | ns/vertex | L1 [m] | Linf [m] "
          "| plain FMM solve [ms] | plain L1 | plain Linf | variable-cost solve [ms] |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for n, ts, t, t0_, tv, err, err0, s1, s2 in rows:
        print(f"| {n} | {1e3 * ts:.0f} | {1e3 * t:.2f} | {1e9 * t / n:.0f} | {err.mean():.4f} "
              f"| {err.max():.4f} | {1e3 * t0_:.2f} | {err0.mean():.4f} | {err0.max():.4f} "
              f"| {1e3 * tv:.2f} |")
    print()
    print("scikit-fmm on Cartesian grids of about the same node count (same run)")
    print()
    print("| vertices | grid nodes | order 1 [ms] | ns/node | L1 | Linf | order 2 [ms] | L1 | Linf "
          "| ratio pedmesh/skfmm-1 per node |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for n, ts, t, t0_, tv, err, err0, s1, s2 in rows:
        ratio = (t / n) / (s1["t"] / s1["nodes"])
        print(f"| {n} | {s1['nodes']} | {1e3 * s1['t']:.2f} | {1e9 * s1['t'] / s1['nodes']:.0f} "
              f"| {s1['l1']:.4f} | {s1['linf']:.4f} | {1e3 * s2['t']:.2f} | {s2['l1']:.4f} "
              f"| {s2['linf']:.4f} | {ratio:.2f} |")
    hs = [np.sqrt(5000.0 / r[0]) for r in rows]
    o = np.polyfit(np.log(hs), np.log([r[5].mean() for r in rows]), 1)[0]
    o0 = np.polyfit(np.log(hs), np.log([r[6].mean() for r in rows]), 1)[0]
    print()
    print(f"observed L1 order: default {o:.2f}, plain {o0:.2f}")
    n, _, t, *_rest, s1, _s2 = rows[2]
    ratio = (t / n) / (s1["t"] / s1["nodes"])
    print(f"targets at {n} vertices: solve {1e3 * t:.2f} ms (<= 8 ms: "
          f"{'met' if t <= 8e-3 else 'NOT met'}), ratio to scikit-fmm order 1 per node "
          f"{ratio:.2f} (<= 2: {'met' if ratio <= 2 else 'NOT met'})")
    return dict(room="geometries/example3.json", repeats=repeats, order_l1=float(o),
                order_l1_plain=float(o0), rows=[
                    dict(vertices=int(n), setup_s=ts, solve_s=t, l1=float(err.mean()),
                         linf=float(err.max()), plain_solve_s=t0_, plain_l1=float(err0.mean()),
                         plain_linf=float(err0.max()), variable_cost_solve_s=tv,
                         skfmm1=s1, skfmm2=s2)
                    for n, ts, t, t0_, tv, err, err0, s1, s2 in rows])


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=9)
    ap.add_argument("--json", default=None, metavar="FILE", help="write the tables here")
    args = ap.parse_args()
    results = main(args.repeats)
    if args.json:
        from _common import write_json  # benchmarks/ is the script's directory

        write_json(args.json, results)
