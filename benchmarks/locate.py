"""Point-location speed: points per second on a mesh of about 60k triangles.

Target (issue 2): at least 1e6 points/s. Prints the build time of the search grid (once
per mesh) and the median query time over repeats.

    python benchmarks/locate.py
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from pedmesh import load_room
from pedmesh.mesh import triangulate

ROOT = Path(__file__).resolve().parents[1]


def main(n_points: int = 1_000_000, repeats: int = 5) -> None:
    room = load_room(ROOT / "geometries" / "example3.json")
    mesh = triangulate(room, max_area=0.125)
    mesh.locate(np.zeros((1, 2)))  # compile (or load the numba cache)
    t0 = time.perf_counter()
    from pedmesh.mesh._locate import TriangleLocator

    TriangleLocator(mesh.points, mesh.triangles)
    t_build = time.perf_counter() - t0
    rng = np.random.default_rng(0)
    q = rng.uniform([-1, -1], [101, 51], size=(n_points, 2))
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        tri = mesh.locate(q)
        times.append(time.perf_counter() - t0)
    t = float(np.median(times))
    print(f"mesh: {mesh.n_points} vertices, {mesh.n_triangles} triangles")
    print(f"grid build: {t_build * 1e3:.1f} ms")
    print(f"query: {n_points} points in {t * 1e3:.1f} ms (median of {repeats}) "
          f"= {n_points / t / 1e6:.2f} M points/s; {np.mean(tri >= 0):.1%} inside")
    print(f"target >= 1.00 M points/s: {'met' if n_points / t >= 1e6 else 'NOT met'}")


if __name__ == "__main__":
    main()
