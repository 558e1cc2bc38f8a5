"""What more cores buy: both models' kernels, and whole steps, on 1, 2, ... numba threads.

A run is advanced to a state with a crowd in motion; then each hot kernel of a step, and
the whole step, is timed on every thread count asked for, the counts alternating (1, 2,
4, 1, 2, 4, ...) so that the shared machine's noise hits them alike. Printed per kernel:
median and best time per call on each thread count, and the speed-up against one thread
(median over median, best over best).

* Every run also times a reference with nothing serial and nothing shared (independent
  sums of exponentials, after the model's kernels): what it gains on more threads is the
  most this machine gives at that moment (a virtual machine's two cores gave 0.50-0.77
  within one hour here), and the model kernels' ratios are to be read against it.
* ``--model eos`` (or another continuum model; default room: the 100,000-person venue,
  65,000 cells): the kernels of ``FVSolver.residual`` and of the implicit correction (the
  reconstruction, the high- and first-order fluxes, the flux limiter with the divergence,
  the relaxation source, the implicit correction, whose conjugate gradients run in scipy,
  serially) and the whole step.
* ``--model sfm`` (default room: the 10,000-person venue; ``--room
  geometries/venue.json`` for 100,000): the cell list, the pair list with the kernel
  density, the pair forces of a stage, a whole stage (``accel``: pairs, walls, route,
  driving term), the wall crossings and exits (``settle``), the whole Runge-Kutta step and
  ``Simulation.step`` (with the route solve when it is due).
* ``--example2 N``: also N whole processes ``pedmesh run geometries/example2.json
  --model sfm --preset paper --param threads=T`` per thread count, interleaved (wall time
  and CPU time of the whole process, start-up and output included). ``--against DIR``:
  another checkout of pedmesh (``git worktree add ../old main``) run alternately with this
  one (A/B), each run's output compared byte for byte with the other checkout's;
  ``--split``: the time of each part of the output (trajectories, VTK frames, kernel
  outflow, ...) in each process. ``--skip-kernels``: only the processes.

``--profile N`` (continuum): N whole steps on one thread under cProfile, each function's
own time marked parallel (a numba kernel with ``parallel=True``) or serial: the serial share
of a one-thread step, which bounds what more threads can buy (Amdahl).

``--threads 1,2,4``: the thread counts (default: 1, 2, 4, ... up to numba's
``NUMBA_NUM_THREADS``, the machine's cores). ``--json FILE``: the figures, with the
threading layer (``numba.threading_layer()``, and what :mod:`pedmesh._threads` did to load
oneTBB) and the machine.

    python benchmarks/threads.py [--model eos|sfm] [--room FILE] [--threads 1,2]
                                 [--warm S] [--repeats 15] [--example2 N] [--json FILE]
                                 [--against DIR] [--split] [--skip-kernels]

Results are bitwise the same on any thread count (tests/continuum/test_parallel.py,
tests/sfm/test_sfm_parallel.py); this script measures only the time.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))


def _thread_counts(text: str | None) -> list[int]:
    import numba

    most = numba.config.NUMBA_NUM_THREADS
    if text:
        counts = sorted({int(t) for t in text.split(",")})
        if counts[0] < 1 or counts[-1] > most:
            raise SystemExit(f"--threads: each count must be in 1..{most} (NUMBA_NUM_THREADS)")
    else:
        counts, t = [], 1
        while t < most:
            counts.append(t)
            t *= 2
        counts.append(most)
    if 1 not in counts:
        counts = [1, *counts]
    if len(counts) < 2:
        raise SystemExit("needs NUMBA_NUM_THREADS >= 2")
    return counts


def _time(cases, counts, repeats, context=None) -> list[dict]:
    """Time each case on each thread count, the counts alternating; print and return the
    rows (times in seconds)."""
    import contextlib

    import numba

    context = context or contextlib.nullcontext
    head = " ".join(f"{f'{t} thr med / best':>22}" for t in counts)
    ratios = " ".join(f"{f'x{t} med/best':>13}" for t in counts[1:])
    print(f"{'kernel':<44} {head} {ratios}")
    rows = []
    with context():
        for name, fn in cases:
            times = {t: [] for t in counts}
            for t in counts:  # compile / warm each
                numba.set_num_threads(t)
                fn()
            for _ in range(repeats):
                for t in counts:
                    numba.set_num_threads(t)
                    a = time.perf_counter()
                    fn()
                    times[t].append(time.perf_counter() - a)
            med = {t: statistics.median(v) for t, v in times.items()}
            best = {t: min(v) for t, v in times.items()}
            row = {"kernel": name, "median_s": med, "best_s": best,
                   "ratio_median": {t: med[t] / med[1] for t in counts},
                   "ratio_best": {t: best[t] / best[1] for t in counts}}
            rows.append(row)
            cells = " ".join(f"{1e3 * med[t]:10.2f} / {1e3 * best[t]:7.2f} ms" for t in counts)
            rat = " ".join(f"{row['ratio_median'][t]:6.2f}/{row['ratio_best'][t]:5.2f}"
                           for t in counts[1:])
            print(f"{name:<44} {cells} {rat}", flush=True)
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    return rows


def ceiling_case():
    """The reference: a kernel with nothing serial and nothing shared (each thread sums
    exponentials of its own entries, about 40 ms on one thread). What it gains on more
    threads is all this machine gives; the model kernels are judged against it, measured
    in the same run (a virtual machine's cores may share a physical core or be lent to
    other guests)."""
    import math

    import numba as nb

    @nb.njit(parallel=True, cache=True)
    def independent(a, out):
        for i in nb.prange(a.shape[0]):
            s = 0.0
            for k in range(200):
                s += math.exp(-a[i] * k * 1e-3)
            out[i] = s

    a = np.random.default_rng(0).random(48_000)
    out = np.empty_like(a)
    return "reference: independent work (ceiling)", lambda: independent(a, out)


def continuum_cases(args):
    """The continuum's kernels and whole step (see the module docstring)."""
    from pedmesh.io import load_room
    from pedmesh.mesh import triangulate
    from pedmesh.models import get_model

    room = load_room(args.room or ROOT / "geometries" / "venue.json")
    mesh = triangulate(room)
    run = get_model(args.model).build(room, mesh, {"threads": 2})
    t0 = time.perf_counter()
    warm = 60.0 if args.warm is None else args.warm
    while run.t < warm and not run.done:
        run.step()
    s = run.solver
    Q, t = run.state.Q, run.t
    print(f"{args.model} on {room.name}: {mesh.n_triangles} cells, {s.n_active} active, "
          f"{run.remaining:.0f} people inside at t = {t:.1f} s (warm-up "
          f"{time.perf_counter() - t0:.0f} s)")
    dt = s.max_dt(Q, t)
    s._buffers(Q.shape[1])
    nv = Q.shape[1]
    Es, Vi = s._Es.reshape(-1, nv), s._Vi
    opt = s.options

    def recon():
        s.recon.apply(Q, Es, Vi, order=opt.order, eps_hat=opt.eps_hat, qref=s.qref,
                      slot=s._slot, positivity=(opt.rho_eps, 1e-3) if opt.limiter else None,
                      cact=s.cact)

    def high():
        s._fluxes(t, s._Fb)

    def low():
        s._low_order(Q, t, s._FL, s._alpha)

    def residual():
        s._lo_key = None
        s.residual(Q, t, dt)

    def correction():
        if s.implicit is None:
            return
        L, _ = s.residual(Q, t, dt)
        V = Q + dt * L
        if s._live_faces is None:
            s._live_faces = s.implicit.live_faces(s.live)
        s.implicit.correct(V, L[:, 1:3], dt, s.cact, s._live_faces)

    def step():
        from pedmesh.models.continuum.solver import FVState

        st = FVState(Q.copy(), t)
        st.outflow = np.zeros(s.n_exits)
        s.step(st, dt)

    from pedmesh.models.continuum.solver import _one_blas_thread

    cases = [("reconstruction", recon), ("high-order fluxes", high),
             ("first-order fluxes + wave speeds", low),
             ("residual (above + limiter, sources)", residual),
             ("residual + implicit correction", correction), ("whole step (2 stages)", step)]
    info = {"model": args.model, "room": room.name, "cells": mesh.n_triangles,
            "t": t, "inside": run.remaining, "run": run}
    return info, cases, _one_blas_thread


#: compiled functions that only drive parallel kernels (their time is the kernels')
PARALLEL_DRIVERS = {"conjugate_gradients"}


def serial_profile(run, steps: int) -> dict:
    """Where a one-thread step of the continuum run ``run`` spends its time: ``steps`` steps
    under cProfile on one thread, each function's own time marked parallel (a numba kernel
    compiled with ``parallel=True``, or one of :data:`PARALLEL_DRIVERS`: its loops are
    shared by the threads) or serial
    (everything else: the serial kernels, scipy, numpy and the Python of the step, stage
    and route). The serial share bounds the speed-up of more threads (Amdahl)."""
    import cProfile
    import importlib
    import pstats

    import numba

    # a run's step sets numba's thread count to its solver's own (FVController.advance):
    # that is set to one here, or the "one-thread" profile would run on the run's threads
    solver = run.solver
    threads_before = solver.threads
    solver.threads = 1
    numba.set_num_threads(1)
    seen = set()  # the thread counts the solver's steps ran on
    plain_step = solver.step

    def step(*a, **kw):
        seen.add(numba.get_num_threads())
        return plain_step(*a, **kw)

    solver.step = step
    try:
        for _ in range(2):  # (compiled and warm)
            run.step()
        prof = cProfile.Profile()
        a = time.perf_counter()
        prof.enable()
        for _ in range(steps):
            run.step()
        prof.disable()
        wall = time.perf_counter() - a
    finally:
        del solver.step
        solver.threads = threads_before
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    if seen != {1}:
        raise RuntimeError(f"the one-thread profile ran on {sorted(seen)} threads")
    stats = pstats.Stats(prof).stats
    rows = []
    for (fname, _line, func), (_cc, _nc, tt, _ct, _callers) in stats.items():
        parallel = False
        if "pedmesh" in fname and fname.endswith(".py"):
            mod = fname[fname.rindex("pedmesh"):-3].replace(os.sep, ".")
            try:
                obj = getattr(importlib.import_module(mod), func, None)
            except ImportError:
                obj = None
            parallel = (bool(getattr(obj, "targetoptions", {}).get("parallel"))
                        or func in PARALLEL_DRIVERS)
        where = func if "pedmesh" not in fname else f"{fname[fname.rindex('pedmesh'):]}:{func}"
        rows.append({"function": where, "seconds": tt, "parallel": parallel})
    total = sum(r["seconds"] for r in rows)
    serial = sum(r["seconds"] for r in rows if not r["parallel"])
    rows.sort(key=lambda r: -r["seconds"])
    print(f"one-thread profile of {steps} steps: {wall:.2f} s wall, {1e3 * wall / steps:.1f} ms "
          f"a step; serial {100 * serial / total:.1f} % of the profiled time")
    for r in rows[:25]:
        tag = "parallel" if r["parallel"] else "serial  "
        print(f"  {tag} {100 * r['seconds'] / total:5.1f} %  {r['function']}")
    return {"steps": steps, "threads": 1, "wall_s": wall, "profiled_s": total, "serial_s": serial,
            "serial_share": serial / total, "functions": rows[:40]}


def sfm_cases(args):
    """The social force model's kernels, a stage, a step (see the module docstring)."""
    import numba

    import pedmesh
    from pedmesh.models.sfm import kernels as K
    from pedmesh.models.sfm.simulation import PAIR_SKIN

    room = args.room or ROOT / "geometries" / "venue_10k.json"
    t0 = time.perf_counter()
    run = pedmesh.build(room, model="sfm", preset=args.preset)
    sim = run.sim
    warm = 20.0 if args.warm is None else args.warm
    while run.t < warm and not run.done:
        run.step()
    n, p, w, mesh = sim.n, sim.params, sim.walls, sim.mesh
    every = sim.numerics.density_stages == 3
    rc_list = max(sim.rc_f + PAIR_SKIN, sim.rc_d + PAIR_SKIN) if every else sim.rc_f + PAIR_SKIN
    print(f"sfm ({args.preset}) on {Path(room).stem}: {n} people inside at t = {run.t:.1f} s, "
          f"{sim.last_pair_count} pairs listed (warm-up {time.perf_counter() - t0:.0f} s)")
    # copies of the state, so that the timed calls leave the run as it is
    x, v, tri, rho = sim.x.copy(), sim.v.copy(), sim.tri[:n].copy(), sim.rho.copy()
    xs, vs, F, rw, e = (np.empty_like(x), np.empty_like(x), np.empty_like(x), np.empty(len(x)),
                        sim._e.copy())
    pi, pj = sim._pi.copy(), sim._pj.copy()
    start, order = sim._cell_start.copy(), sim._cell_order.copy()
    tbuf, rs, cf, ue = sim._tbuf.copy(), sim._rs.copy(), sim._cf.copy(), sim._ue.copy()
    listed = {}

    def cells():
        K.build_cells(x, n, sim._cx0, sim._cy0, sim._cinv, sim._cnx, sim._cny, start, order)

    def pairs():
        t = numba.get_num_threads()
        lay, pos = K.pair_blocks(n, start, order, sim._cnx, sim._cny, t)
        listed[t] = (lay, pos) + K.list_pairs(
            x, n, start, order, sim._cnx, sim._cny, rc_list, sim.rc_f + PAIR_SKIN, pi, pj, rw,
            sim.rc_d, p.R, not every, lay, pos, e, sim._space[6:8])

    def blocks():
        """The list's blocks for the current thread count (the list is the same for any)."""
        t = numba.get_num_threads()
        if t not in listed:
            pairs()
        return listed[t]

    def forces():
        lay, pos, nn, nf = blocks()
        K.pair_accel_blocks(x, v, n, pi, pj, nn, nf, lay, pos, start, sim.rc_f, sim.rc_d,
                            sim.rad, p.A, p.B, p.k, p.kappa, p.m, p.R, F, rw, every, sim._rs
                            if p.shrink > 0 else sim.rad, p.vision, e, sim._space[6:8])

    def stage():
        lay, pos, nn, nf = blocks()
        K.accel(x, v, n, tri, mesh.points, mesh.triangles, mesh.triangle_neighbors, sim._dpack,
                pi, pj, nn, nf, w.piece, w.next_seg, w.x0, w.y0, w.inv_cell, w.nx, w.ny,
                w.cell_ptr, w.cell_seg, sim.rc_f, sim.rc_d, sim.rc_w, sim.rad, p.A, p.B, p.k,
                p.kappa, p.m, p.R, p.tau, sim._u_eff, sim._law, sim._const_u, sim._use_const, F,
                rw, e, every, sim.toff, tbuf, sim._space, rs, sim._wmap, sim._wgeo, cf, ue, lay,
                pos, start, sim._hinge_pairs)

    start3, order3, pi3, pj3 = start.copy(), order.copy(), pi.copy(), pj.copy()

    def rk3():
        xx, vv, tt = x.copy(), v.copy(), tri.copy()
        K.rk3_step(xx, vv, n, sim.numerics.dt, tt, mesh.points, mesh.triangles,
                   mesh.triangle_neighbors, sim._dpack, start3, order3, sim._cx0, sim._cy0,
                   sim._cinv, sim._cnx, sim._cny, w.piece, w.next_seg, w.x0, w.y0, w.inv_cell,
                   w.nx, w.ny, w.cell_ptr, w.cell_seg, sim.rc_f, sim.rc_d, sim.rc_w, sim.rad, p.A,
                   p.B, p.k, p.kappa, p.m, p.R, p.tau, sim._u_eff, sim._law, sim._const_u,
                   sim._use_const, xs, vs, F, rw, rho.copy(), e, pi3, pj3, PAIR_SKIN,
                   int(sim.numerics.density_stages), sim.toff, tbuf, sim._space, rs, sim._wmap,
                   sim._wgeo, cf, ue, sim._hinge_pairs, numba.get_num_threads())
        listed["step"] = (xx, vv, tt)

    def settle():
        if "step" not in listed:
            rk3()
        xx, vv, tt = (a.copy() for a in listed["step"])
        K.settle(x, xx, vv, tt, n, mesh.points, mesh.triangles, mesh.triangle_neighbors,
                 mesh.triangle_edges, mesh.edge_kind, mesh.edge_owner, mesh.edge_normals,
                 sim._exit_of, sim._exit_frac, sim._dpack)

    def whole():
        # the run's own step (its threads from numba's count: threads None), on the real
        # state: it moves on, as a run does
        sim.numerics = dataclasses.replace(sim.numerics, threads=numba.get_num_threads())
        sim.step()

    cases = [("cell list", cells), ("pair list + kernel density", pairs),
             ("pair forces (one stage)", forces),
             ("stage: pairs, walls, route, driving", stage),
             ("settle: wall crossings, exits", settle),
             ("Runge-Kutta step (3 stages)", rk3),
             ("Simulation.step (incl. routes when due)", whole)]
    info = {"model": "sfm", "preset": args.preset, "room": Path(room).stem, "people": n,
            "t": run.t, "pairs": int(sim.last_pair_count)}
    return info, cases, None


#: run inside an Example 2 process with ``--split``: ``pedmesh run`` with timers around the
#: parts of the output (the wrapped names exist in every version since the run protocol)
_SPLIT = r"""
import functools, json, os, sys, threading, time
t_start = time.perf_counter()
from pedmesh.models.sfm.adapter import SFMRun
from pedmesh.run.output import RunWriter
from pedmesh.run import driver
acc = {}
def wrap(owner, name, key):
    f = getattr(owner, name)
    @functools.wraps(f)
    def g(*a, **k):
        t0 = time.perf_counter()
        try:
            return f(*a, **k)
        finally:  # (the background writer's share apart: it overlaps the steps)
            k = key + (" (writer)" if threading.current_thread().name == "pedmesh-writer"
                       else "")
            acc[k] = acc.get(k, 0.0) + time.perf_counter() - t0
    setattr(owner, name, g)
wrap(SFMRun, "step", "steps")
wrap(SFMRun, "_trajectory_frame", "trajectories")
wrap(SFMRun, "kernel_outflow", "kernel outflow")
wrap(SFMRun, "record", "record")
wrap(SFMRun, "write_frame", "vtk frames")
wrap(RunWriter, "pedestrian_frame", "pedestrians.pvd")
wrap(RunWriter, "density_frame", "density.pvd")
wrap(RunWriter, "trajectory_frame", "trajectory files")  # (printed as the writer's only)
wrap(driver, "_safety", "safety")
from pedmesh.cli import main
try:
    rc = main(sys.argv[1:])
finally:
    acc["exits.csv etc."] = acc.get("record", 0.0) - acc.get("trajectories", 0.0) \
        - acc.get("kernel outflow", 0.0)
    acc["process"] = time.perf_counter() - t_start
    with open(os.environ["PEDMESH_SPLIT_JSON"], "w") as f:
        json.dump(acc, f)
sys.exit(rc)
"""
#: the parts printed with ``--split`` (seconds per process)
_PARTS = ("steps", "trajectories", "vtk frames", "pedestrians.pvd", "density.pvd",
          "kernel outflow", "exits.csv etc.", "safety", "process")
#: the parts written by the background writer (pedmesh.run.background) on a run with more
#: than one thread: on its own thread, beside the steps (not in the stepping thread's time)
_WRITER_PARTS = ("trajectory files (writer)", "pedestrians.pvd (writer)",
                 "density.pvd (writer)", "kernel outflow (writer)")
#: summary.json's fields that differ between two runs of the same thing
_VOLATILE = {"wall_time_s", "time_split_s", "pid"}


def _same_output(a: Path, b: Path) -> list[str]:
    """The files in which run folders ``a`` and ``b`` differ (every file byte for byte,
    summary.json without its wall times and process id)."""
    def files(d):
        return {p.relative_to(d).as_posix(): p for p in sorted(d.rglob("*"))
                if p.is_file() and p.name != ".lock"}

    fa, fb = files(a), files(b)
    bad = sorted(set(fa) ^ set(fb))
    for name in sorted(set(fa) & set(fb)):
        if name == "summary.json":
            sa, sb = (json.loads(f[name].read_text()) for f in (fa, fb))
            if any(sa.get(k) != sb.get(k) for k in set(sa) | set(sb) if k not in _VOLATILE):
                bad.append(name)
        elif fa[name].read_bytes() != fb[name].read_bytes():
            bad.append(name)
    return bad


def example2_processes(counts, repeats, *, against: str | None = None,
                       split: bool = False) -> list[dict]:
    """Whole ``pedmesh run`` processes of Example 2 (SFM, paper preset) on each thread
    count, interleaved; wall and CPU time (user + system) of each. ``against``: another
    checkout of pedmesh (``git worktree add``) run alternately with this one, A/B, each
    run's output compared byte for byte with the other checkout's on the same thread
    count. ``split``: the time of each part of the output in each process (timers around
    the model's record and frame methods)."""
    trees = [("this", ROOT)] + ([("against", Path(against).resolve())] if against else [])
    times = {(k, t): [] for k, _ in trees for t in counts}
    cpu = {key: [] for key in times}
    parts = {key: [] for key in times}
    summaries = {}
    differ: dict[tuple, list[str]] = {}
    print(f"Example 2 (sfm, paper), whole processes, {repeats} per thread count"
          + (f" and checkout ({ROOT} and {trees[1][1]})" if against else "") + ", interleaved")
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(repeats):
            for label, root in (trees if r % 2 == 0 else trees[::-1]):
                env = dict(os.environ, PYTHONPATH=os.pathsep.join(
                    [str(root), *filter(None, [os.environ.get("PYTHONPATH")])]))
                for t in counts:
                    out = Path(tmp) / f"{label}-r{r}-t{t}"
                    args = [str(ROOT / "geometries" / "example2.json"), "--model", "sfm",
                            "--preset", "paper", "--param", f"threads={t}", "--out",
                            str(out), "-q"]
                    cmd = [sys.executable, *(["-c", _SPLIT, "run"] if split else
                                             ["-m", "pedmesh", "run"]), *args]
                    env["PEDMESH_SPLIT_JSON"] = str(out) + ".json"
                    before = resource.getrusage(resource.RUSAGE_CHILDREN)
                    a = time.perf_counter()
                    subprocess.run(cmd, check=True, env=env, stdout=subprocess.DEVNULL,
                                   cwd=tmp)
                    times[label, t].append(time.perf_counter() - a)
                    after = resource.getrusage(resource.RUSAGE_CHILDREN)
                    cpu[label, t].append(after.ru_utime - before.ru_utime + after.ru_stime
                                         - before.ru_stime)
                    if split:
                        parts[label, t].append(json.loads(Path(env["PEDMESH_SPLIT_JSON"])
                                                          .read_text()))
                    s = json.loads((out / "summary.json").read_text())
                    summaries.setdefault(t, set()).add((s["t_evac_50"], s["t_evac_90"],
                                                        s["t_evac_100"], s["steps"]))
                    print(f"  run {r + 1}, {label}, {t} thread(s): {times[label, t][-1]:6.1f} s "
                          f"wall, {cpu[label, t][-1]:6.1f} s CPU", flush=True)
            for t in counts:  # this checkout's output against the other's, then drop both
                first = Path(tmp) / f"this-r{r}-t{t}"
                if against:
                    differ[r, t] = _same_output(first, Path(tmp) / f"against-r{r}-t{t}")
            for d in Path(tmp).iterdir():
                if d.is_dir():
                    shutil.rmtree(d)
    same = len({x for v in summaries.values() for x in v}) == 1
    rows = []
    for label, _ in trees:
        for t in counts:
            v, v1 = times[label, t], times[label, counts[0]]
            med, best = statistics.median(v), min(v)
            row = {"checkout": label, "threads": t, "wall_s": v, "cpu_s": cpu[label, t],
                   "median_s": med, "best_s": best,
                   "ratio_median": med / statistics.median(v1), "ratio_best": best / min(v1)}
            if split:
                row["parts_s"] = {k: [p.get(k, 0.0) for p in parts[label, t]]
                                  for k in (*_PARTS, *_WRITER_PARTS)}
            rows.append(row)
            print(f"  {label}, {t} thread(s): median {med:6.1f} s, best {best:6.1f} s, CPU "
                  f"median {statistics.median(cpu[label, t]):6.1f} s; x{row['ratio_median']:.2f}"
                  f" median, x{row['ratio_best']:.2f} best (against {counts[0]} thread)")
            if split:
                for k in (*_PARTS, *_WRITER_PARTS):
                    x = row["parts_s"][k]
                    if k in _WRITER_PARTS and not any(x):
                        continue
                    print(f"      {k:<18} median {statistics.median(x):6.2f} s, best "
                          f"{min(x):6.2f} s")
    print(f"  T50/T90/T100/steps the same on every run: {same}")
    if against:
        bad = {k: v for k, v in differ.items() if v}
        print("  output the same byte for byte as the other checkout's on every run: "
              + ("yes" if not bad else f"NO: {bad}"))
    return rows


def main(argv=None) -> int:
    import numba

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--model", default="eos", help="sfm or a continuum model (default eos)")
    ap.add_argument("--room", default=None)
    ap.add_argument("--preset", default="paper", help="the SFM's preset (default paper)")
    ap.add_argument("--threads", default=None, help="thread counts, e.g. 1,2,4 (default: "
                    "powers of 2 up to NUMBA_NUM_THREADS)")
    ap.add_argument("--warm", type=float, default=None,
                    help="simulated seconds before timing (default 60 continuum, 20 sfm)")
    ap.add_argument("--repeats", type=int, default=15)
    ap.add_argument("--example2", type=int, default=0, metavar="N",
                    help="also N whole Example 2 SFM processes per thread count")
    ap.add_argument("--profile", type=int, default=0, metavar="N",
                    help="(continuum) also profile N whole steps on one thread: the serial "
                         "share")
    ap.add_argument("--against", default=None, metavar="DIR",
                    help="with --example2: also run another checkout of pedmesh (e.g. a git "
                    "worktree of main), alternately, and compare the outputs byte for byte")
    ap.add_argument("--split", action="store_true",
                    help="with --example2: time the parts of the output in each process")
    ap.add_argument("--skip-kernels", action="store_true",
                    help="only the --example2 processes (no kernel timings)")
    ap.add_argument("--json", default=None, help="write the figures to this file")
    args = ap.parse_args(argv)
    counts = _thread_counts(args.threads)
    info, cases, context = {}, [], None
    if args.skip_kernels:
        pass
    elif args.model in ("sfm", "sf", "social-force"):
        info, cases, context = sfm_cases(args)
    else:
        info, cases, context = continuum_cases(args)
    from pedmesh._threads import tbb_load_status
    from pedmesh.models.continuum.solver import threading_layer

    layer = threading_layer()
    print(f"numba {numba.__version__}, threading layer '{layer}' (oneTBB "
          f"{tbb_load_status()}), NUMBA_NUM_THREADS {numba.config.NUMBA_NUM_THREADS}")
    rows = _time([*cases, ceiling_case()], counts, args.repeats, context)
    run = info.pop("run", None)
    profile = serial_profile(run, args.profile) if args.profile and run is not None else None
    whole = example2_processes(counts, args.example2, against=args.against,
                               split=args.split) if args.example2 else None
    if args.json:
        from _common import write_json

        write_json(args.json, {
            "threading_layer": layer, "tbb": tbb_load_status(),
            "numba": numba.__version__, "numba_num_threads": numba.config.NUMBA_NUM_THREADS,
            "threads": counts, "repeats": args.repeats, "state": info, "kernels": rows,
            "example2_processes": whole, "profile": profile})
        print(f"figures in {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
