"""Where the social force model's route at a door is not converged (issue 44): a probe.

The 60-person, 0.8 m door room of ``tests/sfm/test_routes.py`` under ``validated`` with
static routes whose cost is the wall clearance alone (``route_clearance`` 0.5 m, no crowd),
mean T50 / T90 [s] over seeds 1..N with their standard errors, in two arms:

* ``native``: the pedestrians walk on the route mesh refined by ``--walk`` and the route is
  solved there (what a run does);
* ``transfer``: they walk on the route mesh refined by ``--walk``, the route is solved on
  the one refined by ``--route``, and its directions are sampled at the walking mesh's
  vertices and triangle centroids.

If ``transfer --walk 1 --route 4`` answers as ``native --walk 4``, the route's own accuracy
is what moves the answer, not the mesh the people walk on::

    python benchmarks/route_probe.py native --walk 1
    python benchmarks/route_probe.py transfer --walk 1 --route 4 [--seeds 12]
    [--param NAME=VALUE ...]

The arm replaces ``Simulation._route`` for the first solve (the probe's only patch); the
rest of the run is the model's own.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

import pedmesh
from pedmesh.eikonal.direction import DirectionField, pack_directions
from pedmesh.eikonal.fmm import EikonalSolver
from pedmesh.mesh.route_mesh import route_mesh
from pedmesh.models.sfm.simulation import Simulation
from pedmesh.models.sfm.walls import clearance_factor
from pedmesh.parameters import parse_overrides

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "sfm"))
from test_routes import _door_room  # noqa: E402  (the test's room)


def _patch(mode: str, room, resolution: float, clearance: float, kernel: float,
           route_refine: float) -> None:
    orig = Simulation._route

    def route(self) -> None:
        orig(self)
        if getattr(self, "_probe_done", False):
            return
        self._probe_done = True
        m = self.mesh
        own = DirectionField(m, self._solver.solve(clearance_factor(m, clearance)))
        if mode == "native":
            self._dpack = own.packed
            return
        r = route_mesh(room, resolution=resolution, kernel=kernel, clearance=clearance,
                       refine=route_refine)
        fine = DirectionField(r, EikonalSolver(r).solve(clearance_factor(r, clearance)))
        v = fine.at(m.points)
        off = np.hypot(v[:, 0], v[:, 1]) < 0.5  # (a boundary vertex the fine mesh missed)
        v[off] = own.vertex_directions[off]
        self._dpack = pack_directions(m, v, fine.at(m.points[m.triangles].mean(axis=1)))

    Simulation._route = route


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("mode", choices=("native", "transfer"))
    ap.add_argument("--walk", type=float, default=1.0, help="route_refine of the walking mesh")
    ap.add_argument("--route", type=float, default=4.0, help="route_refine of the route "
                    "(transfer)")
    ap.add_argument("--seeds", type=int, default=12)
    ap.add_argument("--param", action="append", default=[], metavar="NAME=VALUE")
    a = ap.parse_args(argv)
    params = parse_overrides(a.param)
    room = _door_room(60)
    from pedmesh.presets import get_preset

    preset = {**get_preset("validated").overrides(), **params}
    _patch(a.mode, room, float(preset["route_resolution"]),
           float(preset["route_clearance"]), float(preset["route_kernel"]), a.route)
    t0 = time.perf_counter()
    rows = np.array([[r.times["T50"], r.times["T90"]] for r in (
        pedmesh.simulate(room, "sfm", preset="validated",
                         params={**params, "route_refine": a.walk}, seed=s, t_end=200.0,
                         static_routes=True) for s in range(1, a.seeds + 1))])
    mean, se = rows.mean(0), rows.std(0) / np.sqrt(len(rows))
    print(f"{a.mode} walk {a.walk:g} route {a.route if a.mode == 'transfer' else a.walk:g} "
          f"{params or ''}: T50 {mean[0]:.2f} +- {se[0]:.2f} s, T90 {mean[1]:.2f} +- "
          f"{se[1]:.2f} s ({len(rows)} seeds, {time.perf_counter() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
