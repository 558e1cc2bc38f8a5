"""How long a ``pedmesh run`` takes to start, and what a continuum run costs against the
social force model as a whole process (issue 46, "Start-up").

Part 1, start-up: ``pedmesh run geometries/example2.json --model M --t-end 0.1 -q`` in a
new process for ``eos`` and ``sfm``, numba's cache warm (one untimed run of each first):
the interpreter, the imports, the parser, meshing, numba's cache loads, the model's set-up,
a step or ten, the output and the interpreter's shutdown. Part 2 (unless ``--skip-whole``):
the whole Example 2 run, ``pedmesh run geometries/example2.json --model M -q``, of both.

Each part's runs are interleaved (eos, sfm, eos, sfm, ...) and the disk synced between
them (untimed), so that no run pays for the write-back of the one before. Printed: median
and best wall time of each, eos / sfm (median over median, best over best), and whether
the targets are met: the cached eos start-up at most :data:`TARGET_START_S` (median), and
the whole eos process at most :data:`TARGET_RATIO` of the social force model's (median).

The start-up part also times, interleaved with the runs, the **floor**: a process that only
imports the libraries every run needs (numpy, scipy's sparse, spatial and linalg modules,
shapely, triangle, VTK's data model and XML writers, numba) and calls one cached numba
kernel (numba's compiler and its registries start at the first, whichever it is). What a
run takes beyond it is pedmesh's own start-up; the floor says how loaded the machine is
and how much of the target is left to pedmesh.

``--against DIR``: another checkout of pedmesh (e.g. ``git worktree add ../old main``)
timed alternately with this one, A/B (its processes run with ``PYTHONPATH=DIR``); the
output files of its whole runs are compared byte for byte with this checkout's
(``summary.json`` apart: it holds the process id and the wall time).

    python benchmarks/startup.py [--repeats 7] [--whole-repeats 3] [--skip-whole]
                                 [--against DIR [--against-label TEXT]]
                                 [--json docs/data/startup.json]

The processes run as ``python -m pedmesh`` with this interpreter and the environment as
it is (``PYTHONDONTWRITEBYTECODE`` for one: without cached byte code every module is
compiled at every start; the JSON records it). The machine is shared and noisy: judge by
the ratios within one run, not by seconds.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import write_json  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
ROOM = "geometries/example2.json"
#: [s] the most a cached ``--model eos --t-end 0.1`` process may take (issue 46)
TARGET_START_S = 1.5
#: the most the whole eos process of Example 2 may take, as a share of the social force
#: model's (issue 46)
TARGET_RATIO = 0.25
MODELS = ("eos", "sfm")
#: the floor process (see the module docstring), run from a folder of its own
FLOOR_SCRIPT = """\
import numpy, scipy.sparse, scipy.spatial, scipy.linalg, shapely, triangle
import vtkmodules.vtkCommonDataModel, vtkmodules.vtkIOXML
import numba


@numba.njit(cache=True)
def total(x):
    return x.sum()


total(numpy.ones(3))
"""


def run_floor(folder: Path) -> float:
    """The wall time [s] of one floor process (its kernel cached in ``folder`` by an
    untimed first run)."""
    script = folder / "floor.py"
    if not script.is_file():
        folder.mkdir(parents=True, exist_ok=True)
        script.write_text(FLOOR_SCRIPT)
        subprocess.run([sys.executable, str(script)], check=True, cwd=folder)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, str(script)], check=True, cwd=folder)
    return time.perf_counter() - t0


def run_cli(model: str, out: Path, extra: list[str], tree: Path | None) -> float:
    """The wall time [s] of one ``pedmesh run`` process (of the checkout ``tree``, None:
    this one)."""
    cmd = [sys.executable, "-m", "pedmesh", "run", str(ROOT / ROOM), "--model", model,
           "--out", str(out), "-q", *extra]
    env = None
    if tree is not None:
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(
            [str(tree), *filter(None, [os.environ.get("PYTHONPATH")])]))
    t0 = time.perf_counter()
    # (in the output's folder: ``python -m`` puts the working directory first on sys.path,
    # which in this checkout would shadow the other's pedmesh)
    subprocess.run(cmd, check=True, cwd=out.parent, env=env, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    os.sync()  # (the output written back now, untimed)
    return wall


def package_of(tree: Path | None, cwd: Path) -> str:
    """Where the processes of checkout ``tree`` import pedmesh from (a check of --against)."""
    env = None
    if tree is not None:
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(
            [str(tree), *filter(None, [os.environ.get("PYTHONPATH")])]))
    r = subprocess.run([sys.executable, "-c", "import pedmesh; print(pedmesh.__file__)"],
                       check=True, cwd=cwd, env=env, capture_output=True, text=True)
    return str(Path(r.stdout.strip()).parent)


def _differ(a: Path, b: Path) -> list[str]:
    """The output files of run folders ``a`` and ``b`` that are not the same bytes."""
    fa = {p.relative_to(a).as_posix(): p for p in a.rglob("*") if p.is_file()}
    fb = {p.relative_to(b).as_posix(): p for p in b.rglob("*") if p.is_file()}
    names = sorted((set(fa) | set(fb)) - {"summary.json"})
    return [n for n in names if n not in fa or n not in fb
            or fa[n].read_bytes() != fb[n].read_bytes()]


def interleaved(label: str, extra: list[str], repeats: int, tmp: Path,
                trees: dict[str, Path | None], compare: bool = False,
                floor: bool = False) -> dict:
    """``repeats`` processes of each model in each checkout, interleaved (the checkouts'
    order alternating from one repeat to the next); their wall times [s]. ``floor``: a
    floor process (:func:`run_floor`) at the start of each repeat too."""
    walls = {(k, m): [] for k in trees for m in MODELS}
    floors: list[float] = []
    differ: dict[str, list[str]] = {}
    for r in range(repeats):
        if floor:
            floors.append(run_floor(tmp / "floor"))
            print(f"  {label} {r + 1}/{repeats}:   floor     {floors[-1]:6.2f} s", flush=True)
        order = list(trees) if r % 2 == 0 else list(trees)[::-1]
        for m in MODELS:
            for k in order:
                out = tmp / f"{label}-{k}-{m}-{r}"
                walls[k, m].append(run_cli(m, out, extra, trees[k]))
                print(f"  {label} {r + 1}/{repeats}: {k:>7} {m} {walls[k, m][-1]:6.2f} s",
                      flush=True)
            if compare and len(trees) > 1 and r == repeats - 1:
                a, b = (tmp / f"{label}-{k}-{m}-{r}" for k in trees)
                differ[m] = _differ(a, b)
    res = {}
    for k in trees:
        rows = {m: dict(wall_s=walls[k, m], median_s=statistics.median(walls[k, m]),
                        best_s=min(walls[k, m])) for m in MODELS}
        e, s = rows["eos"], rows["sfm"]
        res[k] = dict(models=rows, ratio_median=e["median_s"] / s["median_s"],
                      ratio_best=e["best_s"] / s["best_s"])
    command = " ".join(["pedmesh run", ROOM, "--model M", *extra, "-q"])
    out = dict(command=command, repeats=repeats, checkouts=res)
    if floors:
        out["floor"] = dict(wall_s=floors, median_s=statistics.median(floors), best_s=min(floors))
    if compare and len(trees) > 1:
        out["files_differing"] = differ
    return out


def report(title: str, res: dict) -> None:
    print(f"\n{title}: {res['command']}, {res['repeats']} interleaved repeat(s)")
    print(f"{'checkout':>9} {'model':>6} {'median [s]':>11} {'best [s]':>9}")
    for k, c in res["checkouts"].items():
        for m, r in c["models"].items():
            print(f"{k:>9} {m:>6} {r['median_s']:>11.2f} {r['best_s']:>9.2f}")
        print(f"{k:>9} eos / sfm: median {c['ratio_median']:.3f}, best {c['ratio_best']:.3f}")
    if "floor" in res:
        f = res["floor"]
        print(f"{'floor':>9} {'':>6} {f['median_s']:>11.2f} {f['best_s']:>9.2f}   (the libraries' "
              "imports and one cached numba kernel)")
        for k, c in res["checkouts"].items():
            e = c["models"]["eos"]
            print(f"{k:>9} eos beyond the floor: median {e['median_s'] - f['median_s']:.2f} s, "
                  f"best {e['best_s'] - f['best_s']:.2f} s")
    for m, names in res.get("files_differing", {}).items():
        print(f"  {m}: output the same bytes in both checkouts: "
              + ("yes" if not names else f"NO ({', '.join(names)})"))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--repeats", type=int, default=7, help="start-up processes per model")
    p.add_argument("--whole-repeats", type=int, default=3,
                   help="whole Example 2 processes per model")
    p.add_argument("--skip-whole", action="store_true", help="the start-up only")
    p.add_argument("--against", default=None, metavar="DIR",
                   help="another checkout of pedmesh, timed alternately with this one")
    p.add_argument("--against-label", default=None, metavar="TEXT",
                   help="what the other checkout is, for the table (e.g. a commit)")
    p.add_argument("--json", default=None, metavar="FILE", help="write the figures here")
    args = p.parse_args()
    trees: dict[str, Path | None] = {"this": None}
    if args.against:
        trees["against"] = Path(args.against).resolve()
    results: dict = dict(room=ROOM, target_start_s=TARGET_START_S, target_ratio=TARGET_RATIO,
                         against=str(trees.get("against")) if args.against else None,
                         against_label=args.against_label or args.against,
                         pythondontwritebytecode=bool(os.environ.get("PYTHONDONTWRITEBYTECODE")))
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        results["packages"] = {k: package_of(tree, tmp) for k, tree in trees.items()}
        for k, where in results["packages"].items():
            print(f"{k}: pedmesh from {where}")
        for k, tree in trees.items():  # numba's caches filled, files in the page cache
            for m in MODELS:
                run_cli(m, tmp / f"warm-{k}-{m}", ["--t-end", "0.1"], tree)
        start = interleaved("start-up", ["--t-end", "0.1"], args.repeats, tmp, trees,
                            floor=True)
        results["startup"] = start
        whole = None
        if not args.skip_whole:
            whole = interleaved("whole", [], args.whole_repeats, tmp, trees, compare=True)
            results["whole"] = whole
    report("Start-up (numba's cache warm)", start)
    eos = start["checkouts"]["this"]["models"]["eos"]
    met = eos["median_s"] <= TARGET_START_S
    results["startup_met"] = met
    print(f"target: eos start-up <= {TARGET_START_S} s (median): {'met' if met else 'NOT met'}"
          f" (median {eos['median_s']:.2f} s, best {eos['best_s']:.2f} s)")
    if whole is not None:
        report("Whole Example 2", whole)
        w = whole["checkouts"]["this"]
        met = w["ratio_median"] <= TARGET_RATIO
        results["whole_met"] = met
        print(f"target: whole eos <= {TARGET_RATIO} x sfm (median): "
              f"{'met' if met else 'NOT met'} (median {w['ratio_median']:.3f}, best "
              f"{w['ratio_best']:.3f})")
    if args.json:
        write_json(args.json, results)


if __name__ == "__main__":
    main()
