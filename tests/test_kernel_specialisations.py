"""Each compiled kernel is compiled once per process for the usual runs (issue 46, "First
run": compile time).

numba compiles a kernel once for each combination of argument types, and a read-only array
(a mesh's) is another type than a writable one, a constant ``False`` passed from compiled
code another than a ``bool``. Every such second specialisation is the same machine code
compiled again: on a fresh install the fast-marching kernel's and the pair list's took
about half a minute each (benchmarks/compile_time.py). The runs below (a room under the
social force model and three continua, a two-storey building under sfm and eos) leave
every pedmesh kernel with one.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from building_data import TWO

ROOT = Path(__file__).resolve().parents[1]

WORKLOAD = """
import json, sys
import numba
from pedmesh import simulate
from pedmesh.io import load_room

room = load_room(sys.argv[1])
for model in ("sfm", "eos", "rdue", "pw"):
    simulate(room, model, t_end=1.0)
simulate(room, "sfm", t_end=1.0, out_dir=sys.argv[3])
building = load_room(sys.argv[2])
for model in ("sfm", "eos"):
    simulate(building, model, t_end=1.0)
many = {}
for name, mod in list(sys.modules.items()):
    if not name.startswith("pedmesh"):
        continue
    for obj in list(vars(mod).values()):
        if isinstance(obj, numba.core.registry.CPUDispatcher) and len(obj.signatures) > 1:
            f = obj.py_func
            many[f"{f.__module__}.{f.__name__}"] = [str(s) for s in obj.signatures]
print(json.dumps(many))
"""


def test_every_kernel_is_compiled_once_for_rooms_and_buildings(tmp_path):
    building = tmp_path / "two.json"
    building.write_text(json.dumps(TWO))
    proc = subprocess.run(
        [sys.executable, "-c", WORKLOAD, str(ROOT / "geometries" / "corridor_bottleneck.json"),
         str(building), str(tmp_path / "run")],
        capture_output=True, text=True, timeout=1800)
    assert proc.returncode == 0, proc.stderr[-3000:]
    many = json.loads(proc.stdout.strip().splitlines()[-1])
    assert not many, "kernels compiled more than once:\n" + "\n".join(
        f"{k}:\n    " + "\n    ".join(v) for k, v in many.items())
