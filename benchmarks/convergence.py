"""One answer whatever the mesh (issue 44): evacuation times against the run's mesh.

For each room and model, T50 and T90 [s] on uniform meshes of ``max_area`` 2 ... 0.02 m^2
(``feature_area`` None) and on the default graded mesh; the social force model with two
seeds a mesh (their mean and spread), the continuum models once (they are deterministic).
Then the social force model's own discretisation at the default mesh: ``route_resolution``
(the edge of its route mesh at the exits) and ``route_refine`` (every edge of the route mesh
divided). The room ``door`` (the 60-person, 0.8 m door of ``tests/sfm/test_routes.py``) has
only the ``route_refine`` study, 1 / 2 / 4 with twelve seeds: at a door the route's
discretisation matters most (its run's mesh plays no part there)::

    python benchmarks/convergence.py --json docs/data/convergence.json \\
        [--rooms uo-100,example2,door] [--models sfm-validated,sfm-paper,eos,rdue,pw] \\
        [--plot docs/images/convergence.png]

Every run's times are written to the JSON as soon as it ends, with the fingerprint of
its preset (``pedmesh.presets.fingerprint``: the values and the eos calibration), and a
rerun with the same file skips what is there under the same preset: an interrupted study
loses nothing, and a refit preset's runs are run again (those under another are dropped
first). ``docs/render_figures.py``
renders the tables of docs/validation/route_convergence.md from the file.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import write_json  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
ROOMS = {"uo-100": ROOT / "geometries" / "experiments" / "uo-100-180-180.json",
         "example2": ROOT / "geometries" / "example2.json",
         "bottleneck": ROOT / "geometries" / "corridor_bottleneck.json",
         "door": None}  # (built in code: tests/sfm/test_routes.py's _door_room)
#: the meshes: "default" (graded) and uniform ones of these largest areas [m^2]
AREAS = {"uo-100": ("default", 2.0, 0.5, 0.2, 0.1, 0.05, 0.02),
         "example2": ("default", 2.0, 0.5, 0.2, 0.1),
         "bottleneck": ("default", 2.0, 0.5, 0.2, 0.1, 0.05), "door": ()}
#: (model, preset) of each label
MODELS = {"sfm-validated": ("sfm", "validated"), "sfm-paper": ("sfm", "paper"),
          "sfm-weidmann": ("sfm", "weidmann"), "eos": ("eos", "validated"),
          "rdue": ("rdue", "validated"), "pw": ("pw", "validated")}
SEEDS = (0, 1)
#: the seeds of the door room's study (its standard error of T90 about 0.1 s)
DOOR_SEEDS = tuple(range(1, 13))
#: the door room's route refinements
DOOR_REFINES = (2.0, 4.0)
#: [m] the social force model's route mesh resolutions refined at the default mesh
RESOLUTIONS = (0.2, 0.1, 0.05)
#: the route mesh refinements (``route_refine``: every edge divided) at the preset's
#: route_resolution
REFINES = (2.0,)
#: [m] the route kernels of the sensitivity study (the model, not the numerics)
KERNELS = (1.0, 1.5, 2.0, 3.0)


def _key(room: str, label: str, area, seed, resolution=None, kernel=None,
         refine=None) -> str:
    return (f"{room}|{label}|{area}|{seed}|{resolution}" + (f"|L{kernel}" if kernel else "")
            + (f"|x{refine:g}" if refine else ""))


def run_one(room: str, label: str, area, seed, resolution=None, kernel=None,
            refine=None) -> dict:
    """T50, T90, T100 [s] and the wall time of one run."""
    import pedmesh
    from pedmesh.presets import fingerprint

    model, preset = MODELS[label]
    mo = None if area == "default" else {"max_area": float(area), "feature_area": None}
    kw = {} if seed is None else {"seed": int(seed)}
    params = {} if resolution is None else {"route_resolution": float(resolution)}
    if kernel is not None:
        params["route_kernel"] = float(kernel)
    if refine is not None:
        params["route_refine"] = float(refine)
    site = _door_room() if room == "door" else str(ROOMS[room])
    t0 = time.perf_counter()
    res = pedmesh.simulate(site, model, preset=preset, mesh_options=mo,
                           params=params, t_end=1000.0, **kw)
    out = {k: res.times[k] for k in ("T50", "T90", "T100")}
    out["wall_s"] = time.perf_counter() - t0
    out["preset"] = fingerprint(preset)
    out["cells"] = int((res.summary.get("mesh") or {}).get("triangles") or 0)
    rm = res.summary.get("route_mesh")
    out["route_mesh"] = int(rm["triangles"]) if rm else None
    return out


def _door_room():
    """The 60-person room with a 0.8 m door of tests/sfm/test_routes.py."""
    sys.path.insert(0, str(ROOT / "tests" / "sfm"))
    from test_routes import _door_room as door

    return door(60)


def _plan(rooms, labels, resolutions) -> list[tuple]:
    todo = []
    for room in rooms:
        if room == "door":
            if "sfm-validated" in labels:
                todo += [(room, "sfm-validated", "default", s, None, None,
                          None if f == 1.0 else f)
                         for f in (1.0, *DOOR_REFINES) for s in DOOR_SEEDS]
            continue
        for label in labels:
            seeds = SEEDS if label.startswith("sfm") else (None,)
            for area in AREAS[room]:
                todo += [(room, label, area, s, None) for s in seeds]
        if "sfm-validated" in labels:
            todo += [(room, "sfm-validated", "default", s, r) for r in resolutions
                     for s in SEEDS]
            todo += [(room, "sfm-validated", "default", s, None, k) for k in KERNELS
                     for s in SEEDS]
            todo += [(room, "sfm-validated", "default", s, None, None, f) for f in REFINES
                     for s in SEEDS]
    return todo


def _seed_stats(got: list[dict]) -> dict:
    """The runs ``got`` of one setting (one per seed): their count, mean T50 / T90 [s] and
    the spread (max - min) of each."""
    q = ("T50", "T90")
    return {"n": len(got), **{k: float(np.mean([g[k] for g in got])) for k in q},
            **{f"{k}_spread": float(np.ptp([g[k] for g in got])) for k in q},
            **{f"{k}_se": float(np.std([g[k] for g in got], ddof=1) / np.sqrt(len(got)))
               if len(got) > 1 else 0.0 for k in q}}


def summarise(runs: dict, rooms, labels, resolutions) -> dict:
    """Per room and model: for each mesh the mean T50/T90 over the seeds, their spread (max
    - min), and the change against the default mesh; the route resolution study."""
    out = {}
    for room in rooms:
        rows = []
        for label in labels:
            seeds = SEEDS if label.startswith("sfm") else (None,)
            cols = []
            for area in AREAS[room]:
                got = [runs.get(_key(room, label, area, s)) for s in seeds]
                got = [g for g in got if g is not None]
                if not got:
                    continue
                t = {k: [g[k] for g in got if g[k] is not None] for k in ("T50", "T90")}
                cols.append({"area": area, "n": len(got), "cells": got[0]["cells"],
                             **{k: float(np.mean(v)) if v else None for k, v in t.items()},
                             **{f"{k}_spread": float(np.ptp(v)) if len(v) > 1 else 0.0
                                for k, v in t.items()},
                             "wall_s": float(np.mean([g["wall_s"] for g in got]))})
            base = next((c for c in cols if c["area"] == "default"), None)
            for c in cols:
                for k in ("T50", "T90"):
                    c[f"d{k}"] = (c[k] / base[k] - 1.0 if base and c[k] and base[k]
                                  else None)
            if cols:
                rows.append({"model": label, "meshes": cols})
        study, kernels, refines = [], [], []
        if "sfm-validated" in labels:
            def seeds_of(*setting) -> list[dict]:
                got = [runs.get(_key(room, "sfm-validated", "default", s, *setting))
                       for s in (DOOR_SEEDS if room == "door" else SEEDS)]
                return [g for g in got if g is not None]

            study = [{"resolution": r, **_seed_stats(g)} for r in resolutions
                     if (g := seeds_of(r))]
            kernels = [{"kernel": k, **_seed_stats(g)} for k in KERNELS
                       if (g := seeds_of(None, k))]
            refines = [{"refine": f, "route_mesh": g[0].get("route_mesh"), **_seed_stats(g)}
                       for f in (1.0, *(DOOR_REFINES if room == "door" else REFINES))
                       if (g := seeds_of(None, None, None if f == 1.0 else f))]
        out[room] = {"rows": rows, "resolution": study, "kernel": kernels,
                     "refine": refines}
    return out


def plot(summary: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rooms = [r for r in summary if summary[r]["rows"]]
    fig, axes = plt.subplots(1, len(rooms), figsize=(5.5 * len(rooms), 4.2), squeeze=False)
    for ax, room in zip(axes[0], rooms):
        for row in summary[room]["rows"]:
            cols = [c for c in row["meshes"] if c["area"] != "default" and c["T90"]]
            if not cols:
                continue
            a = np.array([float(c["area"]) for c in cols])
            t = np.array([c["T90"] for c in cols])
            s = np.array([c["T90_spread"] for c in cols])
            line = ax.errorbar(a, t, yerr=0.5 * s, marker="o", capsize=3, label=row["model"])
            base = next((c for c in row["meshes"] if c["area"] == "default"), None)
            if base and base["T90"]:
                ax.axhline(base["T90"], color=line[0].get_color(), lw=0.8, ls=":")
        ax.set_xscale("log")
        ax.invert_xaxis()
        ax.set_xlabel("max_area of the run's mesh [m$^2$] (dotted: the default mesh)")
        ax.set_ylabel("T90 [s]")
        ax.set_title(room)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    print(f"wrote {path}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", type=Path, required=True, help="results file (resumed)")
    ap.add_argument("--rooms", default="uo-100,example2")
    ap.add_argument("--models", default="sfm-validated,sfm-paper,eos,rdue,pw")
    ap.add_argument("--resolutions", default=",".join(f"{r:g}" for r in RESOLUTIONS))
    ap.add_argument("--plot", type=Path, default=None)
    args = ap.parse_args(argv)
    rooms = args.rooms.split(",")
    labels = args.models.split(",")
    resolutions = tuple(float(r) for r in args.resolutions.split(",") if r)
    for r in rooms:
        if r not in ROOMS:
            ap.error(f"unknown room {r!r} (rooms: {', '.join(ROOMS)})")
    for m in labels:
        if m not in MODELS:
            ap.error(f"unknown model {m!r} (models: {', '.join(MODELS)})")
    runs = {}
    if args.json.is_file():
        runs = json.loads(args.json.read_text())["results"].get("runs", {})
    from pedmesh.presets import fingerprint

    current = {label: fingerprint(preset) for label, (_, preset) in MODELS.items()}
    stale = [k for k, r in runs.items() if r.get("preset") != current.get(k.split("|")[1])]
    for k in stale:  # (computed under another preset: a refit's, or unknown)
        del runs[k]
    todo = [t for t in _plan(rooms, labels, resolutions) if _key(*t) not in runs]
    print(f"{len(runs)} runs in {args.json} ({len(stale)} under another preset dropped), "
          f"{len(todo)} to go", flush=True)
    for i, t in enumerate(todo):
        res = run_one(*t)
        runs[_key(*t)] = res
        print(f"[{i + 1}/{len(todo)}] {t}: T50 {res['T50']}, T90 {res['T90']} "
              f"({res['wall_s']:.0f} s)", flush=True)
        write_json(args.json, {"runs": runs,
                               "summary": summarise(runs, rooms, labels, resolutions)})
    summary = summarise(runs, rooms, labels, resolutions)
    write_json(args.json, {"runs": runs, "summary": summary, "rooms": rooms,
                           "models": labels, "seeds": list(SEEDS),
                           "resolutions": list(resolutions)})
    for room, s in summary.items():
        print(f"\n{room}")
        for row in s["rows"]:
            print(f"  {row['model']:14s} " + "  ".join(
                f"{c['area']}: {c['T50']:.1f}/{c['T90']:.1f}"
                + (f" ({100 * c['dT90']:+.1f}%)" if c.get("dT90") is not None else "")
                for c in row["meshes"] if c["T90"]))
        for r in s["resolution"]:
            print(f"  route_resolution {r['resolution']:g} m: T50 {r['T50']:.1f}, "
                  f"T90 {r['T90']:.1f}")
        for r in s["refine"]:
            print(f"  route_refine {r['refine']:g}: T50 {r['T50']:.2f} +- {r['T50_se']:.2f}, "
                  f"T90 {r['T90']:.2f} +- {r['T90_se']:.2f} ({r['n']} seeds)")
    if args.plot:
        plot(summary, args.plot)
    return 0


if __name__ == "__main__":
    sys.exit(main())
