"""The cost of a step on a building where its people are (issue 45).

Ten people on the top floor of a tower of N floors (20 x 10 m each, 3 m apart, the stairs
in two notches in turn, the exit on the ground floor: :func:`tower`, the issue's test
geometry) against the same ten in a one-floor room of the same plan, under the social
force model (``pedmesh.build(path, model="sfm", seed=0)``: the shipped preset, routes
every second). Each case is built once; each repeat steps a copy of it: ``--warmup``
steps, then ``--steps`` timed ones (wall time per step, and its routing share from the
model's timers), the cases interleaved. The goal: a step of the 50-floor tower at most
:data:`TARGET` times the room's.

``--reference`` adds the 50-floor tower solving its whole routes every time
(:data:`pedmesh.eikonal.active.ACTIVE_SET` off: what a step cost before issue 45, but for
the other changes of the issue, which that switch leaves on).

    python benchmarks/building_steps.py [--levels 10 50] [--repeats 5] [--steps 300]
                                        [--warmup 20] [--reference]
                                        [--json docs/data/building_steps.json]

Printed: median and best ms per step of each case, the routing's share, the vertices a
route solve marched last (the active set) and each case's ratio to the room (median over
median, best over best). The machine is shared and noisy: judge by the ratios of one run.
"""

from __future__ import annotations

import argparse
import copy
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import write_json  # noqa: E402

#: a step of the 50-floor tower may cost at most this many times the room's (issue 45)
TARGET = 2.0
#: the floor plan: 20 x 10 m with two stair notches
NOTCHED = [[0, 0], [20, 0], [20, 10], [16, 10], [16, 8], [12, 8], [12, 10], [8, 10], [8, 8],
           [4, 8], [4, 10], [0, 10]]
START = [[2, 1], [8, 1], [8, 6], [2, 6]]
PEOPLE = 10


def tower(levels: int, out: Path) -> tuple[Path, Path]:
    """Write the tower of ``levels`` floors (ten people on the top one) to ``out`` and the
    one-floor room of the same plan with the same ten people beside it (``*_room.json``);
    returns both paths."""
    floors = []
    for k in range(levels):
        lv = {"name": f"L{k}", "z": 3.0 * k, "outline": NOTCHED}
        if k == 0:
            lv["exits"] = [{"name": "front", "polyline": [[0, 3], [0, 5]]}]
        if k == levels - 1:
            lv["start_areas"] = [{"name": "top", "polygon": START, "count": PEOPLE}]
        floors.append(lv)
    stairs = []
    for k in range(levels - 1):
        # alternate the direction so that consecutive stairs meet on the landing edge
        if k % 2 == 0:
            poly, b, t = [[4, 8], [8, 8], [8, 10], [4, 10]], [[4, 8], [4, 10]], [[8, 8], [8, 10]]
        else:
            poly, b, t = ([[12, 8], [16, 8], [16, 10], [12, 10]], [[12, 8], [12, 10]],
                          [[16, 8], [16, 10]])
        stairs.append({"name": f"S{k}", "polygon": poly, "bottom": {"level": f"L{k}", "edge": b},
                       "top": {"level": f"L{k + 1}", "edge": t}})
    out.write_text(json.dumps({"format": "pedmesh-room", "version": 1, "name": f"tower{levels}",
                               "units": "m", "levels": floors, "stairs": stairs}))
    room = {"format": "pedmesh-room", "version": 1, "name": "plan", "units": "m",
            "outline": NOTCHED, "exits": [{"name": "front", "polyline": [[0, 3], [0, 5]]}],
            "start_areas": [{"name": "top", "polygon": START, "count": PEOPLE}]}
    room_path = out.with_name(out.stem + "_room.json")
    room_path.write_text(json.dumps(room))
    return out, room_path


def build(path: Path, active_set: bool = True):
    """The social force model's run on ``path`` (the active set on or off)."""
    import pedmesh
    from pedmesh.eikonal import active

    old = active.ACTIVE_SET
    active.ACTIVE_SET = active_set
    try:
        return pedmesh.build(str(path), model="sfm", seed=0)
    finally:
        active.ACTIVE_SET = old


def measure(base, warmup: int, steps: int) -> dict:
    """Step a copy of the run ``base``: ``warmup`` steps, then ``steps`` timed ones."""
    run = copy.deepcopy(base)
    for _ in range(warmup):
        run.step()
    tm = run.sim.timers
    r0, f0, s0 = tm.routing, tm.forces, tm.settle
    t0 = time.perf_counter()
    for _ in range(steps):
        run.step()
    wall = time.perf_counter() - t0
    act = getattr(run.sim, "_active", None)
    return {"step": wall / steps, "routing": (tm.routing - r0) / steps,
            "forces": (tm.forces - f0) / steps, "settle": (tm.settle - s0) / steps,
            "inside": int(run.sim.n),
            "marched": None if not act else int(act[0].last_marched)}


def main(levels: list[int], repeats: int, steps: int, warmup: int, reference: bool,
         json_path: str | None) -> dict:
    tmp = Path(tempfile.mkdtemp(prefix="building_steps_"))
    top = max(levels)
    paths = {n: tower(n, tmp / f"tower{n}.json") for n in sorted(levels)}
    t = time.perf_counter()
    cases: dict[str, tuple[int, object]] = {"room": (1, build(paths[top][1]))}
    print(f"built the room in {time.perf_counter() - t:.1f} s")
    for n in sorted(levels):
        t = time.perf_counter()
        cases[f"tower{n}"] = (n, build(paths[n][0]))
        print(f"built the {n}-floor tower in {time.perf_counter() - t:.1f} s")
    if reference:
        t = time.perf_counter()
        cases[f"tower{top}-whole"] = (top, build(tmp / f"tower{top}.json", active_set=False))
        print(f"built the {top}-floor tower (whole solves) in {time.perf_counter() - t:.1f} s")
    res: dict[str, list[dict]] = {k: [] for k in cases}
    for rep in range(repeats):
        for key, (_, base) in cases.items():
            res[key].append(measure(base, warmup, steps))
        print(f"repeat {rep + 1}/{repeats}: " + ", ".join(
            f"{k} {1e3 * res[k][-1]['step']:.3f}" for k in cases) + " ms/step")
    room = [r["step"] for r in res["room"]]
    rows = []
    for key, (n, base) in cases.items():
        step = [r["step"] for r in res[key]]
        rows.append({
            "case": key, "levels": n, "whole_solves": key.endswith("-whole"),
            "vertices": int(getattr(base.sim, "atlas", None).surface.n_points
                            if hasattr(base.sim, "atlas") else base.sim.mesh.n_points),
            "triangles": int(base.sim.mesh.n_triangles),
            "step_s": step, "routing_s": [r["routing"] for r in res[key]],
            "forces_s": [r["forces"] for r in res[key]],
            "settle_s": [r["settle"] for r in res[key]],
            "inside": [r["inside"] for r in res[key]],
            "marched": res[key][-1]["marched"],
            "median_ms": 1e3 * statistics.median(step), "best_ms": 1e3 * min(step),
            "routing_median_ms": 1e3 * statistics.median(r["routing"] for r in res[key]),
            "ratio_median": statistics.median(step) / statistics.median(room),
            "ratio_best": min(step) / min(room)})
    print(f"\n{PEOPLE} people, steps {warmup + 1}-{warmup + steps} of each run, {repeats} "
          "interleaved repeats; ms per step (median / best), its routing (median), the "
          "vertices the last route solve marched, and the ratio to the room:")
    for r in rows:
        marched = "" if r["marched"] is None else f"{r['marched']:,} of {r['vertices']:,}"
        print(f"  {r['case']:14s} {r['median_ms']:.3f} / {r['best_ms']:.3f}  routing "
              f"{r['routing_median_ms']:.3f}  {marched:>20s}  x {r['ratio_median']:.2f} / "
              f"{r['ratio_best']:.2f}")
    goal = next(r for r in rows if r["case"] == f"tower{top}")
    met = goal["ratio_median"] <= TARGET and goal["ratio_best"] <= TARGET
    print(f"\ngoal: a step of the {top}-floor tower at most {TARGET:g} x the room's: "
          f"{'met' if met else 'NOT met'} (median {goal['ratio_median']:.2f}, best "
          f"{goal['ratio_best']:.2f})")
    out = {"people": PEOPLE, "steps": steps, "warmup": warmup, "repeats": repeats,
           "levels": sorted(levels), "target": TARGET, "met": met, "rows": rows}
    if json_path:
        write_json(json_path, out)
    return out


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--levels", type=int, nargs="+", default=[10, 50])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--warmup", type=int, default=20)
    ap.add_argument("--reference", action="store_true",
                    help="also the tallest tower solving its whole routes every time")
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    main(a.levels, a.repeats, a.steps, a.warmup, a.reference, a.json)
