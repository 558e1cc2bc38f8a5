"""What a fresh install compiles before its first runs, and how long it takes (issue 46,
"First run").

A new process with an empty numba cache (its own ``NUMBA_CACHE_DIR``) runs a room
(geometries/corridor_bottleneck.json, 3 s of simulated time) under the social force model
and the continua eos, rdue and pw, then a two-storey building (tests/building_data.py's
``TWO``) under sfm and eos: every kernel these runs call is compiled once, as on a fresh
install. numba's compile events are timed: each kernel's own time (the kernels it compiles
on the way are counted as theirs), the number of compilations, and the kernels compiled
more than once (a second specialisation: the same code again, for another argument type).

Printed: per checkout the whole process and the compile time (median and best over the
repeats), the kernels that took longest, and with ``--against DIR`` (another checkout,
e.g. ``git worktree add ../old HEAD~1``) the ratio, the runs interleaved (A, B, A, B, ...).
The machine is shared and noisy: single kernels' times move by 20-30 % from run to run;
judge by the totals and the ratio.

    python benchmarks/compile_time.py [--repeats 1] [--against DIR [--against-label TEXT]]
                                      [--json docs/data/compile_time.json]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import write_json  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]

#: the process that compiles: argv = the checkout, an output folder
WORKER = r"""
import collections, json, sys, time
root, out = sys.argv[1], sys.argv[2]
sys.path.insert(0, root + "/tests")
from numba.core import event
import numba

own = collections.defaultdict(float)
count = collections.Counter()

class Timer(event.Listener):
    def __init__(self):
        self.stack = []
    def on_start(self, ev):
        self.stack.append([time.perf_counter(), 0.0])
    def on_end(self, ev):
        t0, inner = self.stack.pop()
        d = time.perf_counter() - t0
        f = ev.data["dispatcher"].py_func
        key = f.__module__ + "." + f.__name__
        own[key] += d - inner
        count[key] += 1
        if self.stack:
            self.stack[-1][1] += d

event.register("numba:compile", Timer())
t0 = time.perf_counter()
import pedmesh
assert pedmesh.__file__.startswith(root), pedmesh.__file__
from pedmesh import simulate
from pedmesh.io import load_room
from building_data import TWO

phases = {}
room = load_room(root + "/geometries/corridor_bottleneck.json")
for model in ("sfm", "eos", "rdue", "pw"):
    t1 = time.perf_counter()
    simulate(room, model, t_end=3.0)
    phases[model] = time.perf_counter() - t1
with open(out + "/two.json", "w") as fh:
    json.dump(TWO, fh)
building = load_room(out + "/two.json")
for model in ("sfm", "eos"):
    t1 = time.perf_counter()
    simulate(building, model, t_end=3.0)
    phases["building " + model] = time.perf_counter() - t1
wall = time.perf_counter() - t0
ours = {k: v for k, v in own.items() if k.startswith("pedmesh.")}
twice = sorted(k for k in ours if count[k] > 1)
print(json.dumps({"wall_s": wall, "compile_s": sum(own.values()),
                  "pedmesh_compile_s": sum(ours.values()),
                  "compilations": sum(count.values()), "phases_s": phases,
                  "kernels_s": dict(sorted(ours.items(), key=lambda kv: -kv[1])[:15]),
                  "compiled_twice": twice}))
"""


def cold_run(tree: Path) -> dict:
    """One worker process on the checkout ``tree`` with an empty numba cache."""
    with tempfile.TemporaryDirectory(prefix="pedmesh-compile-") as tmp:
        env = dict(os.environ, NUMBA_CACHE_DIR=str(Path(tmp) / "numba"),
                   PYTHONPATH=str(tree))
        proc = subprocess.run([sys.executable, "-c", WORKER, str(tree), tmp], env=env,
                              capture_output=True, text=True, cwd=tmp)
    if proc.returncode != 0:
        raise SystemExit(f"the worker on {tree} failed:\n{proc.stderr[-3000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def summary(runs: list[dict]) -> dict:
    wall = [r["wall_s"] for r in runs]
    comp = [r["compile_s"] for r in runs]
    best = min(runs, key=lambda r: r["compile_s"])
    return {"repeats": len(runs),
            "wall_median_s": statistics.median(wall), "wall_best_s": min(wall),
            "compile_median_s": statistics.median(comp), "compile_best_s": min(comp),
            "compilations": best["compilations"], "phases_s": best["phases_s"],
            "kernels_s": best["kernels_s"], "compiled_twice": best["compiled_twice"]}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--against", type=Path, help="another checkout, timed alternately")
    ap.add_argument("--against-label", default=None)
    ap.add_argument("--json", type=Path)
    a = ap.parse_args(argv)
    trees = {"this checkout": ROOT}
    if a.against is not None:
        trees[a.against_label or a.against.name] = a.against.resolve()
    runs: dict[str, list[dict]] = {k: [] for k in trees}
    for rep in range(a.repeats):
        for label, tree in trees.items():
            r = cold_run(tree)
            runs[label].append(r)
            print(f"[{rep + 1}/{a.repeats}] {label}: process {r['wall_s']:.1f} s, compiling "
                  f"{r['compile_s']:.1f} s in {r['compilations']} compilations", flush=True)
    results = {"workload": "corridor_bottleneck under sfm, eos, rdue, pw (3 s each); "
                           "tests/building_data.py TWO under sfm, eos (3 s each)",
               "checkouts": {k: summary(v) for k, v in runs.items()}}
    for label, s in results["checkouts"].items():
        print(f"\n{label}: compile median {s['compile_median_s']:.1f} s, best "
              f"{s['compile_best_s']:.1f} s; process median {s['wall_median_s']:.1f} s; "
              f"{s['compilations']} compilations; compiled twice: "
              f"{', '.join(s['compiled_twice']) or 'none'}")
        for k, v in list(s["kernels_s"].items())[:10]:
            print(f"  {v:7.1f} s  {k.removeprefix('pedmesh.')}")
    if len(trees) == 2:
        this, other = results["checkouts"].values()
        results["ratio_median"] = this["compile_median_s"] / other["compile_median_s"]
        results["ratio_best"] = this["compile_best_s"] / other["compile_best_s"]
        print(f"\ncompile time, this / {list(trees)[1]}: median {results['ratio_median']:.2f}, "
              f"best {results['ratio_best']:.2f}")
    if a.json:
        write_json(a.json, results)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
