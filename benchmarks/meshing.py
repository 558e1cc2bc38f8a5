"""Route-mesh build time: the compiled nearest-segment distances of the size field against
GEOS's nearest search on an STR tree (the reference, measured in the same run).

Every social force run under ``validated`` builds a route mesh (pedmesh.mesh.route_mesh),
whose size field asks for the distance to the nearest exit, reflex corner and wall at each
triangle's centroid in every refinement pass. The two variants give the same meshes, bit
for bit (checked here and in tests/run/test_overheads.py); the A/B repeats are interleaved
and the ratio is of medians. Both remember the distances of points asked for again (the
refinement asks again for most centroids of the pass before).

    python benchmarks/meshing.py [--repeats 3] [--json docs/data/meshing.json]
"""

from __future__ import annotations

import argparse
import hashlib
import sys
import time
from pathlib import Path

import numpy as np
import shapely

import pedmesh.mesh.route_mesh as RM
from pedmesh import load_room

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import write_json  # noqa: E402
SITES = ("experiments/uo-100-180-180.json", "pillar_hall.json", "office.json",
         "venue_10k.json")


class _GeosSearch:
    """The distance to the nearest of some segments by GEOS (shapely's STR tree), as the
    size fields measured it before the compiled search."""

    def __init__(self, seg: np.ndarray) -> None:
        self.seg = seg
        geoms = [shapely.Point(g[0]) if np.array_equal(g[0], g[1]) else shapely.LineString(g)
                 for g in seg.reshape(-1, 2, 2)]
        self.tree = shapely.STRtree(geoms)

    def __call__(self, xy: np.ndarray) -> np.ndarray:
        if len(self.tree) == 0:
            return np.full(len(xy), np.inf)
        (_, _), d = self.tree.query_nearest(shapely.points(xy), return_distance=True,
                                            all_matches=False)
        return d


class _Geos(RM._NearestDistances):
    """The size field's distances (remembered by the points as ever) by GEOS."""

    def __init__(self, segments) -> None:
        super().__init__(segments)
        self.trees = [_GeosSearch(t.seg) for t in self.trees]


def _build(site, variant: str):
    RM._cache.clear()
    compiled = RM._NearestDistances
    if variant == "geos":
        RM._NearestDistances = _Geos
    try:
        t0 = time.perf_counter()
        mesh = RM.route_mesh(site, resolution=0.1, kernel=2.0, clearance=0.5)
        dt = time.perf_counter() - t0
    finally:
        RM._NearestDistances = compiled
    digest = hashlib.sha256(mesh.points.tobytes() + mesh.triangles.tobytes()).hexdigest()
    return dt, digest, mesh.n_triangles


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--sites", default=",".join(SITES))
    ap.add_argument("--json", type=Path, default=None)
    a = ap.parse_args()
    _build(load_room(ROOT / "geometries" / "l_shaped.json"), "compiled")  # (compile)
    rows = {}
    for name in a.sites.split(","):
        site = load_room(ROOT / "geometries" / name)
        t = {"compiled": [], "geos": []}
        digests = set()
        for _ in range(a.repeats):  # interleaved
            for variant in ("compiled", "geos"):
                dt, digest, n = _build(site, variant)
                t[variant].append(dt)
                digests.add(digest)
        med = {k: float(np.median(v)) for k, v in t.items()}
        rows[name] = {"triangles": n, "same_mesh": len(digests) == 1,
                      **{f"{k}_median_s": med[k] for k in med},
                      **{f"{k}_best_s": float(min(v)) for k, v in t.items()},
                      "speed_up": med["geos"] / med["compiled"]}
        r = rows[name]
        print(f"{name}: {n:,} triangles, compiled {r['compiled_median_s']:.2f} s "
              f"(best {r['compiled_best_s']:.2f}), GEOS {r['geos_median_s']:.2f} s "
              f"(best {r['geos_best_s']:.2f}): {r['speed_up']:.1f}x, "
              f"same mesh: {r['same_mesh']}", flush=True)
    if a.json:
        write_json(a.json, {"repeats": a.repeats, "resolution_m": 0.1, "kernel_m": 2.0,
                            "clearance_m": 0.5, "sites": rows})


if __name__ == "__main__":
    main()
